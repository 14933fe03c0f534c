"""Module 2: link GSn components with transfer-regrasp sequences.

A link from vertex a to vertex b exists when the object can be carried from
a's pose to b's pose by transfers and regrasps starting from a's grasp
(computed by the same local planners as the reduction). Linked components
merge. Most of the paper's planning time went here; the attempts, links and
time are counted.

One link loop, :func:`link_pass`, serves every caller: a single query
(:func:`link_query`, towards the goal region), the learning phase
(:func:`~dexplan.planning.roadmap.learning.link_components`, every component
towards the largest) and the build in tasks (its link attempts run in
parallel, in batches).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from dexplan.core.segments import Segment
from dexplan.core.typing import FloatArray
from dexplan.planning.context import PlanningContext
from dexplan.planning.gsn.space import POSE_DIM
from dexplan.planning.local.grasps import grasp_from_state, regrasps_onto
from dexplan.planning.local.reduction import (
    ReductionResult,
    ReductionSettings,
    reduce_object_path,
)
from dexplan.planning.local.smoothing import straight_move_ok
from dexplan.planning.local.transitions import densify_poses
from dexplan.planning.roadmap.graph import Geodesic, Roadmap, pose_distance, pose_distances
from dexplan.planning.roadmap.problems import rlg_states
from dexplan.planning.roadmap.search import GsnQuery, GsnResult, GsnStats, LinkReduction

__all__ = [
    "MODULE2_SHARE",
    "MODULE2_WAYPOINTS",
    "OTHER_GRASPS",
    "PAIRS_PER_COMPONENT",
    "LinkPass",
    "Pair",
    "component_groups",
    "link_pass",
    "link_query",
    "link_reduction",
    "module2_round",
    "nearest_pairs",
    "object_move_free",
    "try_link",
]

Pair = tuple[int, int]
"""Two roadmap vertex indices: a link attempt from the first to the second."""

PAIRS_PER_COMPONENT = 3
"""Nearest vertex pairs tried between two components before giving up on them."""

MODULE2_WAYPOINTS = 16
"""RLG states a single query's module 2 adds once when it has no link to try
(:func:`link_query`'s ``waypoints``), for planners whose
:class:`~dexplan.planning.ompl.registry.PlannerTraits` ask for them."""

#: Share of the time left that one module-2 pass of a single query may use.
MODULE2_SHARE = 0.3

#: Other start grasps a module-2 attempt may regrasp onto before its gaits.
OTHER_GRASPS = 8


def object_move_free(ctx: PlanningContext, a: FloatArray, b: FloatArray) -> bool:
    """True when the object alone can move straight from a's pose to b's (no obstacle)."""
    s = ctx.transitions.settings
    return straight_move_ok(
        a[:POSE_DIM],
        b[:POSE_DIM],
        lambda p: not ctx.world.object_collides(p),
        s.max_step_m,
        s.max_step_rad,
    )


def try_link(ctx: PlanningContext, a: FloatArray, b_pose: FloatArray) -> bool:
    """Module-2 link test: can transfers and regrasps carry the object from a to b's pose?"""
    return link_reduction(ctx, a, b_pose).result.success


def link_reduction(
    ctx: PlanningContext, a: FloatArray, b_pose: FloatArray, via: Sequence[FloatArray] = ()
) -> LinkReduction:
    """The module-2 link attempt from state ``a`` to the object pose ``b_pose: (7,)``.

    The object moves straight (the poses as the planner's reduction
    densifies them: unit quaternions, ``b_pose`` on ``a``'s hemisphere) and
    finger gaits carry it from ``a``'s grasp, or, with ``via`` states
    ``(7 + nq,)`` at ``a``'s object pose, from the grasp of the first of them
    the hand can regrasp onto with the object fixed
    (:func:`~dexplan.planning.local.grasps.regrasps_onto`).
    """
    tr = ctx.transitions
    s = tr.settings
    ends = np.array([a[:POSE_DIM], b_pose], dtype=float)
    ends[:, 3:] /= np.linalg.norm(ends[:, 3:], axis=1, keepdims=True)
    if float(np.dot(ends[0, 3:], ends[1, 3:])) < 0.0:
        ends[1, 3:] = -ends[1, 3:]
    dense = densify_poses(ends, s.max_step_m, s.max_step_rad)
    q, grasp = a[POSE_DIM:], grasp_from_state(tr, a[:POSE_DIM], a[POSE_DIM:])
    settings = ReductionSettings()
    moves: list[Segment] = []
    if len(via):
        for x in via:
            target = grasp_from_state(tr, x[:POSE_DIM], x[POSE_DIM:])
            moved = regrasps_onto(tr, dense[0], q, grasp, target, settings.same_contact_m)
            if moved is not None:
                moves, q, grasp = moved
                break
        else:
            why = f"no regrasps onto any of {len(via)} other start grasps"
            return LinkReduction(dense, q.copy(), ReductionResult(False, (), 0, why))
    red = reduce_object_path(tr, dense, q, grasp, settings)
    if moves:
        red = dataclasses.replace(red, segments=(*moves, *red.segments))
    return LinkReduction(dense, a[POSE_DIM:].copy(), red)


@dataclass(frozen=True)
class LinkPass:
    """What one :func:`link_pass` did.

    Attributes:
        attempts: link attempts made.
        links: the pairs linked, in the order they were attempted.
    """

    attempts: int
    links: tuple[Pair, ...]


def _never() -> bool:
    return False


def link_pass(
    roadmap: Roadmap,
    groups: Iterable[Sequence[Pair]],
    attempt: Callable[[Sequence[Pair]], Sequence[bool]],
    move_free: Callable[[int, int], bool],
    *,
    stop: Callable[[], bool] = _never,
    tried: set[Pair] | None = None,
    batch: int | None = None,
    after: Callable[[], None] | None = None,
) -> LinkPass:
    """Module 2's link loop: one pass over groups of candidate vertex pairs.

    Each group holds candidates best first. A pair in ``tried`` is skipped
    (and recorded there otherwise), so is a pair the object alone cannot
    move along (``move_free(a, b)`` false: an obstacle in the way).

    Serial (``batch`` None): each group's pairs are attempted in turn until
    one links; ``after()`` follows every attempt; ``stop()`` is asked before
    each group and after each attempt, and ends the pass. Batched (``batch``
    n): the first remaining pair of each group, for up to n groups, are
    attempted together by one ``attempt`` call (tasks that run in parallel).

    Linked pairs join the roadmap's links; in serial mode at once, so that a
    lazily generated group (:func:`component_groups`) sees the merge.

    Args:
        roadmap: the roadmap the links join.
        groups: candidate pairs, one sequence per group (may be a generator).
        attempt: the link attempts of some pairs -> whether each linked.
        move_free: whether the object alone can move straight from a to b.
        stop: ends the pass when true (a deadline, an attempt budget).
        tried: pairs attempted or rejected before, or None to try every pair.
        batch: None for serial attempts, or the most pairs of one batch.
        after: called after each serial attempt (progress reports).

    Returns:
        The attempts made and the pairs linked.
    """
    linked: list[Pair] = []
    pending: list[Pair] = []
    attempts = 0
    for group in groups:
        if batch is None and stop():
            break
        for a, b in group:
            if tried is not None:
                if (a, b) in tried:
                    continue
                tried.add((a, b))
            if not move_free(a, b):
                continue
            if batch is not None:
                pending.append((a, b))
                break
            attempts += 1
            ok = bool(attempt([(a, b)])[0])
            if ok:
                roadmap.add_link(a, b)
                linked.append((a, b))
            if after is not None:
                after()
            if ok or stop():
                break
        if batch is not None and len(pending) >= batch:
            break
    if pending:
        attempts += len(pending)
        for pair, ok in zip(pending, attempt(pending), strict=True):
            if ok:
                roadmap.add_link(*pair)
                linked.append(pair)
    return LinkPass(attempts, tuple(linked))


def component_groups(roadmap: Roadmap, k: int = PAIRS_PER_COMPONENT) -> Iterator[list[Pair]]:
    """Link candidates between the largest component and each other one, largest first.

    Each group is the ``k`` nearest pairs (object-pose distance) from the
    largest component to one other. Groups are made lazily: a component an
    earlier group's link merged into the largest is skipped, and the
    largest's vertices are those of the moment. Nothing when one component
    (or none) is left.
    """
    n_comp, labels = roadmap.components()
    if n_comp < 2:
        return
    sizes = np.bincount(labels, minlength=n_comp)
    first = np.unique(labels, return_index=True)[1]  # first vertex of each component
    order = np.argsort(-sizes, kind="stable")
    main_rep = int(first[order[0]])
    for rep in (int(first[c]) for c in order[1:]):
        _, labels = roadmap.components()
        if labels[rep] == labels[main_rep]:
            continue  # merged on the way
        src = np.flatnonzero(labels == labels[main_rep])
        dst = np.flatnonzero(labels == labels[rep])
        yield nearest_pairs(roadmap.vertices, src, dst, k)


def nearest_pairs(vertices: FloatArray, src: np.ndarray, dst: np.ndarray, k: int) -> list[Pair]:
    """The ``k`` nearest ``(a in src, b in dst)`` pairs by object-pose distance.

    Args:
        vertices: (N, 7 + nq) roadmap vertices.
        src: vertex indices of the pairs' first ends.
        dst: vertex indices of their second ends.
        k: pairs wanted.
    """
    best: list[tuple[float, int, int]] = []
    for chunk in np.array_split(src, max(1, len(src) // 512)):
        d = pose_distances(vertices[chunk][:, None, :], vertices[dst][None, :, :])
        flat = np.argsort(d, axis=None, kind="stable")[:k]
        for f in flat:
            i, j = divmod(int(f), len(dst))
            best.append((float(d[i, j]), int(chunk[i]), int(dst[j])))
    best.sort()
    return [(a, b) for _, a, b in best[:k]]


def link_query(
    ctx: PlanningContext,
    roadmap: Roadmap,
    query: GsnQuery,
    start: int,
    deadline: float,
    stats: GsnStats,
    max_attempts: int | None = None,
    geodesic: Geodesic | None = None,
    links: list[LinkReduction] | None = None,
    waypoints: int = 0,
) -> GsnResult:
    """Module 2: join the start's component to the goal region with links, then search.

    Goal vertices are the roadmap vertices in the goal region, plus sampled
    goal states when there are none. Component pairs are tried nearest first
    (object-pose distance, :func:`link_pass`); every successful link merges
    two components. The path's GSn edges are densified with ``geodesic``
    when given. ``stats`` counts ``module2_attempts``, ``module2_links``,
    ``module2_time_s`` (and ``module2_waypoints`` when some were added) and
    gets ``components_after_links``.

    Each attempt runs on a random stream of its own (:func:`_query_attempt`).
    Successful links are appended to ``links`` (the result carries them all).

    When no candidate can be tried (no other vertex, or the object alone
    cannot move straight to any: an obstacle in the way) and ``waypoints``
    is positive, up to that many RLG states join the roadmap once, as
    vertices of their own, so that links can go round the obstacle through
    their object poses (a planner whose graph holds only its trees, often
    just the start, leaves module 2 nothing else to link to when an
    obstacle blocks the object's straight move).
    """
    links = [] if links is None else links
    t0 = time.perf_counter()
    goals = _goal_vertices(roadmap, query, deadline)
    attempt = _query_attempt(ctx, roadmap, query, start, set(goals), stats, links)
    first = int(stats["module2_attempts"])

    def budget_left() -> bool:
        return max_attempts is None or int(stats["module2_attempts"]) - first < max_attempts

    def stop() -> bool:
        return not budget_left() or time.perf_counter() >= deadline

    def move_free(a: int, b: int) -> bool:
        return object_move_free(ctx, roadmap.vertices[a], roadmap.vertices[b])

    path_ids = None
    seeded = waypoints <= 0
    while time.perf_counter() < deadline:
        path_ids = roadmap.shortest_path(start, goals) if goals else None
        if path_ids is not None or not goals:
            break
        done = link_pass(
            roadmap, [_goal_candidates(roadmap, start, goals)], attempt, move_free, stop=stop
        )
        if not done.links and done.attempts == 0 and budget_left() and not seeded:
            seeded = True  # nothing could be tried: waypoints round the obstacle, once
            added = rlg_states(ctx, waypoints, deadline)
            for x in added:
                roadmap.add_vertex(x)
            stats["module2_waypoints"] = stats.get("module2_waypoints", 0) + len(added)
            continue
        if not done.links:
            break
    if path_ids is None and goals:
        # a link made as the time ran out (an attempt runs to its end)
        path_ids = roadmap.shortest_path(start, goals)
    stats["module2_time_s"] += time.perf_counter() - t0
    stats["components_after_links"] = roadmap.components()[0]
    if path_ids is None:
        return GsnResult(
            None, roadmap, stats, "start and goal are not connected in GSn", tuple(links)
        )
    return GsnResult(roadmap.path_states(path_ids, geodesic), roadmap, stats, links=tuple(links))


def _goal_vertices(roadmap: Roadmap, query: GsnQuery, deadline: float) -> list[int]:
    """The roadmap's vertices in the goal region; sampled goal states join it when none."""
    goals = [i for i, x in enumerate(roadmap.vertices) if query.goal_test(x)[0]]
    while not goals and time.perf_counter() < deadline:
        g = query.goal_sampler()
        if g is not None:
            goals.append(roadmap.add_vertex(g))
    return goals


def _query_attempt(
    ctx: PlanningContext,
    roadmap: Roadmap,
    query: GsnQuery,
    start: int,
    goal_set: set[int],
    stats: GsnStats,
    links: list[LinkReduction],
) -> Callable[[Sequence[Pair]], list[bool]]:
    """The link attempts of a query's module 2 (counted in ``stats``; links kept in ``links``).

    Each attempt runs on a random stream of its own (the context's seed and
    the attempt's number), so a link's regrasps do not depend on how many
    attempts came before within a pass the clock ended. Every attempt from
    the start after the query's first one first regrasps onto another
    sampled start grasp (with a many-fingered hand the gaits from some start
    grasps stall within a few degrees whatever the landings, from others
    they turn the object in seconds). Links into the goal region end on
    ``query.goal_pose`` when given.
    """

    def one(a: int, b: int) -> bool:
        stats["module2_attempts"] += 1
        n = int(stats["module2_attempts"])
        ctx.reseed_local_planners(ctx.seed, 3, n)
        goal_pose = query.goal_pose
        to_goal = goal_pose is not None and b in goal_set
        b_pose = goal_pose if goal_pose is not None and to_goal else roadmap.vertices[b][:POSE_DIM]
        # after the first, attempts from the start begin by regrasping onto
        # another start grasp: gaits that stall do so from some grasps
        via = _other_grasps(ctx, roadmap.vertices[a], n) if a == start and n > 1 else []
        link = link_reduction(ctx, roadmap.vertices[a], b_pose, via)
        if link.result.success:
            links.append(link)
            stats["module2_links"] += 1
        return link.result.success

    return lambda pairs: [one(a, b) for a, b in pairs]


def module2_round(
    ctx: PlanningContext,
    roadmap: Roadmap,
    query: GsnQuery,
    starts: Sequence[int],
    deadline: float,
    stats: GsnStats,
    geodesic: Geodesic,
    links: list[LinkReduction],
    waypoints: int,
) -> GsnResult:
    """Module 2 after a module-1 round of a single query without a path.

    Links start from the planner's first start vertex, or from the query's
    start state added as a vertex when the planner's graph has none; see
    :func:`_module2_pass` for the time they get.
    """
    start = starts[0] if starts else roadmap.add_vertex(query.start)
    return _module2_pass(ctx, roadmap, query, start, deadline, stats, geodesic, links, waypoints)


def _module2_pass(
    ctx: PlanningContext,
    roadmap: Roadmap,
    query: GsnQuery,
    start: int,
    deadline: float,
    stats: GsnStats,
    geodesic: Geodesic,
    links: list[LinkReduction],
    waypoints: int = 0,
) -> GsnResult:
    """Module 2 of a single query: a few links from the start's component towards the goal.

    Attempts start within :data:`MODULE2_SHARE` of the time left, so that
    module 1 grows its roadmap again when the links fail; an attempt that
    has started runs to its end (or the query's deadline). A many-DOF hand's
    link takes seconds: cut at the share's end, a link nearly through would
    be lost and the next pass would start it over.
    """
    t_now = time.perf_counter()
    link_by = t_now + MODULE2_SHARE * max(0.0, deadline - t_now)
    return link_query(
        ctx,
        roadmap,
        query,
        start,
        link_by,
        stats,
        max_attempts=4,
        geodesic=geodesic,
        links=links,
        waypoints=waypoints,
    )


def _other_grasps(ctx: PlanningContext, x: FloatArray, attempt: int) -> list[FloatArray]:
    """Other valid states at ``x``'s object pose, from a stream of the attempt's own."""
    rng = np.random.default_rng([ctx.seed, 4, attempt])
    return ctx.sampler.samples_at_pose(x[:POSE_DIM], OTHER_GRASPS, rng)


def _goal_candidates(roadmap: Roadmap, start: int, goals: list[int]) -> list[Pair]:
    """Module-2 link candidates of a query, best first (:func:`_link_candidates`)."""
    src, dst, order = _link_candidates(roadmap, start, goals)
    return [(int(src[flat // len(dst)]), int(dst[flat % len(dst)])) for flat in order]


def _link_candidates(
    roadmap: Roadmap, start: int, goals: list[int]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Module-2 link candidates from the start's component, best first.

    The start straight to the goal's vertices comes first. Other pairs are
    ranked by link length plus how far the far end still is from the goal:
    links straight into a goal component come first, links into other
    components (merged on the way, as in the paper) next.

    Returns:
        ``(src, dst, order)``: the start component's vertices, the other
        vertices, and the first 64 pairs as flat indices into
        ``len(src) x len(dst)``.
    """
    _, labels = roadmap.components()
    src = np.flatnonzero(labels == labels[start])
    dst = np.flatnonzero(labels != labels[start])
    if len(dst) == 0:
        return src, dst, np.zeros(0, dtype=np.int64)
    goal_v = roadmap.vertices[goals[0]]
    to_goal = np.array([pose_distance(roadmap.vertices[b], goal_v) for b in dst])
    to_goal[np.isin(labels[dst], labels[goals])] = 0.0
    d = np.array(
        [[pose_distance(roadmap.vertices[a], roadmap.vertices[b]) for b in dst] for a in src]
    )
    d = d + to_goal[None, :]
    # the start straight to the goal first: a link there is the whole plan (the
    # reduction of the query's path reuses it), while links between other
    # vertices turn the object about axes the task never asked for, only for
    # the query's reduction to redo the gaits along the path that results
    d[np.flatnonzero(src == start)[:, None], np.flatnonzero(np.isin(dst, goals))[None, :]] = -1.0
    return src, dst, np.argsort(d, axis=None, kind="stable")[:64]
