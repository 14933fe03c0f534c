"""GSn motions of the paper's section VI: contacts along surface geodesics.

Between two GSn states on a mesh the paper moves each contact along its
surface geodesic while the object pose interpolates. Here: the pose moves
on a straight line and a slerp, each contact the same arc-length fraction of
its geodesic (:class:`~dexplan.planning.local.contact_paths.ContactPaths`), and
each finger follows by IK to its fingertip centre (closed form where the
finger has one, :meth:`~dexplan.model.hand.hand.Hand.finger_ik_fast`; the branch
nearest the previous step, the last link pressing along the inward normal);
steps of at most ``step_m`` of contact travel or object translation and
``step_rad`` of rotation, halved (``max_splits`` times at most) while a
joint moves more than ``jump_rad`` in one (else the motion fails: an IK
branch jump); every state after the first goes through the validity
checker (the first is the caller's, a roadmap state).

OMPL's projected interpolation (module 1's motions) joins other pairs of
states than this motion does, so accepting either joins more pairs than
either alone; this is the motion a Python ``ob.MotionValidator`` would add.
``scripts/section6_motions.py`` compares the two.
"""

from __future__ import annotations

import enum
import math
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from dexplan.core.errors import InvalidInputError
from dexplan.core.pose import interpolate_pose, inverse_transform_points, quat_angle, quat_to_matrix
from dexplan.core.typing import FloatArray
from dexplan.model.hand.hand import Hand
from dexplan.model.objects.geodesic import SurfacePath
from dexplan.planning.gsn.space import POSE_DIM
from dexplan.planning.gsn.validity import GraspValidity
from dexplan.planning.local.contact_paths import ContactPaths
from dexplan.planning.local.grasps import grasp_from_state
from dexplan.planning.local.transitions import Transitions

__all__ = [
    "GeodesicFallback",
    "GeodesicMotion",
    "GeodesicMotionSettings",
    "MotionFailure",
    "geodesic_motion",
]

END_JOINT_TOLERANCE = 1e-6
"""Largest joint gap (rad) between a motion's last IK state and ``b``: past it
the motion ended on another IK branch than ``b``'s (a :class:`GeodesicFallback`
then does not join the states)."""


@dataclass(frozen=True)
class GeodesicMotionSettings:
    """Step sizes of :func:`geodesic_motion`.

    Attributes:
        step_m: largest contact travel (along its geodesic) or object
            translation in one step (m).
        step_rad: largest object rotation in one step (rad).
        jump_rad: largest joint change in one step (rad); a larger one is
            halved, at most ``max_splits`` times.
        max_splits: halvings of one step before the motion fails.
    """

    step_m: float = 0.002
    step_rad: float = 0.02
    jump_rad: float = 0.05
    max_splits: int = 5


class MotionFailure(enum.StrEnum):
    """Why a section VI motion is not valid (a member equals its string)."""

    NO_GEODESIC = "no_geodesic"  # not a mesh, or no geodesic between two contacts
    IK = "ik"  # no IK solution for a fingertip centre (out of reach, or not converged)
    JOINT_JUMP = "joint_jump"  # an IK branch change (past max_splits halvings)
    INVALID = "invalid"  # a state the validity checker rejects (see detail)
    DEADLINE = "deadline"  # the caller's deadline passed before the motion's end


@dataclass(frozen=True)
class GeodesicMotion:
    """A section VI motion, or why there is none.

    Attributes:
        states: (N, 7 + nq) ambient states from the start to the end, both
            included, each valid; (0, 7 + nq) when the motion failed.
        failure: None when valid.
        detail: the validity checker's reason for ``INVALID``.
    """

    states: FloatArray
    failure: MotionFailure | None = None
    detail: str | None = None

    @property
    def valid(self) -> bool:
        """Whether the motion is valid."""
        return self.failure is None


