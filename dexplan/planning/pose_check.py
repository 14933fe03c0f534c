"""Whether a grasp can exist at an object pose, checked cheaply before any sampling.

A start or goal pose where the object sits inside the palm or an obstacle,
or where some fingertip cannot reach the object's surface, has no grasp: the
sampler would spend its attempts (and a goal the whole time limit) finding
none, and its counters ("400 inverse kinematics") would not say what to
change. :func:`check_pose` says it in one line, before planning.

Reach: a finger's fingertip centre lies in its reach voxels
(:meth:`~dexplan.model.hand.hand.Hand.reach_voxels`); the fingertip touches
the object where the centre is one fingertip radius from the surface. The
gap of a finger is how far its reachable fingertip centres stay from that
(``min sd - r`` over the voxel centres, ``sd`` the object's signed distance):
0 when the finger can touch the object. The voxels are filled from sampled
configurations and dilated by one voxel, so they overestimate the reach by
up to :data:`REACH_SLACK`; a pose is refused only beyond that, never where
a grasp could exist.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dexplan.core.pose import quat_to_matrix
from dexplan.core.typing import FloatArray
from dexplan.model.hand.hand import Hand
from dexplan.model.hand.reach import REACH_VOXEL, ReachVoxels
from dexplan.model.objects import Shape
from dexplan.planning.context import PlanningContext
from dexplan.planning.gsn.validity import RejectedSample, Rejection

__all__ = [
    "REACH_EDGE",
    "REACH_SLACK",
    "FingerReach",
    "PoseCheck",
    "ReachExtent",
    "check_pose",
    "check_query",
    "finger_reach",
    "goal_tolerance",
    "reach_extent",
]

REACH_EDGE = 0.02
"""Margin (m) below which a fingertip is at the edge of its reach: a sampler that
finds no grasp there is told so. The builtin scenarios' fingers reach 25-70 mm
past the object's surface at their start and goal poses."""

REACH_SLACK = 3.0 * REACH_VOXEL
"""Gap (m) beyond which a finger certainly cannot touch the object.

A voxel centre lies within half a voxel diagonal (0.87 voxel) of any point it
covers, and a reachable fingertip centre between two sampled ones within a
voxel of one: 3 voxels (12 mm) bound the error of the voxel estimate."""

_CHUNK = 256
"""Points whose signed distance :func:`_nearest_surface` asks for at once."""

_CENTRES: dict[int, tuple[ReachVoxels, FloatArray]] = {}
"""Voxel centres by ``id`` of their :class:`ReachVoxels` (kept with it: ids are reused)."""
_CENTRES_KEPT = 32
"""Voxel sets whose centres are kept (8 four-finger hands)."""


@dataclass(frozen=True)
class FingerReach:
    """How far one finger's fingertip is from touching the object.

    Attributes:
        finger: the finger's index.
        tip_frame: its fingertip frame.
        gap: distance (m) from the finger's reachable fingertip centres to
            where the fingertip touches the object; 0 when it can touch it.
        covered: True when the object covers the whole reach instead (every
            reachable fingertip centre is inside the object, or nearer its
            surface than the fingertip radius); ``gap`` is then how far
            (m) the deepest one is from touching.
        p_closest_world: (3,) the reachable fingertip centre nearest to touching,
            world frame.
        margin: how far (m) past the surface the fingertip can reach
            (negative: ``-gap`` short of it). A finger that reaches the object
            by a few millimetres only touches it at the edge of its workspace,
            where its links rarely leave it a grasp.
    """

    finger: int
    tip_frame: str
    gap: float
    covered: bool
    p_closest_world: FloatArray
    margin: float = 0.0


