"""The learning phase in tasks: one roadmap, built by local processes or a Ray cluster.

:func:`run_build` (what :func:`~dexplan.planning.roadmap.learning.build_roadmap`
runs with ``--jobs`` or ``--ray``) grows the same kind of roadmap as the serial
build, PRM's way (GSn samples, then a GSn motion check from each vertex to its
nearest neighbours, then module-2 links between components), but cut into
tasks that workers run:

- **sample** tasks draw :data:`SAMPLES_PER_TASK` RLG states each;
- **edge** tasks check :data:`PAIRS_PER_TASK` candidate GSn motions each;
- **link** tasks make one module-2 transfer-regrasp attempt each.

Every task carries its own seed, derived from the build seed, the task's kind
and its index (:func:`task_seed`), and builds its own planning context from
it, so a task's answer does not depend on which worker ran it or on what that
worker ran before. The results are merged in task order, and the tasks of a
round are fixed before any of them runs. The roadmap is therefore the same for
a seed and a ``nodes`` target whatever the worker count (``--jobs 1`` runs
the tasks in this process). With a time limit the clock decides how many
rounds run.

Workers are processes of a ``forkserver`` (``spawn`` where there is none)
:mod:`multiprocessing` pool, or Ray actors (``dexplan[ray]``): each builds the
hand once and then runs tasks.
"""

from __future__ import annotations

import enum
import math
import multiprocessing as mp
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from dexplan.core.errors import InvalidInputError
from dexplan.core.ray_cluster import join_ray
from dexplan.core.typing import FloatArray
from dexplan.model.hand.hand import Hand
from dexplan.model.scenario import Scenario
from dexplan.planning.context import PlanningContext, build_hand, learning_context
from dexplan.planning.gsn.space import POSE_DIM
from dexplan.planning.progress import Stage
from dexplan.planning.roadmap.graph import Roadmap
from dexplan.planning.roadmap.module2 import (
    Pair,
    component_groups,
    link_pass,
    object_move_free,
    try_link,
)
from dexplan.planning.roadmap.problems import constraint_spec
from dexplan.planning.roadmap.queries import query_problem

SAMPLES_PER_TASK = 8
"""GSn states a sample task draws."""

PAIRS_PER_TASK = 48
"""Candidate GSn motions an edge task checks."""

LINKS_PER_ROUND = 8
"""Module-2 link attempts fixed per round (one per component, largest first)."""

NEIGHBOURS = 10
"""Nearest vertices (scaled ambient distance) each vertex tries to join, as PRM's default."""


class TaskKind(enum.StrEnum):
    """The kinds of build task; a task is a tuple whose first item is its kind.

    - ``(SAMPLE, seed, count)``: up to ``count`` RLG states -> ``(k, 7 + nq)`` array;
    - ``(EDGE, [(x_a, x_b), ...])``: GSn motion checks -> ``(m,)`` bool array;
    - ``(LINK, seed, x_a, b_pose)``: one module-2 link attempt -> bool.
    """

    SAMPLE = "sample"
    EDGE = "edge"
    LINK = "link"


Task = tuple[Any, ...]
"""A build task: ``(TaskKind, arguments...)`` (see :class:`TaskKind`); plain
tuples pickle cheaply to worker processes and Ray actors."""

_KIND_NUMBERS = {TaskKind.SAMPLE: 1, TaskKind.EDGE: 2, TaskKind.LINK: 3}

MAX_JOBS = 256
"""Most local worker processes."""


def task_seed(seed: int, kind: str, index: int) -> int:
    """The seed of task ``index`` of a ``kind`` (a :class:`TaskKind`) of a build."""
    number = _KIND_NUMBERS[TaskKind(kind)]
    return int(np.random.SeedSequence([seed, number, index]).generate_state(1)[0])