def geodesic_motion(
    trans: Transitions,
    validity: GraspValidity,
    paths: ContactPaths,
    a: FloatArray,
    b: FloatArray,
    settings: GeodesicMotionSettings | None = None,
    *,
    deadline: float = math.inf,
) -> GeodesicMotion:
    """The section VI motion between GSn states ``a`` and ``b: (7 + nq,)``.

    Every finger holds a contact (the grasps of ``a`` and ``b`` are those of
    their fingertips, :func:`~dexplan.planning.local.grasps.grasp_from_state`).
    A fingertip centre sits one radius along its triangle's normal off the
    geodesic point, plus its state's own offset from there (nonzero where a
    contact lies on a mesh edge or vertex), blended linearly from ``a``'s to
    ``b``'s. The last state reaches ``b``'s object pose (its quaternion may
    be ``-b``'s, the same rotation) and fingertip centres; its joints are
    the IK's, equal to ``b``'s when ``b`` lies on the branch the motion
    followed. Past ``deadline`` (``time.perf_counter()``) the motion stops
    with :attr:`MotionFailure.DEADLINE`.

    Raises:
        InvalidInputError: the subspace has free fingers (this moves every
            finger along the surface).
    """
    s = settings or GeodesicMotionSettings()
    hand = trans.hand
    if len(validity.gsn.contact_ids) != hand.n_fingers:
        raise InvalidInputError(
            f"geodesic_motion moves every finger along the surface; contact fingers "
            f"{list(validity.gsn.contact_ids)} of {hand.n_fingers}"
        )
    empty = np.zeros((0, len(a)))
    pa, pb = _end_poses(a, b)
    curves = paths.paths(
        grasp_from_state(trans, pa, a[POSE_DIM:]), grasp_from_state(trans, pb, b[POSE_DIM:])
    )
    if curves is None:
        return GeodesicMotion(empty, MotionFailure.NO_GEODESIC)
    steps = _CurveFollower(hand, curves, pa, pb, a[POSE_DIM:], b[POSE_DIM:], s)
    # the states first (IK only, cheap), then the validity checker on them in
    # bisection order, as OMPL's motion validators: an invalid stretch is met early
    failed = steps.follow(_step_count(curves, pa, pb, s), deadline)
    if failed is not None:
        return GeodesicMotion(empty, failed)
    for i in bisection_order(len(steps.out) - 1):
        if time.perf_counter() >= deadline:
            return GeodesicMotion(empty, MotionFailure.DEADLINE)
        verdict = validity.check(steps.out[i + 1])
        if not verdict.valid:
            return GeodesicMotion(empty, MotionFailure.INVALID, str(verdict.reason))
    return GeodesicMotion(np.array(steps.out))