@dataclass(frozen=True)
class PoseCheck:
    """What stands in the way of any grasp at one object pose.

    Attributes:
        which: ``"start"`` or ``"goal"``.
        pose: (7,) the object pose, world frame, XYZW.
        palm: ``(link, depth_m)`` of the palm geometries the object intersects.
        obstacles: ``(name, depth_m)`` of the obstacles it intersects.
        reach: per contact finger, its :class:`FingerReach`.
        slack: gap (m) a finger may have and still be given the benefit of
            the doubt (:data:`REACH_SLACK`, plus a goal's tolerance).
    """

    which: str
    pose: FloatArray
    palm: tuple[tuple[str, float], ...]
    obstacles: tuple[tuple[str, float], ...]
    reach: tuple[FingerReach, ...]
    slack: float

    @property
    def short(self) -> tuple[FingerReach, ...]:
        """The fingers that certainly cannot touch the object here."""
        return tuple(f for f in self.reach if f.gap > self.slack)

    @property
    def blocked(self) -> bool:
        """True when no grasp can exist at this pose."""
        return bool(self.palm or self.obstacles or self.short)

    def describe(self) -> str:
        """One line: what is in the way, and what to change ("" when nothing is)."""
        where = f"the {self.which} pose {_xyz(self.pose)}"
        move = f"move [{self.which}] object_pose_xyzquat"
        if self.palm:
            return (
                f"the object at {where} is inside the palm ({_overlaps(self.palm)}): "
                f"{move} away from the palm"
            )
        if self.obstacles:
            return (
                f"the object at {where} is inside an obstacle ({_overlaps(self.obstacles)}): "
                f"{move} or the obstacle"
            )
        short = self.short
        if not short:
            return ""
        far = [f for f in short if not f.covered]
        gaps = ", ".join(
            f"{f.tip_frame} {_mm(f.gap)} {'inside' if f.covered else 'short'}" for f in short
        )
        fix = f"{move} towards the fingers" if far else "use a smaller object"
        return (
            f"the object at {where} is out of reach of {len(short)} of {len(self.reach)} "
            f"fingertips ({gaps}; dexplan info --hand shows their reach): {fix}"
        )

    def edge_hint(self) -> str:
        """Why sampling may have found no grasp: fingertips at the edge of their reach.

        For a pose that passed the check but where the sampler found no grasp
        (its rejections are "inverse kinematics" or "force closure": fingertips
        that only graze the object). "" when every fingertip reaches
        :data:`REACH_EDGE` past the surface.
        """
        edge = sorted((f for f in self.reach if f.margin < REACH_EDGE), key=lambda f: f.margin)
        if not edge:
            return ""
        parts = ", ".join(
            f"{f.tip_frame} {_mm(-f.margin)} short"
            if f.margin < 0
            else f"{f.tip_frame} only {_mm(f.margin)} past the surface"
            for f in edge
        )
        return (
            f"; at the {self.which} pose {len(edge)} of {len(self.reach)} fingertips are at the "
            f"edge of their reach ({parts}): move [{self.which}] object_pose_xyzquat towards "
            "the fingers (dexplan info --hand shows their reach)"
        )

    def samples(self, q_neutral: FloatArray) -> list[RejectedSample]:
        """The verdict as rejected states (``--debug-rrd``): the object at the pose, hand open.

        One per intersected palm geometry or obstacle (reason ``collision``) and
        one per finger out of reach (reason ``reach``, its gap and closest
        reachable fingertip centre in the detail).
        """
        x = np.concatenate([self.pose, q_neutral])
        out = [
            RejectedSample(x, Rejection.COLLISION, f"object / {n} ({_mm(d)} deep, {self.which})")
            for n, d in (*self.palm, *self.obstacles)
        ]
        out += [
            RejectedSample(
                x,
                Rejection.REACH,
                f"finger {f.finger} ({f.tip_frame}) {_mm(f.gap)} "
                f"{'deep' if f.covered else 'short'} at the {self.which} pose; "
                f"nearest reachable fingertip centre {_xyz(f.p_closest_world)}",
            )
            for f in self.short
        ]
        return out


def _overlaps(hits: tuple[tuple[str, float], ...]) -> str:
    return ", ".join(f"{n} {_mm(d)} deep" if d > 0 else n for n, d in hits)


def _mm(metres: float) -> str:
    return f"{metres * 1e3:.0f} mm"


def _xyz(p: FloatArray) -> str:
    return "(" + ", ".join(f"{v:.3f}" for v in p[:3]) + ")"


def _nearest_surface(obj: Shape, p_obj: FloatArray, lower: FloatArray) -> tuple[int, float]:
    """The point of ``p_obj: (N, 3)`` with the least signed distance to ``obj``, and that distance.

    ``lower: (N,)`` are lower bounds of the distances (distance to the object
    centre minus its bounding radius). The :data:`_CHUNK` points of least bound
    are measured first, then only those whose bound is below the best distance
    found: a mesh's signed distance costs tens of microseconds a point, and a
    finger's reach has thousands (for a sphere the bound is the distance, and
    the first chunk is all).
    """
    k = min(_CHUNK, len(lower))
    first = np.argpartition(lower, k - 1)[:k]
    sd = np.atleast_1d(np.asarray(obj.signed_distance(p_obj[first])))
    arg = int(np.argmin(sd))
    best, where = float(sd[arg]), int(first[arg])
    rest = np.ones(len(lower), dtype=bool)
    rest[first] = False
    rest &= lower < best
    more = np.flatnonzero(rest)
    for lo in range(0, len(more), _CHUNK):
        chunk = more[lo : lo + _CHUNK]
        sd = np.atleast_1d(np.asarray(obj.signed_distance(p_obj[chunk])))
        arg = int(np.argmin(sd))
        if sd[arg] < best:
            best, where = float(sd[arg]), int(chunk[arg])
    return where, best


def _voxel_centres(vox: ReachVoxels) -> FloatArray:
    """(K, 3) the centres of a finger's occupied reach voxels, world frame (kept per voxels)."""
    hit = _CENTRES.get(id(vox))
    if hit is None or hit[0] is not vox:
        hit = (vox, vox.origin + (np.argwhere(vox.occupied) + 0.5) * vox.size)
        if len(_CENTRES) >= _CENTRES_KEPT:  # a few hands' worth; the oldest goes
            del _CENTRES[next(iter(_CENTRES))]
        _CENTRES[id(vox)] = hit
    return hit[1]


