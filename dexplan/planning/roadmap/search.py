"""A GSn search: its query, its result, and module 2's link reductions.

Module 1 and module 2 (:mod:`~dexplan.planning.roadmap.module1`,
:mod:`~dexplan.planning.roadmap.module2`) and the multi-query answer
(:mod:`~dexplan.planning.roadmap.queries`) take a :class:`GsnQuery` and give a
:class:`GsnResult`; the planner reduces its path and reuses the links'
reductions (:class:`LinkReduction`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TypedDict

import numpy as np

from dexplan.core.typing import FloatArray
from dexplan.planning.local.reduction import ReductionResult
from dexplan.planning.roadmap.graph import Roadmap

__all__ = ["GsnQuery", "GsnResult", "GsnStats", "LinkReduction"]


@dataclass(frozen=True)
class GsnQuery:
    """A GSn query: start state, goal test and goal-state sampler.

    Attributes:
        start: (7 + nq,) start state on GSn.
        goal_test: maps a state to (in goal region, distance to it).
        goal_sampler: returns a valid GSn state in the goal region, or None.
        goal_pose: (7,) the goal object pose itself, when the region has one:
            module-2 links into the goal region end there, the pose the
            planner's reduction ends on (so it can reuse them).
    """

    start: FloatArray
    goal_test: Callable[[FloatArray], tuple[bool, float]]
    goal_sampler: Callable[[], FloatArray | None]
    goal_pose: FloatArray | None = None


@dataclass(frozen=True)
class LinkReduction:
    """A successful module-2 link: the transfers and regrasps that make it.

    The planner reduces its GSn path's object trajectory afresh; when that
    trajectory is a link's own (a link from the start straight into the goal
    region), it takes the link's reduction instead of redoing it (seconds on a
    many-DOF hand, and a fresh try can fail where the link went through).

    Attributes:
        poses: (P, 7) the dense object trajectory the link followed.
        q_start: (nq,) hand joints at its start.
        result: its reduction (successful).
    """

    poses: FloatArray
    q_start: FloatArray
    result: ReductionResult

    def matches(self, poses: FloatArray, q_start: FloatArray, tol: float = 1e-9) -> bool:
        """Whether it follows ``poses: (P, 7)`` from ``q_start: (nq,)`` (quaternion sign free)."""
        if poses.shape != self.poses.shape or not np.allclose(q_start, self.q_start, atol=tol):
            return False
        dots = np.abs(np.sum(poses[:, 3:] * self.poses[:, 3:], axis=1))
        same_place = np.allclose(poses[:, :3], self.poses[:, :3], atol=tol)
        return bool(same_place and np.all(dots > 1 - tol))


class GsnStats(TypedDict, total=False):
    """Figures of modules 1 and 2 for one query (the plan's ``stats`` of the same names).

    A typed mapping rather than a dataclass: callers pass their own running
    tally to :func:`~dexplan.planning.roadmap.module2.link_query`, which adds to it.
    See :class:`~dexplan.planning.stats.PlanStats` for what each figure means.
    """

    module2_attempts: int
    module2_links: int
    module2_time_s: float
    module2_waypoints: int
    gsn_status: str
    gsn_rounds: int
    gsn_time_s: float
    roadmap_nodes: int
    roadmap_edges: int
    components: int
    components_after_links: int
    geodesic_motion_attempts: int
    geodesic_motion_edges: int


@dataclass(frozen=True)
class GsnResult:
    """Outcome of module 1 (+ module 2) for one query.

    Attributes:
        path: (K, 7 + nq) GSn states from start to goal, or None.
        roadmap: the roadmap (with start and goal vertices added).
        stats: planner and module-2 figures.
        message: detail when there is no path.
        links: the module-2 links made for this query, with their reductions.
    """

    path: FloatArray | None
    roadmap: Roadmap
    stats: GsnStats = field(default_factory=lambda: GsnStats())
    message: str = ""
    links: tuple[LinkReduction, ...] = ()
