"""The reduction property applied edge by edge to a GSn path (paper, section IV).

Each GSn edge ``(pose_a, contacts_a) -> (pose_b, contacts_b)`` becomes a
transfer on the current grasp, or regrasps onto ``contacts_b`` then a
transfer, or regrasps onto ``contacts_a`` then a transfer; when none is valid
the edge is bisected on GSn until every piece is, or a resolution limit is
hit. The bisection's midpoint is the object pose slerp and contacts halfway:
first the world fingertip centres averaged and projected onto the surface;
on a mesh, an edge that fails so is reduced again with each contact halfway
along its surface geodesic (the paper's section VI,
:mod:`dexplan.planning.local.contact_paths`; :attr:`ReductionSettings.midpoints`).
The planner uses it when the finger gaits of :mod:`.reduction` fail.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from dexplan.core.errors import InvalidInputError
from dexplan.core.pose import interpolate_pose, inverse_transform_points
from dexplan.core.segments import Segment, SegmentKind
from dexplan.core.typing import FloatArray
from dexplan.planning.local.contact_paths import ContactPaths
from dexplan.planning.local.grasps import regrasps_onto
from dexplan.planning.local.reduction import (
    Midpoint,
    ReductionResult,
    ReductionSettings,
    reduction_stats,
)
from dexplan.planning.local.transitions import GraspContacts, Transitions, densify_poses


def reduce_gsn_path(
    trans: Transitions,
    poses: FloatArray,
    grasps: Sequence[GraspContacts],
    q_start: FloatArray,
    settings: ReductionSettings | None = None,
    deadline: float | None = None,
) -> ReductionResult:
    """The reduction property, edge by edge: transfers and regrasps along a GSn path.

    Every edge of the path is replaced by (first that is valid)

    1. a transfer on the current grasp;
    2. regrasps onto the edge's end contacts, then a transfer;
    3. regrasps onto the edge's start contacts, then a transfer;

    or else it is bisected and both halves are reduced in turn, at most
    ``settings.max_depth`` times. The grasp is changed only where a transfer
    needs it, so a path that one grasp can follow gives a single transfer.

    Args:
        trans: local planners.
        poses: (K, 7) object poses of the GSn path, XYZW, unit quaternions.
        grasps: K contact sets (object frame), one per GSn state.
        q_start: (nq,) hand configuration holding ``grasps[0]`` at ``poses[0]``.
        settings: limits (``max_depth`` is the resolution limit).
        deadline: ``time.perf_counter()`` value after which it gives up.

    Returns:
        A :class:`ReductionResult`; ``reached`` is the index of the last GSn
        state reached. The failure reason names the edge and the limit hit.
    """
    if len(poses) != len(grasps):
        raise InvalidInputError(f"{len(poses)} poses but {len(grasps)} contact sets")
    # quaternion signs continuous along the path: a transfer ends on the sign
    # its slerp arrives with, and the next edge's regrasps must start there
    poses = np.array(poses, dtype=float)
    for k in range(1, len(poses)):
        if float(np.dot(poses[k - 1, 3:], poses[k, 3:])) < 0.0:
            poses[k, 3:] *= -1.0
    reducer = EdgeReducer(trans, settings or ReductionSettings(), deadline, q_start, grasps[0])
    for k in range(len(poses) - 1):
        if not reducer.whole_edge(poses[k], grasps[k], poses[k + 1], grasps[k + 1]):
            return ReductionResult(
                False,
                tuple(reducer.segments),
                k,
                f"GSn edge {k} -> {k + 1} of {len(poses) - 1}: {reducer.failure}",
                reducer.stats(),
            )
    return ReductionResult(True, tuple(reducer.segments), len(poses) - 1, None, reducer.stats())


class EdgeReducer:
    """State of :func:`reduce_gsn_path`: the hand's current configuration and grasp.

    Args:
        trans: local planners.
        settings: limits.
        deadline: ``time.perf_counter()`` value after which it gives up.
        q: (nq,) hand configuration holding ``grasp`` at the path's first pose.
        grasp: the contacts held there, object frame.
    """

    def __init__(
        self,
        trans: Transitions,
        settings: ReductionSettings,
        deadline: float | None,
        q: FloatArray,
        grasp: GraspContacts,
    ) -> None:
        self.trans = trans
        self.settings = settings
        self.deadline = deadline
        self.q = q.copy()
        self.grasp = grasp
        self.segments: list[Segment] = []
        self.regrasps = 0
        self.bisections = 0
        self.failure = ""
        self.contact_paths = ContactPaths(trans.obj)
        self.midpoint: Midpoint = Midpoint(settings.midpoints[0])
        self.geodesic_midpoints = 0
        self.retries = 0

    def stats(self) -> dict[str, int]:
        """The local planners' counters with the reduction's (regrasps, bisections, midpoints)."""
        out = reduction_stats(self.trans, self.regrasps)
        out["reduction_bisections"] = self.bisections
        out["reduction_geodesic_midpoints"] = self.geodesic_midpoints
        out["reduction_midpoint_retries"] = self.retries
        return out

    def whole_edge(
        self, pa: FloatArray, ca: GraspContacts, pb: FloatArray, cb: GraspContacts
    ) -> bool:
        """Reduce one GSn edge, with each of the settings' midpoint interpolations in turn.

        A failed attempt leaves nothing behind: segments, joints, grasp and
        regrasp count are restored before the next.
        """
        kept = (len(self.segments), self.q, self.grasp, self.regrasps)
        modes = [
            m
            for m in self.settings.midpoints
            if m != Midpoint.GEODESIC or self.contact_paths.active
        ]
        for k, mode in enumerate(modes):
            if k:
                self.retries += 1
                del self.segments[kept[0] :]
                self.q, self.grasp, self.regrasps = kept[1], kept[2], kept[3]
            self.midpoint = Midpoint(mode)
            if self.edge(pa, ca, pb, cb, 0):
                return True
            if self.failure == "time limit reached":
                break
        return False

    def edge(
        self, pa: FloatArray, ca: GraspContacts, pb: FloatArray, cb: GraspContacts, depth: int
    ) -> bool:
        """Reduce the edge ``(pa, ca) -> (pb, cb)``; the hand is at ``pa`` on ``self.grasp``."""
        if self.deadline is not None and time.perf_counter() > self.deadline:
            self.failure = "time limit reached"
            return False
        s = self.trans.settings
        dense = densify_poses(np.stack([pa, pb]), s.max_step_m, s.max_step_rad)
        if self._transfer(dense, [], self.q, self.grasp):
            self._resync(pb, cb)
            return True
        for target in (cb, ca):
            moved = self._regrasps_to(pa, target)
            if moved is not None and self._transfer(dense, *moved):
                return True
        if depth >= self.settings.max_depth:
            self.failure = (
                f"resolution limit: no transfer or regrasp sequence is valid after "
                f"{depth} bisections (max_depth={self.settings.max_depth})"
            )
            return False
        self.bisections += 1
        pm, cm = self._midpoint(pa, ca, pb, cb)
        return self.edge(pa, ca, pm, cm, depth + 1) and self.edge(pm, cm, pb, cb, depth + 1)

    def _transfer(
        self, dense: FloatArray, regrasps: list[Segment], q: FloatArray, grasp: GraspContacts
    ) -> bool:
        """Transfer along ``dense`` after ``regrasps``; commit all of it when it is valid."""
        tr = self.trans.transfer(dense, 0, q, grasp)
        if tr.reason is not None:
            return False
        self.segments.extend(regrasps)
        self.regrasps += len(regrasps)
        last = self.segments[-1] if self.segments else None
        if last is not None and last.kind == "transfer":
            # consecutive edges on one grasp make a single transfer
            self.segments[-1] = Segment(
                SegmentKind.TRANSFER, None, last.waypoints + tr.waypoints[1:]
            )
        elif len(tr.waypoints) > 1:
            self.segments.append(Segment(SegmentKind.TRANSFER, None, tr.waypoints))
        self.q, self.grasp = tr.waypoints[-1].q, tr.grasp
        return True

    def _resync(self, pose: FloatArray, target: GraspContacts) -> None:
        """Regrasp fingers that drifted far from the GSn path's contacts, where possible.

        Transfers keep the grasp while the path's contacts slide on; a grasp
        far from the path's can no longer be regrasped onto it finger by
        finger, so fingers more than ``settings.resync_m`` away are moved back
        (each only when its landing keeps every (n-1) subgrasp force closure).
        """
        trans = self.trans
        gap = np.linalg.norm(self.grasp.points - target.points, axis=1)
        for f in np.argsort(-gap):
            if gap[f] <= self.settings.resync_m:
                break
            f = int(f)
            new = self.grasp.replace(f, target.points[f], target.normals_out[f])
            if trans.grasp_quality(new, exact=True) <= trans.validity.fc_margin:
                continue
            point, normal = target.points[f], target.normals_out[f]
            seg = trans.regrasp(pose, self.q, self.grasp, f, point, normal)
            if seg is not None:
                self.segments.append(seg)
                self.regrasps += 1
                self.q, self.grasp = seg.end.q, new

    def _regrasps_to(
        self, pose: FloatArray, target: GraspContacts
    ) -> tuple[list[Segment], FloatArray, GraspContacts] | None:
        """:func:`regrasps_onto` from the current grasp; None also when it is ``target``.

        (The same grasp: the transfer on it already failed.)
        """
        out = regrasps_onto(
            self.trans, pose, self.q, self.grasp, target, self.settings.same_contact_m
        )
        return None if out is None or not out[0] else out

    def _midpoint(
        self, pa: FloatArray, ca: GraspContacts, pb: FloatArray, cb: GraspContacts
    ) -> tuple[FloatArray, GraspContacts]:
        """GSn midpoint of an edge: the object pose slerp and the contacts halfway.

        The contacts per the current midpoint interpolation
        (:attr:`ReductionSettings.midpoints`): halfway along each contact's
        surface geodesic (object frame, :class:`ContactPaths`), or as OMPL's
        projected interpolation moves them (interpolating the hand joints
        moves the fingertips roughly along the chord between their world
        positions: the world fingertip centres are averaged and projected
        onto the surface).
        """
        trans = self.trans
        pm = interpolate_pose(pa, pb, 0.5)
        if self.midpoint == Midpoint.GEODESIC:
            halfway = self.contact_paths.between(ca, cb, 0.5)
            if halfway is not None:
                self.geodesic_midpoints += 1
                return pm, halfway
        tips_world = 0.5 * (trans.tip_targets(pa, ca) + trans.tip_targets(pb, cb))
        pts, n_out = trans.obj.closest_point(inverse_transform_points(pm, tips_world))
        return pm, GraspContacts(np.asarray(pts).reshape(-1, 3), np.asarray(n_out).reshape(-1, 3))