def _end_poses(a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Object poses ``(7,)`` of states ``a``, ``b``: unit quaternions, ``b``'s sign nearer."""
    pa, pb = np.array(a[:POSE_DIM], dtype=float), np.array(b[:POSE_DIM], dtype=float)
    pa[3:] /= np.linalg.norm(pa[3:])
    pb[3:] /= np.linalg.norm(pb[3:])
    if float(pa[3:] @ pb[3:]) < 0.0:  # the same rotation's nearer sign
        pb[3:] = -pb[3:]
    return pa, pb


def _step_count(
    curves: Sequence[SurfacePath], pa: FloatArray, pb: FloatArray, s: GeodesicMotionSettings
) -> int:
    """Steps from ``pa`` to ``pb`` within the settings' contact travel, translation, rotation."""
    return max(
        1,
        math.ceil(max(c.length for c in curves) / s.step_m),
        math.ceil(float(np.linalg.norm(pb[:3] - pa[:3])) / s.step_m),
        math.ceil(quat_angle(pa[3:], pb[3:]) / s.step_rad),
    )


class _CurveFollower:
    """The hand states of a section VI motion, by IK along the contacts' curves.

    Args:
        hand: the hand.
        curves: one contact curve per finger (object frame).
        pa: (7,) the start's object pose; ``pb`` the end's (sign nearer ``pa``).
        q_a: (nq,) the start's joints; ``q_b`` the end's.
        settings: the steps.

    Attributes:
        out: (7 + nq,) states so far, the start's first.
    """

    def __init__(
        self,
        hand: Hand,
        curves: Sequence[SurfacePath],
        pa: FloatArray,
        pb: FloatArray,
        q_a: FloatArray,
        q_b: FloatArray,
        settings: GeodesicMotionSettings,
    ) -> None:
        self.hand = hand
        self.curves = curves
        self.pa, self.pb = pa, pb
        self.settings = settings
        self.r = hand.fingertip_radius
        self.off_a, self.off_b = self._offsets(pa, q_a, 0.0), self._offsets(pb, q_b, 1.0)
        self.out: list[FloatArray] = [np.concatenate([pa, q_a])]

    def _offsets(self, pose: FloatArray, q: FloatArray, t: float) -> FloatArray:
        """(n, 3) fingertip centres minus the curves' offset points at ``t``, object frame."""
        tips = inverse_transform_points(pose, self.hand.fingertip_positions(q))
        on = [p + self.r * n_out for p, _, n_out in (c.at(t) for c in self.curves)]
        return tips - np.array(on)

    def follow(self, n: int, deadline: float) -> MotionFailure | None:
        """Append the states of ``n`` steps to the end; a failure, or None."""
        for k in range(1, n + 1):
            if time.perf_counter() >= deadline:
                return MotionFailure.DEADLINE
            failed = self._advance((k - 1) / n, k / n, 0)
            if failed is not None:
                return failed
        return None

    def _state(self, t: float, q_prev: FloatArray) -> FloatArray | MotionFailure:
        """The state ``(7 + nq,)`` at fraction ``t`` by IK from ``q_prev``, or an IK failure."""
        hand = self.hand
        pose = interpolate_pose(self.pa, self.pb, t)
        R = quat_to_matrix(pose[3:])
        q = q_prev.copy()
        for f, curve in enumerate(self.curves):
            p, _, n_out = curve.at(t)
            tip = p + self.r * n_out + (1.0 - t) * self.off_a[f] + t * self.off_b[f]
            q_f = hand.finger_ik_fast(f, R @ tip + pose[:3], q_prev, -(R @ n_out))
            if q_f is None:
                return MotionFailure.IK
            q[hand.finger_q_index[f]] = q_f
        return np.concatenate([pose, q])

    def _advance(self, t0: float, t1: float, depth: int) -> MotionFailure | None:
        """Append the states from ``t0`` (the last one) to ``t1``; a failure, or None."""
        x = self._state(t1, self.out[-1][POSE_DIM:])
        if isinstance(x, MotionFailure):
            return x
        if np.max(np.abs(x[POSE_DIM:] - self.out[-1][POSE_DIM:])) > self.settings.jump_rad:
            if depth >= self.settings.max_splits:
                return MotionFailure.JOINT_JUMP
            mid = 0.5 * (t0 + t1)
            return self._advance(t0, mid, depth + 1) or self._advance(mid, t1, depth + 1)
        self.out.append(x)
        return None


def bisection_order(n: int) -> list[int]:
    """``0 .. n-1`` in bisection order (the last, the middle, then the quarters, ...).

    ``bisection_order(7) == [6, 2, 0, 4, 1, 3, 5]``: a motion's states
    checked in this order meet an invalid stretch after few checks.
    """
    if n <= 0:
        return []
    order = [n - 1]
    seen = {n - 1}
    queue = [(0, n - 1)]  # half-open index ranges still to split
    while queue:
        nxt: list[tuple[int, int]] = []
        for lo, hi in queue:
            if lo >= hi:
                continue
            mid = (lo + hi - 1) // 2 if hi - lo > 1 else lo
            if mid not in seen:
                seen.add(mid)
                order.append(mid)
            nxt.extend([(lo, mid), (mid + 1, hi)])
        queue = nxt
    return order


class GeodesicFallback:
    """The section VI motion as module 1's second motion (OMPL's ``motion_fallback``).

    Called where OMPL's projected motion between two roadmap states is
    invalid (:class:`~dexplan.planning.ompl.motions.FallbackMotions`): the
    paper's motion joins them when it is valid, starts at ``a`` and ends at
    ``b`` exactly (same quaternion sign, the IK's last joints within
    :data:`END_JOINT_TOLERANCE` of ``b``'s; the ends are then ``a`` and
    ``b`` themselves).

    Args:
        trans: the transitions (hand and object).
        validity: GSn's validity checker.
        paths: the object's geodesic contact paths (active: a mesh).
        settings: the motion's steps.

    Attributes:
        failures: why calls did not join their states, counted (``"sign"``:
            the quaternions' signs differ, so the ambient path would jump;
            ``"branch"``: it ended on another IK branch; else a
            :class:`MotionFailure` value).
    """

    def __init__(
        self,
        trans: Transitions,
        validity: GraspValidity,
        paths: ContactPaths,
        settings: GeodesicMotionSettings | None = None,
    ) -> None:
        if not paths.active:
            raise InvalidInputError(f"no surface geodesics: {paths.fallback}")
        self._trans = trans
        self._validity = validity
        self._paths = paths
        self._settings = settings
        self.failures: Counter[str] = Counter()

    def __call__(self, a: FloatArray, b: FloatArray, deadline: float) -> FloatArray | None:
        """``(K, 7 + nq)`` valid states from ``a`` to ``b`` (both exactly), or None."""
        if float(a[3:POSE_DIM] @ b[3:POSE_DIM]) < 0.0:
            self.failures["sign"] += 1
            return None
        motion = geodesic_motion(
            self._trans, self._validity, self._paths, a, b, self._settings, deadline=deadline
        )
        if motion.failure is not None:
            self.failures[motion.failure.value] += 1
            return None
        states = motion.states.copy()
        if float(np.max(np.abs(states[-1][POSE_DIM:] - b[POSE_DIM:]))) > END_JOINT_TOLERANCE:
            self.failures["branch"] += 1
            return None
        states[0], states[-1] = a, b
        return states