# ------------------------------------------------------------------ workers
class TaskWorker:
    """Runs build tasks for one scenario (one per process or Ray actor)."""

    def __init__(self, scenario: Scenario, space: str, hand: Hand | None = None) -> None:
        self.scenario = scenario
        self.hand = hand or build_hand(scenario)
        self._ctx = learning_context(scenario, 0, self.hand)
        self._problem = query_problem(self._ctx, space)

    def run(self, task: Task) -> Any:
        """One task's answer: states ``(k, n)``, edge verdicts ``(m,)`` or a link verdict."""
        kind = task[0]
        if kind == TaskKind.SAMPLE:
            _, seed, count = task
            sampler = learning_context(self.scenario, seed, self.hand).sampler
            got = [x for x in (sampler.sample() for _ in range(count)) if x is not None]
            return np.array(got, dtype=float).reshape(len(got), -1)
        if kind == TaskKind.EDGE:
            pairs = task[1]
            return np.array([self._problem.check_motion(a, b) for a, b in pairs], dtype=bool)
        if kind == TaskKind.LINK:
            _, seed, a, b_pose = task
            return bool(try_link(learning_context(self.scenario, seed, self.hand), a, b_pose))
        raise ValueError(f"unknown build task {kind!r}")


_WORKER: TaskWorker | None = None


def _init_process(scenario: Scenario, space: str) -> None:
    global _WORKER
    _WORKER = TaskWorker(scenario, space)


def _run_in_process(task: Task) -> Any:
    assert _WORKER is not None
    return _WORKER.run(task)


class Runner(Protocol):
    """Runs a list of tasks; answers in task order."""

    workers: int

    def map(self, tasks: Sequence[Task]) -> list[Any]:
        """The tasks' answers, in task order."""
        ...

    def close(self) -> None:
        """Stop the workers."""
        ...


class InlineRunner:
    """Tasks in this process (``--jobs 1``)."""

    def __init__(self, scenario: Scenario, space: str, hand: Hand | None = None) -> None:
        self.worker = TaskWorker(scenario, space, hand)
        self.workers = 1

    def map(self, tasks: Sequence[Task]) -> list[Any]:
        """The tasks' answers, in task order."""
        return [self.worker.run(t) for t in tasks]

    def close(self) -> None:
        """Nothing to stop."""


class ProcessRunner:
    """Tasks over ``jobs`` local processes (forkserver, or spawn)."""

    def __init__(self, scenario: Scenario, space: str, jobs: int) -> None:
        method = "forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn"
        self.workers = jobs
        context = mp.get_context(method)
        if method == "forkserver":  # the server imports the models once; workers fork from it
            context.set_forkserver_preload(["dexplan.planning.roadmap.tasks"])
        self._pool = context.Pool(jobs, initializer=_init_process, initargs=(scenario, space))

    def map(self, tasks: Sequence[Task]) -> list[Any]:
        """The tasks' answers, in task order."""
        return self._pool.map(_run_in_process, tasks, chunksize=1)

    def close(self) -> None:
        """Stop the processes."""
        self._pool.terminate()
        self._pool.join()


class RayRunner:
    """Tasks over Ray actors (one per CPU of the cluster, or ``jobs``)."""

    def __init__(self, scenario: Scenario, space: str, address: str, jobs: int | None) -> None:
        ray, self._own = join_ray(address, num_cpus=jobs or 2)
        self._ray = ray
        cpus = int(ray.cluster_resources().get("CPU", 1))
        self.workers = max(1, jobs or cpus)
        actor: Any = ray.remote(num_cpus=1)(TaskWorker)  # typed by Ray only where installed
        self._actors: list[Any] = [actor.remote(scenario, space) for _ in range(self.workers)]

    def map(self, tasks: Sequence[Task]) -> list[Any]:
        """The tasks' answers, in task order (round-robin over the actors)."""
        n = len(self._actors)
        refs = [self._actors[k % n].run.remote(t) for k, t in enumerate(tasks)]
        return list(self._ray.get(refs))

    def close(self) -> None:
        """Stop the actors (and Ray, when started here)."""
        for a in self._actors:
            self._ray.kill(a)
        if self._own:
            self._ray.shutdown()


