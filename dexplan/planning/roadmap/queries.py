"""Multi-query: answer a query on a roadmap built beforehand.

A query's start and goal states join the roadmap as PRM joins them: by GSn
motions (re-checked in travel direction) to their nearest roadmap vertices in
object-pose distance. The shortest path of the roadmap's GSn edges and
module-2 links then joins them. Only when it cannot (start and goal in
different components, or not joined at all) is the roadmap grown: start and
goal become vertices with the edges found, and module 2 links components
(:func:`~dexplan.planning.roadmap.module2.link_query`); what it adds stays in the
roadmap, so a later query (and ``--save-roadmap``) has it.

The roadmap is not changed by a query it answers.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from dexplan.core.errors import RoadmapFileError
from dexplan.core.typing import FloatArray
from dexplan.planning.context import PlanningContext
from dexplan.planning.ompl import PlanningProblem
from dexplan.planning.roadmap.graph import Roadmap, pose_distances
from dexplan.planning.roadmap.module2 import link_query, object_move_free
from dexplan.planning.roadmap.problems import constraint_spec, geodesic_fallback
from dexplan.planning.roadmap.search import GsnQuery, GsnResult, GsnStats

NEAREST = 10
"""Roadmap vertices tried, nearest first, when joining a start or goal state."""

JOINED = 1
"""GSn motions kept per joined state (the nearest that works)."""

_JOIN_CACHE: dict[tuple[int, bytes, bool], tuple[FloatArray, list[int]]] = {}
_JOIN_CACHE_SIZE = 64
"""Joins remembered (queries from one start join the roadmap the same way)."""

GOAL_SAMPLES = 60
"""Goal sampler calls before a query gives up on a goal grasp (within its deadline).

