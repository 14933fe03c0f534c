"""Module 1: explore GSn with an OMPL planner, in rounds, until a path is found.

The OMPL planner (through :mod:`dexplan.planning.ompl`, the only package that
imports OMPL) grows its graph in rounds of doubling work; what it explored is
kept as a :class:`~dexplan.planning.roadmap.graph.Roadmap`. After a round
without a path, module 2 (:mod:`~dexplan.planning.roadmap.module2`) tries a
few transfer-regrasp links towards the goal region.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from dexplan.core.typing import FloatArray
from dexplan.planning.context import PlanningContext
from dexplan.planning.gsn.chart import ChartProblem
from dexplan.planning.ompl import PlanningProblem, planner_traits
from dexplan.planning.progress import Stage
from dexplan.planning.roadmap.graph import Geodesic, Roadmap, scenario_key
from dexplan.planning.roadmap.module2 import MODULE2_WAYPOINTS, module2_round
from dexplan.planning.roadmap.problems import search_problem
from dexplan.planning.roadmap.search import GsnQuery, GsnResult, GsnStats, LinkReduction

__all__ = ["ROUND_ITERATIONS", "ROUND_MILESTONES", "explore_gsn"]


ROUND_ITERATIONS = 50
"""Planner iterations of a tree planner's first module-1 round (doubling per round)."""

ROUND_MILESTONES = 4
"""Roadmap size after a PRM-family planner's first module-1 round (doubling per round)."""


def explore_gsn(
    ctx: PlanningContext,
    query: GsnQuery,
    planner: str,
    *,
    params: Mapping[str, Any] | None = None,
    space: str = "projected",
    seed: int = 1,
    deadline: float,
    module2: bool = True,
    on_round: Callable[[Stage, Mapping[str, int]], None] | None = None,
) -> GsnResult:
    """Module 1 (+ module 2 when needed): a GSn path from the start to the goal region.

    The paper's single-query scheme: the OMPL planner grows its roadmap in
    rounds; after each round without a path, module 2 tries a few
    transfer-regrasp links between the start's component and the goal
    region's, and the query stops as soon as they are connected. With
    ``module2=False`` the OMPL planner alone runs until the deadline.

    Rounds are counted in work, not time, so the same seed gives the same
    path whenever the deadline does not cut the search short: tree planners
    run :data:`ROUND_ITERATIONS` planner iterations (doubling each round); the
    PRM family, whose own ``solve`` is multi-threaded and time-sliced, grows
    its roadmap single-threaded to :data:`ROUND_MILESTONES` milestones
    (doubling), after which start and goal are connected into it and the
    roadmap is searched.

    ``on_round(stage, counts)`` is called after each module-1 round
    (:attr:`Stage.MODULE1`: rounds, nodes, edges, components) and each
    module-2 pass (:attr:`Stage.MODULE2`: attempts, links), so a caller can
    show the search as it runs.
    """
    t0 = time.perf_counter()
    report = on_round or (lambda _stage, _counts: None)
    problem = search_problem(ctx, query, planner, params, space, seed)
    key = scenario_key(ctx)
    stats: GsnStats = {"module2_attempts": 0, "module2_links": 0, "module2_time_s": 0.0}
    iterations, milestones, rounds = ROUND_ITERATIONS, ROUND_MILESTONES, 0
    links: list[LinkReduction] = []  # every pass's, for the planner to reuse
    waypoints = MODULE2_WAYPOINTS if planner_traits(planner).waypoints else 0
    while True:
        rounds += 1
        roadmap, starts, path, status = _module1_round(
            ctx, problem, query, planner, key, deadline, iterations, milestones
        )
        _round_stats(stats, problem, roadmap, "exact" if path is not None else status, rounds, t0)
        counts = {"rounds": rounds, "nodes": roadmap.n_vertices, "edges": len(roadmap.edges)}
        report(Stage.MODULE1, {**counts, "components": stats["components"]})
        if path is not None:
            return GsnResult(path, roadmap, stats, links=tuple(links))
        iterations *= 2
        milestones *= 2
        if not module2:
            if time.perf_counter() >= deadline - 0.05:
                return GsnResult(None, roadmap, stats, "no GSn path within the time limit")
            continue
        geodesic = _geodesic(problem)
        linked = module2_round(
            ctx, roadmap, query, starts, deadline, stats, geodesic, links, waypoints
        )
        stats["gsn_time_s"] = time.perf_counter() - t0
        report(
            Stage.MODULE2,
            {"attempts": int(stats["module2_attempts"]), "links": int(stats["module2_links"])},
        )
        if linked.path is not None or time.perf_counter() >= deadline - 0.05:
            return linked


