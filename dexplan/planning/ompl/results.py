"""What planning returns: solve results, re-checked paths, planner graphs.

Plain frozen dataclasses of NumPy arrays in ambient coordinates (no OMPL objects),
and OMPL's ``PlannerStatus`` values by name.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from dexplan.core.typing import FloatArray, IntArray
from dexplan.planning.ompl.spaces import Frame

__all__ = ["STATUS_NAMES", "PathCheck", "RoadmapData", "SolveResult", "read_planner_data"]


@dataclass(frozen=True, eq=False)
class RoadmapData:
    """A planner's graph, extracted from ``ob.PlannerData``.

    Attributes:
        vertices: ``(N, n)`` ambient states.
        edges: ``(E, 2)`` int64 vertex indices ``(from, to)`` as OMPL reports them
            (the PRM family reports each undirected edge in both directions).
        start_ids: ``(S,)`` int64 indices of start vertices.
        goal_ids: ``(G,)`` int64 indices of goal vertices.

    """

    vertices: FloatArray
    edges: IntArray
    start_ids: IntArray
    goal_ids: IntArray

    @property
    def num_vertices(self) -> int:
        """N, the number of vertices."""
        return int(self.vertices.shape[0])


@dataclass(frozen=True, eq=False)
class PathCheck:
    """A path re-checked in travel direction.

    See :meth:`~dexplan.planning.ompl.problem.PlanningProblem.check_path`.

    Attributes:
        path: ``(K, n)`` ambient states: the densified discrete geodesics when
            interpolating, else the waypoints.
        waypoints: ``(M, n)`` ambient waypoints that were checked.
        path_valid: every state of ``path`` is on the manifold (within tolerance), in
            bounds and valid, and every segment is a valid motion in travel direction
            (directly or after repair).
        repaired_segments: segments ``i`` (``i -> i+1``) whose forward motion failed
            but whose reverse motion was valid; their states are the reversed reverse
            geodesic.
        invalid_segments: segments that failed both ways, or with an invalid end.
        max_step: largest planning-space distance between consecutive path states.

    """

    path: FloatArray
    waypoints: FloatArray
    path_valid: bool
    repaired_segments: tuple[int, ...]
    invalid_segments: tuple[int, ...]
    max_step: float


@dataclass(frozen=True, eq=False)
class SolveResult:
    """Outcome of :meth:`~dexplan.planning.ompl.problem.PlanningProblem.solve`.

    Attributes:
        status: ``"exact"``, ``"approximate"``, ``"timeout"``, ``"invalid_start"``,
            ``"invalid_goal"``, ``"unrecognized_goal"``, ``"crash"``, ``"abort"``,
            ``"infeasible"``, ``"unknown"`` (OMPL's statuses), or ``"path_invalid"``:
            OMPL reported an exact solution that fails the travel-direction re-check.
        solved: exact solution whose every state and segment passed the re-check.
        path: ``(K, n)`` ambient states in travel order (densified along the
            discrete geodesics when ``interpolate``), or None without a path.
        waypoints: ``(M, n)`` ambient states the planner returned, or None.
        time_s: wall time of the call.
        planner: planner name.
        path_valid: every path state satisfies the constraint within tolerance, the
            bounds and ``is_valid``, and every segment is a valid motion in travel
            direction (directly or after repair). False without a path.
        repaired_segments: waypoint segments ``i`` (``i -> i+1``) whose forward motion
            failed but whose reverse motion was valid; their states are the reversed
            geodesic (direction-dependent projection).
        invalid_segments: waypoint segments that failed both ways.
        max_step: largest planning-space distance between consecutive path states.
        goal_distance: OMPL's solution difference (0 for exact), NaN without a path.
        message: short human-readable detail.

    """

    status: str
    solved: bool
    path: FloatArray | None
    waypoints: FloatArray | None
    time_s: float
    planner: str
    path_valid: bool
    repaired_segments: tuple[int, ...] = ()
    invalid_segments: tuple[int, ...] = ()
    max_step: float = math.nan
    goal_distance: float = math.nan
    message: str = ""

    @classmethod
    def without_path(cls, status: str, planner: str, time_s: float, message: str) -> SolveResult:
        """The result of a solve that found no path."""
        return cls(
            status=status,
            solved=False,
            path=None,
            waypoints=None,
            time_s=time_s,
            planner=planner,
            path_valid=False,
            message=message,
        )

    @classmethod
    def with_path(
        cls,
        status: str,
        checked: PathCheck,
        checked_path: bool,
        planner: str,
        time_s: float,
        goal_distance: float,
        message: str,
    ) -> SolveResult:
        """The result of a solve whose path was re-checked (``checked_path``) into ``checked``.

        An ``exact`` path that fails the re-check becomes ``path_invalid``.
        """
        valid = checked.path_valid
        final = "path_invalid" if (status == "exact" and checked_path and not valid) else status
        return cls(
            status=final,
            solved=final == "exact" and valid,
            path=checked.path,
            waypoints=checked.waypoints,
            time_s=time_s,
            planner=planner,
            path_valid=valid,
            repaired_segments=checked.repaired_segments,
            invalid_segments=checked.invalid_segments,
            max_step=checked.max_step,
            goal_distance=goal_distance,
            message=message,
        )


STATUS_NAMES: dict[int, str] = {
    0: "unknown",
    1: "invalid_start",
    2: "invalid_goal",
    3: "unrecognized_goal",
    4: "timeout",
    5: "approximate",
    6: "exact",
    7: "crash",
    8: "abort",
    9: "infeasible",
}
"""OMPL ``PlannerStatus`` values by name (the ``status`` of :class:`SolveResult`)."""


def read_planner_data(
    pd: Any, frame: Frame, n: int, given_starts: FloatArray | None
) -> RoadmapData:
    """A filled ``ob.PlannerData`` as :class:`RoadmapData` in ambient coordinates.

    Start ids are the vertices that are the query's start states
    (``given_starts``: ``(S, n)`` in planning coordinates, or None): FMT
    reports every sample it never connected as a start vertex
    (``FMT::getPlannerData`` marks each parent-less motion so), and a caller
    taking those for starts would link the start to its own copies.
    """
    count = int(pd.numVertices())
    read = frame.read
    vertices = np.empty((count, n), dtype=np.float64)
    pairs: list[tuple[int, int]] = []
    for i in range(count):
        vertices[i] = read(pd.getVertex(i).getState())
        pairs.extend((i, int(j)) for j in pd.getEdges(i))
    edges = np.array(pairs, dtype=np.int64).reshape(-1, 2)
    starts = np.array([pd.getStartIndex(k) for k in range(pd.numStartVertices())], dtype=np.int64)
    if len(starts) and given_starts is not None:
        given = given_starts
        gap = np.abs(vertices[starts][:, None, :] - given[None, :, :]).max(axis=2).min(axis=1)
        starts = starts[gap <= 1e-9 * (1.0 + np.abs(given).max())]
    goals = np.array([pd.getGoalIndex(k) for k in range(pd.numGoalVertices())], dtype=np.int64)
    return RoadmapData(vertices=frame.to_x(vertices), edges=edges, start_ids=starts, goal_ids=goals)