20 gave up on 7 of 50 random cube_obstacle goals that have grasps: a box
near the table or the post has few, and the sampler finds them rarely.
"""


def query_problem(ctx: PlanningContext, space: str = "projected") -> PlanningProblem:
    """The OMPL space a query's GSn motions are checked in (no planner run).

    Its motion checks are OMPL's (cheap enough for build tasks and joins,
    and a function of their two states, so workers agree); on meshes
    :meth:`~PlanningProblem.interpolate_path` densifies a roadmap edge that
    OMPL's motion does not join along module 1's section VI motion
    (:func:`~dexplan.planning.roadmap.problems.geodesic_fallback`), which joined it
    when the roadmap grew.
    """
    return PlanningProblem(
        constraint_spec(ctx, space),
        ctx.validity.is_valid,
        planner="PRM",
        seed=None,
        motion_fallback=geodesic_fallback(ctx),
        fallback_checks=False,
    )


def answer_query(
    ctx: PlanningContext,
    roadmap: Roadmap,
    query: GsnQuery,
    *,
    deadline: float,
    space: str = "projected",
) -> GsnResult:
    """A GSn path from the query's start to its goal region through the roadmap.

    Args:
        ctx: the query's planning context.
        roadmap: the roadmap; grown (vertices, edges and links added) only when
            the query cannot be answered on it as it is.
        query: start state, goal test and goal sampler.
        deadline: ``time.perf_counter()`` time to give up at.
        space: the constrained state space (``[planner] space``).

    Returns:
        The :class:`GsnResult`; ``stats["gsn_status"]`` is ``roadmap`` when the
        roadmap answered as it was, ``roadmap_grown`` when it had to grow
        (``module2_links`` links added).

    Raises:
        RoadmapFileError: the roadmap's vertices are not states of this hand.
    """
    width = roadmap.vertices.shape[1] if roadmap.vertices.ndim == 2 else -1
    if width != ctx.gsn.ambient_dim:
        raise RoadmapFileError(
            f"roadmap vertices have {width} columns, this hand's states have "
            f"{ctx.gsn.ambient_dim} (7 + nq)"
        )
    t0 = time.perf_counter()
    problem = query_problem(ctx, space)
    stats: GsnStats = {
        "gsn_status": "roadmap",
        "roadmap_nodes": roadmap.n_vertices,
        "roadmap_edges": len(roadmap.edges),
        "components": roadmap.components()[0],
        "module2_attempts": 0,
        "module2_links": 0,
        "module2_time_s": 0.0,
    }
    goal = None
    for _ in range(GOAL_SAMPLES):
        if time.perf_counter() >= deadline:
            break
        goal = query.goal_sampler()
        if goal is not None:
            break
    if goal is None:
        stats["gsn_time_s"] = time.perf_counter() - t0
        return GsnResult(None, roadmap, stats, "no valid grasp found at the goal pose")
    start = query.start
    if problem.check_motion(start, goal):  # no roadmap needed
        stats["gsn_time_s"] = time.perf_counter() - t0
        ends = [roadmap.n_vertices, roadmap.n_vertices + 1]
        return GsnResult(_path_states(ctx, problem, roadmap, start, goal, ends), roadmap, stats)
    s_edges = _join(problem, roadmap, start, forward=True, deadline=deadline)
    g_edges = _join(problem, roadmap, goal, forward=False, deadline=deadline)
    ids = _search(roadmap, start, goal, s_edges, g_edges)
    if ids is not None:
        states = _path_states(ctx, problem, roadmap, start, goal, ids)
        stats["gsn_time_s"] = time.perf_counter() - t0
        return GsnResult(states, roadmap, stats)
    # grow the roadmap: start and goal join it, module 2 links components
    stats["gsn_status"] = "roadmap_grown"
    s_id = roadmap.add_vertex(start)
    g_id = roadmap.add_vertex(goal)
    new = [(s_id, v) for v in s_edges] + [(v, g_id) for v in g_edges]
    if new:
        roadmap.edges = np.vstack([roadmap.edges, np.array(new, dtype=np.int64)])
    res = link_query(
        ctx, roadmap, query, s_id, deadline, stats, geodesic=lambda a, b: _dense(problem, [a, b])
    )
    res.stats["gsn_time_s"] = time.perf_counter() - t0
    return res


def _dense(problem: PlanningProblem, states: object) -> FloatArray | None:
    """The GSn motion through ``states``, densified and re-checked; None if invalid."""
    checked = problem.check_path(np.asarray(states), interpolate=True)
    return np.asarray(checked.path) if checked.path_valid else None


def _join(
    problem: PlanningProblem, roadmap: Roadmap, x: FloatArray, *, forward: bool, deadline: float
) -> list[int]:
    """Roadmap vertices ``x`` joins by a GSn motion (x -> v if ``forward``, else v -> x)."""
    if roadmap.n_vertices == 0:
        return []
    key = (id(roadmap.vertices), x.tobytes(), forward)
    cached = _JOIN_CACHE.get(key)
    if cached is not None and cached[0] is roadmap.vertices:  # the entry keeps it alive
        return list(cached[1])
    d = pose_distances(roadmap.vertices, x[None, :])
    out: list[int] = []
    for v in np.argsort(d, kind="stable")[:NEAREST]:
        if time.perf_counter() >= deadline:
            break
        a, b = (x, roadmap.vertices[v]) if forward else (roadmap.vertices[v], x)
        if problem.check_motion(a, b):
            out.append(int(v))
            if len(out) >= JOINED:
                break
    if len(out) < JOINED and time.perf_counter() >= deadline:
        return out  # cut short: not remembered
    if len(_JOIN_CACHE) >= _JOIN_CACHE_SIZE:
        _JOIN_CACHE.pop(next(iter(_JOIN_CACHE)))
    _JOIN_CACHE[key] = (roadmap.vertices, list(out))
    return out


def _search(
    roadmap: Roadmap, start: FloatArray, goal: FloatArray, s_edges: list[int], g_edges: list[int]
) -> list[int] | None:
    """Shortest vertex path start -> goal (ids: roadmap vertices, N = start, N + 1 = goal)."""
    if not s_edges or not g_edges:
        return None
    n = roadmap.n_vertices
    verts = np.vstack([roadmap.vertices, start[None], goal[None]])
    parts = [roadmap.edges.reshape(-1, 2), roadmap.links.reshape(-1, 2)]
    parts.append(np.array([(n, v) for v in s_edges] + [(v, n + 1) for v in g_edges]))
    e = np.vstack(parts).astype(np.int64)
    w = pose_distances(verts[e[:, 0]], verts[e[:, 1]]) + 1e-9
    g = coo_matrix(
        (np.concatenate([w, w]), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])),
        shape=(n + 2, n + 2),
    ).tocsr()
    dist, pred = dijkstra(g, indices=n, return_predecessors=True)
    if not np.isfinite(dist[n + 1]):
        return None
    path = [n + 1]
    while path[-1] != n:
        path.append(int(pred[path[-1]]))
    return path[::-1]


def _path_states(
    ctx: PlanningContext,
    problem: PlanningProblem,
    roadmap: Roadmap,
    start: FloatArray,
    goal: FloatArray,
    ids: list[int],
) -> FloatArray:
    """States along a searched path: GSn motions densified, module-2 links as they are.

    The motions were checked when they were made (the roadmap's edges by its
    planner, the joins here), so they are not checked again: the reduction
    follows the path's object trajectory and checks what the hand does along
    it, and the verifier checks the plan. A motion is densified on GSn only
    where the object alone cannot move straight between its ends (an
    obstacle in the way): elsewhere the straight move is what the reduction
    follows anyway (it densifies and shortcuts the object trajectory).
    """
    n = roadmap.n_vertices
    verts = [start if i == n else goal if i == n + 1 else roadmap.vertices[i] for i in ids]
    links = {tuple(sorted(p)) for p in roadmap.links.tolist()}
    out = [verts[0]]
    for k in range(len(ids) - 1):
        a, b = verts[k], verts[k + 1]
        if tuple(sorted((ids[k], ids[k + 1]))) in links or object_move_free(ctx, a, b):
            out.append(b)
        else:
            out.extend(problem.interpolate_path(np.stack([a, b]))[1:])
    return np.array(out)
