"""The learning phase of the multi-query planner: a goal-independent roadmap.

The paper's multiple-query planner first "builds a graph, composed of
components in GSn linked by regrasping-transfer and transfer-regrasping paths,
that will capture the topology of CSfree". :func:`build_roadmap` does that for
a scenario, without its goal:

1. **Module 1**: a PRM-family OMPL planner grows its roadmap in GSn from the
   RLG-style sampler (object poses uniform over the scenario's ``[workspace]``
   box around the start position, orientations uniform), in rounds of doubling
   size, single-threaded.
2. **Module 2**: components are joined by transfer-regrasp links
   (:func:`~dexplan.planning.roadmap.module2.try_link`), nearest vertex pairs first,
   until one component is left or the budget ends.

With ``nodes`` the build is deterministic for a seed (growth stops at a
milestone count, module 2 at an attempt count); with ``time_limit`` the clock
decides how far it gets.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from dexplan.core.errors import InvalidInputError, did_you_mean
from dexplan.model.hand.hand import Hand
from dexplan.model.scenario import Scenario
from dexplan.planning.context import PlanningContext, learning_context
from dexplan.planning.gsn.space import POSE_DIM
from dexplan.planning.ompl import (
    MULTI_QUERY_PLANNERS,
    PlanningProblem,
    check_planner,
    planner_traits,
)
from dexplan.planning.progress import Progress, ProgressEvent, Stage
from dexplan.planning.roadmap import tasks as bt
from dexplan.planning.roadmap.graph import Roadmap, scenario_key
from dexplan.planning.roadmap.module2 import (
    Pair,
    component_groups,
    link_pass,
    object_move_free,
    try_link,
)
from dexplan.planning.roadmap.problems import gsn_problem
from dexplan.planning.roadmap.tasks import MAX_JOBS

FIRST_ROUND_MILESTONES = 16
"""Roadmap size after the first module-1 round (doubling per round)."""

MODULE1_SHARE = 0.6
"""Fraction of a ``time_limit`` module 1 may use; module 2 gets the rest."""

MAX_TIME_LIMIT = 86_400.0
"""Longest build (s)."""

MAX_NODES = 1_000_000
"""Largest ``nodes`` target."""


@dataclass(frozen=True)
class BuildSettings:
    """How a roadmap is built (one of ``time_limit`` and ``nodes``).

    Attributes:
        planner: a PRM-family OMPL planner (:data:`MULTI_QUERY_PLANNERS`).
        seed: random seed.
        time_limit: seconds for the whole build, or None.
        nodes: module-1 roadmap size (vertices), or None.
        max_link_attempts: most module-2 link attempts (None: until merged or
            out of time; with ``nodes`` and no time limit, 20 per component).
        jobs: build in tasks (:mod:`dexplan.planning.roadmap.tasks`) over this
            many local processes (1: tasks in this process); None: the serial
            OMPL build, unless ``ray_address`` is given.
        ray_address: build in tasks over a Ray cluster (``auto``, a
            ``ray://host:port`` address, or ``local`` for a Ray instance
            started here); ``jobs`` then caps the actors.
    """

    planner: str = "PRM"
    seed: int = 1
    time_limit: float | None = None
    nodes: int | None = None
    max_link_attempts: int | None = None
    jobs: int | None = None
    ray_address: str | None = None

    @property
    def tasks(self) -> bool:
        """Whether the build runs in tasks (``--jobs`` or ``--ray``)."""
        return self.jobs is not None or self.ray_address is not None

    def __post_init__(self) -> None:
        if (self.time_limit is None) == (self.nodes is None):
            raise InvalidInputError("give exactly one of --time and --nodes")
        if self.time_limit is not None and not 0 < self.time_limit <= MAX_TIME_LIMIT:
            raise InvalidInputError(
                f"--time must be in (0, {MAX_TIME_LIMIT:g}] s, got {self.time_limit}"
            )
        if self.nodes is not None and not 2 <= self.nodes <= MAX_NODES:
            raise InvalidInputError(f"--nodes must be in [2, {MAX_NODES}], got {self.nodes}")
        if self.jobs is not None and not 1 <= self.jobs <= MAX_JOBS:
            raise InvalidInputError(f"--jobs must be in [1, {MAX_JOBS}], got {self.jobs}")
        if not planner_traits(self.planner).multi_query:
            hint = did_you_mean(self.planner, MULTI_QUERY_PLANNERS)
            raise InvalidInputError(
                f"--planner: a roadmap is built by a multi-query planner "
                f"({', '.join(sorted(MULTI_QUERY_PLANNERS))}), got {self.planner!r}{hint}"
            )


@dataclass(frozen=True)
class BuildStats:
    """Figures of one build (kept in the roadmap file's ``meta.build``).

    Attributes:
        planner, seed: as built.
        nodes, edges, links: roadmap sizes at the end.
        gsn_components: components of the GSn edges alone.
        components: components with the module-2 links.
        rounds: module-1 rounds.
        link_attempts: module-2 link attempts.
        module1_time_s, module2_time_s, time_s: seconds.
        time_limit: the budget (s), or None. target_nodes: the node target, or None.
        workers: processes or Ray actors the tasks ran on (1: the serial build).
        tasks: build tasks run (0: the serial build).
    """

    planner: str
    seed: int
    nodes: int
    edges: int
    links: int
    gsn_components: int
    components: int
    rounds: int
    link_attempts: int
    module1_time_s: float
    module2_time_s: float
    time_s: float
    time_limit: float | None
    target_nodes: int | None
    workers: int = 1
    tasks: int = 0

    def as_dict(self) -> dict[str, object]:
        """The stats as a JSON-ready mapping."""
        return dataclasses.asdict(self)


def build_roadmap(
    scenario: Scenario,
    settings: BuildSettings,
    *,
    hand: Hand | None = None,
    progress: Progress | None = None,
) -> tuple[Roadmap, BuildStats]:
    """The learning phase: grow a GSn roadmap, then link its components.

    Args:
        scenario: the models and the workspace (its goal is ignored).
        settings: planner, seed and budget.
        hand: the scenario's hand if already built.
        progress: called with a :class:`ProgressEvent` per module-1 round
            (counts ``nodes``, ``edges``, ``components``) and per module-2 link
            attempt (``attempts``, ``links``, ``components``).

    Returns:
        The roadmap (``build`` holds the stats) and its :class:`BuildStats`.

    Raises:
        InvalidInputError: bad settings or planner parameters.
    """
    check_planner(settings.planner, scenario.planner.params)
    if settings.tasks:
        return _build_in_tasks(scenario, settings, hand, progress)
    t0 = time.perf_counter()
    ctx = learning_context(scenario, settings.seed, hand)
    budget = settings.time_limit if settings.time_limit is not None else MAX_TIME_LIMIT
    deadline = t0 + budget

    def say(stage: Stage, message: str, **counts: int) -> None:
        if progress is not None:
            progress(ProgressEvent(stage, message, time.perf_counter() - t0, counts))

    problem = gsn_problem(
        ctx, settings.planner, scenario.planner.params, scenario.planner.space, settings.seed
    )
    grower = _Module1(problem, ctx, settings, scenario_key(ctx), say)
    m1_deadline = t0 + (MODULE1_SHARE * budget if settings.time_limit is not None else budget)
    roadmap = grower.grow(m1_deadline, None)
    gsn_components = roadmap.components(with_links=False)[0]
    t_m1 = time.perf_counter() - t0
    t_m2 = time.perf_counter()
    attempts = link_components(ctx, roadmap, settings, deadline, say)
    t_m2 = time.perf_counter() - t_m2
    # time left (only with a time limit): grow on, keep the links, link again
    while settings.time_limit is not None and deadline - time.perf_counter() > 1.0:
        t = time.perf_counter()
        before = roadmap.n_vertices
        roadmap = grower.grow(t + MODULE1_SHARE * (deadline - t), roadmap)
        t_m1 += time.perf_counter() - t
        if roadmap.n_vertices == before:
            break
        gsn_components = roadmap.components(with_links=False)[0]
        t = time.perf_counter()
        attempts += link_components(ctx, roadmap, settings, deadline, say)
        t_m2 += time.perf_counter() - t
    stats = _finish(roadmap, settings, t0, gsn_components, grower.rounds, attempts, t_m1, t_m2)
    return roadmap, stats


def _finish(
    roadmap: Roadmap,
    settings: BuildSettings,
    t0: float,
    gsn_components: int,
    rounds: int,
    link_attempts: int,
    module1_time_s: float,
    module2_time_s: float,
    *,
    workers: int = 1,
    tasks: int = 0,
) -> BuildStats:
    """The build's :class:`BuildStats` (times rounded to 1 us), also kept in ``roadmap.build``.

    ``t0`` is the ``time.perf_counter()`` the build started at.
    """
    stats = BuildStats(
        planner=settings.planner,
        seed=settings.seed,
        nodes=roadmap.n_vertices,
        edges=len(roadmap.edges),
        links=len(roadmap.links),
        gsn_components=gsn_components,
        components=roadmap.components()[0],
        rounds=rounds,
        link_attempts=link_attempts,
        module1_time_s=round(module1_time_s, 6),
        module2_time_s=round(module2_time_s, 6),
        time_s=round(time.perf_counter() - t0, 6),
        time_limit=settings.time_limit,
        target_nodes=settings.nodes,
        workers=workers,
        tasks=tasks,
    )
    roadmap.build = stats.as_dict()
    return stats


class _Module1:
    """Module 1 of the learning phase: the PRM roadmap, grown in rounds of doubling size."""

    def __init__(
        self,
        problem: PlanningProblem,
        ctx: PlanningContext,
        settings: BuildSettings,
        key: str,
        say: Callable[..., None],
    ) -> None:
        self.problem, self.ctx, self.settings, self.key, self.say = (
            problem,
            ctx,
            settings,
            key,
            say,
        )
        self.rounds = 0
        self.targets = _round_targets(settings.nodes)
        self.milestones = 0

    def grow(self, until: float, old: Roadmap | None) -> Roadmap:
        """Rounds until ``until``, the node target or the clock; ``old``'s links are kept."""
        roadmap = old or self._empty()
        nodes = self.settings.nodes
        while until - time.perf_counter() > 0.0:
            if nodes is not None and self.milestones >= nodes:
                break
            target = max(next(self.targets), self.milestones + 1)
            self.rounds += 1
            self.milestones = self.problem.grow_roadmap(
                until - time.perf_counter(), max_milestones=target
            )
            roadmap = _read_roadmap(self.problem, self.ctx, self.settings.planner, self.key)
            if old is not None:
                roadmap.links = _carry_links(old, roadmap)
            n_comp = roadmap.components(with_links=False)[0]
            self.say(
                Stage.MODULE1,
                f"module 1: round {self.rounds}: {roadmap.n_vertices} nodes, "
                f"{len(roadmap.edges)} edges, {n_comp} components",
                rounds=self.rounds,
                nodes=roadmap.n_vertices,
                edges=len(roadmap.edges),
                components=n_comp,
            )
            if self.milestones < target:
                break  # the clock stopped it
        return roadmap

    def _empty(self) -> Roadmap:
        return Roadmap(
            np.zeros((0, self.ctx.gsn.ambient_dim)),
            np.zeros((0, 2), dtype=np.int64),
            np.zeros((0, 2), dtype=np.int64),
            self.settings.planner,
            self.key,
        )


def _carry_links(old: Roadmap, new: Roadmap) -> np.ndarray:
    """``old``'s links as indices of ``new`` (vertices matched exactly; lost ones dropped)."""
    index = {row.tobytes(): i for i, row in enumerate(new.vertices)}
    out = []
    for a, b in old.links.tolist():
        ia = index.get(old.vertices[a].tobytes())
        ib = index.get(old.vertices[b].tobytes())
        if ia is not None and ib is not None:
            out.append((ia, ib))
    return np.array(out, dtype=np.int64).reshape(-1, 2)


def _round_targets(nodes: int | None) -> Iterator[int]:
    """Milestone targets of the module-1 rounds: doubling, capped at ``nodes``."""
    target = FIRST_ROUND_MILESTONES
    while True:
        if nodes is not None and target >= nodes:
            yield nodes
            return
        yield target
        target *= 2


def _read_roadmap(
    problem: PlanningProblem, ctx: PlanningContext, planner: str, key: str
) -> Roadmap:
    """The planner's graph as a :class:`Roadmap` (each undirected edge once)."""
    data = problem.planner_data()
    edges = np.asarray(data.edges, dtype=np.int64).reshape(-1, 2)
    if len(edges):
        edges = np.unique(np.sort(edges, axis=1), axis=0)
        edges = edges[edges[:, 0] != edges[:, 1]]
    return Roadmap(
        np.asarray(data.vertices, dtype=float).reshape(-1, ctx.gsn.ambient_dim),
        edges,
        np.zeros((0, 2), dtype=np.int64),
        planner,
        key,
    )


def link_components(
    ctx: PlanningContext,
    roadmap: Roadmap,
    settings: BuildSettings,
    deadline: float,
    say: Callable[..., None],
) -> int:
    """Module 2 of the learning phase: link components until one is left.

    Every other component is linked to the largest one (merged ones grow it):
    the :data:`~dexplan.planning.roadmap.module2.PAIRS_PER_COMPONENT` nearest
    vertex pairs (object-pose distance) are tried in turn
    (:func:`~dexplan.planning.roadmap.module2.link_pass` over
    :func:`~dexplan.planning.roadmap.module2.component_groups`), and a
    component none of them links is left for the next pass. Stops when one
    component is left, a pass links nothing, the attempts run out or the
    deadline passes.

    Returns:
        The number of link attempts.
    """
    n_comp, _ = roadmap.components()
    limit = settings.max_link_attempts
    if limit is None and settings.time_limit is None:
        limit = 20 * n_comp
    ctx.reseed_local_planners(settings.seed, 3)
    attempts = 0
    tried: set[Pair] = set()

    def attempt(pairs: Sequence[Pair]) -> list[bool]:
        nonlocal attempts
        attempts += len(pairs)
        v = roadmap.vertices
        return [try_link(ctx, v[a], v[b][:POSE_DIM]) for a, b in pairs]

    def move_free(a: int, b: int) -> bool:
        return object_move_free(ctx, roadmap.vertices[a], roadmap.vertices[b])

    def stop() -> bool:
        return time.perf_counter() >= deadline or (limit is not None and attempts >= limit)

    def after() -> None:
        count = roadmap.components()[0]
        say(
            Stage.MODULE2,
            f"module 2: {attempts} link attempts, {len(roadmap.links)} links, {count} components",
            attempts=attempts,
            links=len(roadmap.links),
            components=count,
        )

    while n_comp > 1 and not stop():
        done = link_pass(
            roadmap,
            component_groups(roadmap),
            attempt,
            move_free,
            stop=stop,
            tried=tried,
            after=after,
        )
        n_comp = roadmap.components()[0]
        if not done.links:
            break
    return attempts


def _build_in_tasks(
    scenario: Scenario, settings: BuildSettings, hand: Hand | None, progress: Progress | None
) -> tuple[Roadmap, BuildStats]:
    """:func:`build_roadmap` in tasks over workers (:mod:`dexplan.planning.roadmap.tasks`)."""
    t0 = time.perf_counter()
    ctx = learning_context(scenario, settings.seed, hand)
    budget = settings.time_limit if settings.time_limit is not None else MAX_TIME_LIMIT
    timed = settings.time_limit is not None

    def say(stage: Stage, message: str, **counts: int) -> None:
        if progress is not None:
            progress(ProgressEvent(stage, message, time.perf_counter() - t0, counts))

    space = scenario.planner.space
    runner = bt.make_runner(scenario, space, settings.jobs, settings.ray_address, ctx.hand)
    try:
        targets = _task_targets(settings.nodes, runner.workers)
        limit = settings.max_link_attempts
        if limit is None and not timed:
            limit = -1  # 20 per component, fixed after module 1
        st = bt.run_build(
            runner,
            ctx,
            settings.seed,
            lambda: next(targets),
            t0 + (MODULE1_SHARE * budget if timed else budget),
            t0 + budget,
            say,
            limit,
            space,
        )
    finally:
        runner.close()
    roadmap = bt.st_roadmap(st, settings.planner, scenario_key(ctx))
    t_m1 = st.module1_time_s
    stats = _finish(
        roadmap,
        settings,
        t0,
        roadmap.components(with_links=False)[0],
        st.rounds,
        st.link_attempts,
        t_m1,
        time.perf_counter() - t0 - t_m1,
        workers=runner.workers,
        tasks=st.sample_tasks + st.edge_tasks + st.link_attempts,
    )
    return roadmap, stats


def _task_targets(nodes: int | None, workers: int) -> Iterator[int | None]:
    """Vertex targets of the task build's module-1 rounds (None: no more rounds).

    With ``nodes``: doubling from :data:`FIRST_ROUND_MILESTONES` up to it,
    whatever the worker count (the roadmap must not depend on it). With a time
    limit: doubling, by at most 64 vertices per worker a round, so the last
    round does not overrun the budget by much.
    """
    if nodes is not None:
        yield from _round_targets(nodes)
        while True:
            yield None
    target = FIRST_ROUND_MILESTONES
    while True:
        yield target
        target += min(target, 64 * workers)