def _round_stats(
    stats: GsnStats,
    problem: PlanningProblem | ChartProblem,
    roadmap: Roadmap,
    status: str,
    rounds: int,
    t0: float,
) -> None:
    """Update ``stats`` after a module-1 round (``t0``: the query's start, perf_counter s)."""
    stats.update(
        {
            "gsn_status": status,
            "gsn_rounds": rounds,
            "gsn_time_s": time.perf_counter() - t0,
            "roadmap_nodes": roadmap.n_vertices,
            "roadmap_edges": len(roadmap.edges),
            "components": roadmap.components()[0],
        }
    )
    if isinstance(problem, PlanningProblem):
        tried, joined, _ = problem.fallback_motions
        stats["geodesic_motion_attempts"] = tried
        stats["geodesic_motion_edges"] = joined


def _module1_round(
    ctx: PlanningContext,
    problem: PlanningProblem | ChartProblem,
    query: GsnQuery,
    planner: str,
    key: str,
    deadline: float,
    iterations: int,
    milestones: int,
) -> tuple[Roadmap, list[int], FloatArray | None, str]:
    """One round of module 1: grow the OMPL planner's graph, look for a path.

    Returns:
        ``(roadmap, start vertex ids, path or None, OMPL status)``.
    """
    remaining = max(0.05, deadline - time.perf_counter())
    if problem.is_multi_query:
        problem.grow_roadmap(remaining, max_milestones=milestones)
        res = problem.solve(1e-6)  # only connects start and goal milestones into it
    else:
        res = problem.solve(remaining, max_iterations=iterations)
    data = problem.planner_data()
    roadmap = Roadmap(
        np.asarray(data.vertices, dtype=float).reshape(-1, ctx.gsn.ambient_dim),
        np.asarray(data.edges, dtype=np.int64).reshape(-1, 2),
        np.zeros((0, 2), dtype=np.int64),
        planner,
        key,
    )
    starts = [int(i) for i in np.asarray(data.start_ids, dtype=int)]
    path = None
    if res.solved and res.path is not None and len(res.path):
        path = np.asarray(res.path)
    elif problem.is_multi_query and starts:
        path = _roadmap_path(problem, roadmap, starts[0], query)
    return roadmap, starts, path, res.status


def _roadmap_path(
    problem: PlanningProblem | ChartProblem, roadmap: Roadmap, start: int, query: GsnQuery
) -> FloatArray | None:
    """Shortest roadmap path from ``start`` into the goal region, densified on GSn.

    None when there is none, or when a roadmap edge is not a valid motion in
    the travel direction (the projected motion depends on its direction: a->b may be valid where
    b->a is not).
    """
    goals = [i for i, x in enumerate(roadmap.vertices) if query.goal_test(x)[0]]
    ids = roadmap.shortest_path(start, goals) if goals else None
    if ids is None:
        return None
    checked = problem.check_path(roadmap.vertices[ids], interpolate=True)
    return np.asarray(checked.path) if checked.path_valid else None


def _geodesic(problem: PlanningProblem | ChartProblem) -> Geodesic:
    """GSn motions of a roadmap's edges, re-checked in travel direction."""

    def states(a: FloatArray, b: FloatArray) -> FloatArray | None:
        checked = problem.check_path(np.stack([a, b]), interpolate=True)
        return np.asarray(checked.path) if checked.path_valid else None

    return states