def finger_reach(ctx: PlanningContext, finger: int, pose: FloatArray) -> FingerReach:
    """How far ``finger``'s fingertip is from touching the object at ``pose`` (see the module)."""
    hand, obj = ctx.hand, ctx.obj
    centres = _voxel_centres(hand.reach_voxels(finger))  # world frame
    R = quat_to_matrix(pose[3:7] / np.linalg.norm(pose[3:7]))
    p_obj = (centres - pose[:3]) @ R
    lower = np.linalg.norm(p_obj, axis=1) - obj.bounding_radius
    r = hand.fingertip_radius
    tip = hand.fingertip_frames[finger]
    lo, sd_lo = _nearest_surface(obj, p_obj, lower)
    margin = r - sd_lo
    if sd_lo > r:  # every reachable centre too far from the object
        return FingerReach(finger, tip, sd_lo - r, False, centres[lo], margin)
    if np.any(lower >= r):  # some reachable centre clear of the object: it can touch
        return FingerReach(finger, tip, 0.0, False, centres[lo], margin)
    sd = np.atleast_1d(np.asarray(obj.signed_distance(p_obj)))  # all of the reach is near
    hi = int(np.argmax(sd))
    if sd[hi] < r:  # every reachable centre too deep in it
        return FingerReach(finger, tip, float(r - sd[hi]), True, centres[hi], margin)
    return FingerReach(finger, tip, 0.0, False, centres[lo], margin)


def check_pose(
    ctx: PlanningContext, pose: FloatArray, which: str, tolerance: float = 0.0
) -> PoseCheck:
    """What stands in the way of any grasp with the object at ``pose``.

    Args:
        ctx: the planning context.
        pose: (7,) object pose, world frame, XYZW.
        which: ``"start"`` or ``"goal"``, for the message.
        tolerance: how far (m) the object may be from ``pose`` (a goal's
            position tolerance plus its angle tolerance times the object's
            bounding radius): the reach verdict allows for it. A goal region
            is only refused when every pose in it is.
    """
    pose = np.asarray(pose, dtype=float)
    hits = ctx.world.object_overlaps(pose)
    palm = tuple((n, d) for n, p, d in hits if p)
    obstacles = tuple((n, d) for n, p, d in hits if not p)
    if tolerance > 0.0:  # a goal region: inside the palm at its centre only, not all of it
        palm = tuple((n, d) for n, d in palm if d > tolerance)
        obstacles = tuple((n, d) for n, d in obstacles if d > tolerance)
    reach = tuple(finger_reach(ctx, i, pose) for i in ctx.gsn.contact_ids)
    return PoseCheck(which, pose, palm, obstacles, reach, REACH_SLACK + tolerance)


def goal_tolerance(position_tol: float, angle_tol: float, bounding_radius: float) -> float:
    """How far (m) a point of the object may move within a goal region."""
    return position_tol + min(angle_tol, math.pi) * bounding_radius


def check_query(ctx: PlanningContext) -> PoseCheck | None:
    """The first of the scenario's start and goal poses where no grasp can exist, or None.

    The goal is checked with its region's tolerance (:func:`goal_tolerance`).
    """
    sc = ctx.scenario
    goal = sc.goal
    tol = goal_tolerance(goal.position_tol, goal.angle_tol, ctx.obj.bounding_radius)
    for which, pose, slack in (
        ("start", sc.start.object_pose_xyzquat, 0.0),
        ("goal", goal.object_pose_xyzquat, tol),
    ):
        check = check_pose(ctx, pose, which, slack)
        if check.blocked:
            return check
    return None


@dataclass(frozen=True)
class ReachExtent:
    """Where a finger's fingertip centre can be (``dexplan info --hand``).

    Attributes:
        lower, upper: (3,) corners of the box around its reach voxels, world frame (m).
        base_world: (3,) the finger's first joint origin, neutral configuration, world frame.
        nearest, farthest: least and largest distance (m) of a reachable fingertip
            centre from ``base_world``.
    """

    lower: FloatArray
    upper: FloatArray
    base_world: FloatArray
    nearest: float
    farthest: float


def reach_extent(hand: Hand, finger: int) -> ReachExtent:
    """The extent of ``finger``'s reach voxels (to a voxel, see :data:`REACH_SLACK`)."""
    centres = _voxel_centres(hand.reach_voxels(finger))
    base = hand.joint_origin(int(hand.finger_q_index[finger][0]), hand.neutral)
    d = np.linalg.norm(centres - base, axis=1)
    return ReachExtent(
        centres.min(axis=0), centres.max(axis=0), base, float(d.min()), float(d.max())
    )