def make_runner(
    scenario: Scenario, space: str, jobs: int | None, ray_address: str | None, hand: Hand | None
) -> Runner:
    """The runner of ``--jobs`` / ``--ray`` (jobs 1 and no Ray: this process)."""
    if jobs is not None and not 1 <= jobs <= MAX_JOBS:
        raise InvalidInputError(f"--jobs must be in [1, {MAX_JOBS}], got {jobs}")
    if ray_address is not None:
        return RayRunner(scenario, space, ray_address, jobs)
    if jobs is None or jobs == 1:
        return InlineRunner(scenario, space, hand)
    return ProcessRunner(scenario, space, jobs)


# ------------------------------------------------------------------ the build
@dataclass
class _State:
    """The roadmap as it grows, and the counters of the build."""

    vertices: FloatArray
    edges: list[tuple[int, int]]
    checked: set[tuple[int, int]]
    links: list[tuple[int, int]]
    tried: set[tuple[int, int]]
    sample_tasks: int = 0
    edge_tasks: int = 0
    link_attempts: int = 0
    rounds: int = 0
    module1_time_s: float = 0.0


def grow_round(runner: Runner, st: _State, seed: int, target: int, scale: FloatArray) -> int:
    """One module-1 round: sample up to ``target`` vertices, check the new candidate edges.

    Returns:
        The vertices added.
    """
    need = target - len(st.vertices)
    first = st.sample_tasks
    n_tasks = math.ceil(need / SAMPLES_PER_TASK)
    tasks = [
        (TaskKind.SAMPLE, task_seed(seed, TaskKind.SAMPLE, first + k), SAMPLES_PER_TASK)
        for k in range(n_tasks)
    ]
    st.sample_tasks += n_tasks
    got = [x for x in runner.map(tasks) if len(x)]
    new = np.vstack(got)[:need] if got else np.zeros((0, st.vertices.shape[1]))
    st.vertices = np.vstack([st.vertices, new])
    pairs = _candidate_pairs(st.vertices, scale, st.checked)
    st.checked.update(pairs)
    chunks = [pairs[k : k + PAIRS_PER_TASK] for k in range(0, len(pairs), PAIRS_PER_TASK)]
    v = st.vertices
    verdicts = runner.map([(TaskKind.EDGE, [(v[a], v[b]) for a, b in c]) for c in chunks])
    st.edge_tasks += len(chunks)
    for chunk, ok in zip(chunks, verdicts, strict=True):
        st.edges.extend(p for p, good in zip(chunk, ok, strict=True) if good)
    st.rounds += 1
    return len(new)


def _candidate_pairs(
    vertices: FloatArray, scale: FloatArray, checked: set[tuple[int, int]]
) -> list[tuple[int, int]]:
    """Unchecked ``(a < b)`` pairs of each vertex and its :data:`NEIGHBOURS` nearest, sorted."""
    n = len(vertices)
    if n < 2:
        return []
    y = vertices * scale
    out: set[tuple[int, int]] = set()
    k = min(NEIGHBOURS, n - 1)
    for lo in range(0, n, 512):
        d = np.linalg.norm(y[lo : lo + 512, None, :] - y[None, :, :], axis=-1)
        d[np.arange(len(d)), np.arange(lo, lo + len(d))] = np.inf
        near = np.argsort(d, axis=1, kind="stable")[:, :k]
        for i, row in enumerate(near, start=lo):
            out.update((min(i, int(j)), max(i, int(j))) for j in row)
    return sorted(out - checked)


