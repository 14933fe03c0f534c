"""A GSn path found elsewhere (a user's own OMPL planner), joined up by module 2.

The path's states become a roadmap: each state a vertex, each segment an
edge when it is a valid GSn motion in travel direction. Where a segment is
not (a planner that returned coarse or lazily checked waypoints), and where
the path ends outside the goal region, module 2
(:func:`~dexplan.planning.roadmap.module2.link_query`) joins the pieces with
transfer-regrasp links, exactly as it joins a planner's roadmap components.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable

import numpy as np

from dexplan.core.typing import FloatArray
from dexplan.planning.context import PlanningContext
from dexplan.planning.roadmap.graph import Roadmap, scenario_key
from dexplan.planning.roadmap.module2 import link_query
from dexplan.planning.roadmap.search import GsnQuery, GsnResult, GsnStats

__all__ = ["link_given_path"]


def link_given_path(
    ctx: PlanningContext,
    path: FloatArray,
    query: GsnQuery,
    geodesic: Callable[[FloatArray, FloatArray], FloatArray | None],
    deadline: float,
    planner: str,
) -> GsnResult:
    """A GSn path from ``path[0]`` into the goal region along ``path: (K, 7 + nq)``.

    Args:
        ctx: the planning context.
        path: valid GSn states, the first the query's start.
        query: the query (its goal test and goal sampler).
        geodesic: ``(a, b) -> (M, 7 + nq)`` states of the GSn motion a -> b,
            checked in travel direction, or None where it is not valid.
        deadline: ``time.perf_counter()`` at which module 2 stops.
        planner: the name of the planner that found ``path`` (the roadmap's).

    Returns:
        The joined, densified path (``stats`` count module 2's attempts and
        links), or a result without a path when module 2 found no link.
    """
    path = np.array(path, dtype=np.float64)
    motions: dict[tuple[int, int], FloatArray | None] = {}
    for i, j in itertools.pairwise(range(len(path))):
        motions[(i, j)] = geodesic(path[i], path[j])
    edges = np.array([pair for pair, m in motions.items() if m is not None], dtype=np.int64)
    roadmap = Roadmap(
        path,
        edges.reshape(-1, 2),
        np.zeros((0, 2), dtype=np.int64),
        planner,
        scenario_key(ctx),
    )
    stats: GsnStats = {
        "module2_attempts": 0,
        "module2_links": 0,
        "module2_time_s": 0.0,
        "roadmap_nodes": roadmap.n_vertices,
        "roadmap_edges": len(roadmap.edges),
        "components": roadmap.components()[0],
    }

    by_ends = {(path[i].tobytes(), path[j].tobytes()): m for (i, j), m in motions.items()}

    def known(a: FloatArray, b: FloatArray) -> FloatArray | None:
        # the motions checked above, by their end states (path_states passes states)
        key = (np.asarray(a, dtype=np.float64).tobytes(), np.asarray(b, dtype=np.float64).tobytes())
        states = by_ends.get(key)
        return states if states is not None else geodesic(a, b)

    return link_query(ctx, roadmap, query, 0, deadline, stats, geodesic=known)