def link_round(runner: Runner, st: _State, ctx: PlanningContext, seed: int, room: int) -> int:
    """One module-2 round: up to :data:`LINKS_PER_ROUND` link attempts, one per component.

    Components other than the largest, largest first, each try their nearest
    untried vertex pair to it (object-pose distance) that the object alone
    can move along (:func:`~dexplan.planning.roadmap.module2.link_pass` in
    batches); at most ``room`` attempts, run as tasks. Returns the links
    added, or -1 when no pair is left to try (module 2 ends).
    """
    rm = st_roadmap(st, "", "")
    if rm.components()[0] < 2:
        return 0
    v = st.vertices

    def attempt(pairs: Sequence[Pair]) -> list[Any]:
        tasks = [
            (
                TaskKind.LINK,
                task_seed(seed, TaskKind.LINK, st.link_attempts + k),
                v[a],
                v[b][:POSE_DIM],
            )
            for k, (a, b) in enumerate(pairs)
        ]
        st.link_attempts += len(tasks)
        return runner.map(tasks)

    def move_free(a: int, b: int) -> bool:
        return object_move_free(ctx, v[a], v[b])

    done = link_pass(
        rm,
        component_groups(rm),
        attempt,
        move_free,
        tried=st.tried,
        batch=min(LINKS_PER_ROUND, room),
    )
    st.links.extend(done.links)
    return len(done.links) if done.attempts else -1


def st_roadmap(st: _State, planner: str, key: str) -> Roadmap:
    """The build state as a :class:`Roadmap`."""
    return Roadmap(
        st.vertices.copy(),
        np.array(st.edges, dtype=np.int64).reshape(-1, 2),
        np.array(st.links, dtype=np.int64).reshape(-1, 2),
        planner,
        key,
    )


def new_state(ambient_dim: int) -> _State:
    """An empty build state."""
    return _State(np.zeros((0, ambient_dim)), [], set(), [], set())


def position_scale(ctx: PlanningContext, space: str) -> FloatArray:
    """The ambient coordinates' scale of the GSn constraint (positions per object length)."""
    return np.asarray(constraint_spec(ctx, space).scale, dtype=float)


def run_build(
    runner: Runner,
    ctx: PlanningContext,
    seed: int,
    targets: Callable[[], int | None],
    m1_until: float,
    until: float,
    say: Callable[..., None],
    link_limit: int | None,
    space: str,
) -> _State:
    """Module 1 in rounds until ``targets()`` gives None or ``m1_until``; then module 2.

    ``link_limit``: most link attempts (None: no cap; -1: 20 per component
    left after module 1).
    """
    t0 = time.perf_counter()
    st = new_state(ctx.gsn.ambient_dim)
    scale = position_scale(ctx, space)
    while time.perf_counter() < m1_until:
        target = targets()
        if target is None:
            break
        added = grow_round(runner, st, seed, target, scale)
        rm = st_roadmap(st, "", "")
        n_comp = rm.components(with_links=False)[0]
        say(
            Stage.MODULE1,
            f"module 1: round {st.rounds}: {len(st.vertices)} nodes, {len(st.edges)} edges, "
            f"{n_comp} components ({runner.workers} workers)",
            rounds=st.rounds,
            nodes=len(st.vertices),
            edges=len(st.edges),
            components=n_comp,
        )
        if added == 0:
            break
    st.module1_time_s = time.perf_counter() - t0
    if link_limit == -1:  # with a node target: 20 attempts per component
        link_limit = 20 * st_roadmap(st, "", "").components()[0]
    while time.perf_counter() < until and (link_limit is None or st.link_attempts < link_limit):
        room = LINKS_PER_ROUND if link_limit is None else link_limit - st.link_attempts
        if link_round(runner, st, ctx, seed, room) < 0:
            break
        count = st_roadmap(st, "", "").components()[0]
        say(
            Stage.MODULE2,
            f"module 2: {st.link_attempts} link attempts, {len(st.links)} links, "
            f"{count} components",
            attempts=st.link_attempts,
            links=len(st.links),
            components=count,
        )
        if count == 1:
            break
    return st
