"""The transfer local planner (paper, section IV), contacts fixed on the object.

Contacts fixed in the object frame (:attr:`ContactMotion.FIXED`; rolling
fingertips are :mod:`.rolling_transfer`); the object follows a given pose sequence
(straight line in position, slerp in orientation between samples); every
finger follows by IK. A transfer moves the grasp rigidly, so force closure and
fingertip spacing are constant along it and are checked where the grasp is
made; joint limits (kept :attr:`TransitionSettings.joint_margin` away: joint
steps blow up near full extension) and link collisions are checked at every
waypoint. Waypoints are at most ``max_step_m`` / ``max_step_rad`` apart in
object position, object rotation and every joint.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from dexplan.core.pose import interpolate_pose, quat_angle, quat_to_matrix
from dexplan.core.segments import Waypoint
from dexplan.core.typing import FloatArray
from dexplan.model.hand.hand import Hand
from dexplan.planning.local.transitions.checks import FingerChecks
from dexplan.planning.local.transitions.contacts import GraspContacts
from dexplan.planning.local.transitions.counts import LocalCounts
from dexplan.planning.local.transitions.settings import TransitionSettings

#: Times a transfer step whose joints jump is halved before it gives up.
_MAX_HALVINGS = 4


class TransferStop(enum.StrEnum):
    """Why a transfer stopped before the end of its poses (a member equals its string).

    Attributes:
        OBJECT_COLLISION: the object itself collides at the next pose.
        IK: a finger has no IK solution there.
        JOINT_LIMIT: a finger's solution is within the joint margin of a limit.
        JOINT_JUMP: a finger's joints jump (another IK branch) however small the step.
        COLLISION: a link collision.
        FORCE_CLOSURE: the grasp (rolled: its contacts moved) lost force
            closure or an (n-1)-finger subgrasp did.
    """

    OBJECT_COLLISION = "object_collision"
    IK = "ik"
    JOINT_LIMIT = "joint_limit"
    JOINT_JUMP = "joint_jump"
    COLLISION = "collision"
    FORCE_CLOSURE = "force_closure"


def densify_poses(poses: FloatArray, max_step_m: float, max_step_rad: float) -> FloatArray:
    """Insert poses so consecutive ones differ by at most the given steps.

    Args:
        poses: (P, 7) object poses, XYZW.
        max_step_m: largest translation between consecutive poses (m).
        max_step_rad: largest rotation between consecutive poses (rad).

    Returns:
        (P', 7) poses, straight line in position and slerp in orientation
        between the given ones, the quaternions' signs continuous (each
        interpolation starts from the previous output, so a given pose whose
        quaternion has the other sign comes out negated, the same rotation).
    """
    out = [poses[0]]
    for b in poses[1:]:
        a = out[-1]
        d = float(np.linalg.norm(b[:3] - a[:3]))
        ang = quat_angle(a[3:], b[3:])
        k = max(1, math.ceil(max(d / max_step_m, ang / max_step_rad)))
        out.extend(interpolate_pose(a, b, j / k) for j in range(1, k + 1))
    return np.array(out)


#: A transfer's steps: ``(pose (7,), q (nq,))`` pairs.
_Steps = list[tuple[FloatArray, FloatArray]]
#: Why a transfer step failed: the blocking finger (None: nobody in particular) and the reason.
_Stop = tuple[int | None, TransferStop]


@dataclass(frozen=True)
class TransferResult:
    """Outcome of :meth:`TransferPlanner.transfer`.

    Attributes:
        waypoints: waypoints from the start pose to the last valid one.
        reached: index in the pose sequence of the last pose reached.
        blocking: finger that stopped the transfer (IK, joint limit or link
            collision), or None when the end was reached or the object collided.
        reason: why it stopped, or None when it reached the end.
        grasp: the contacts at the last waypoint (the grasp the transfer
            started with, unless the fingertips rolled).
    """

    waypoints: tuple[Waypoint, ...]
    reached: int
    blocking: int | None
    reason: TransferStop | None
    grasp: GraspContacts


class TransferPlanner:
    """Transfers of a fixed grasp along object poses.

    Args:
        hand: the hand.
        settings: the local planners' settings.
        checks: the per-finger collision checks and joint bounds.
        stats: the local planners' counters (``transfers`` counted here).
    """

    def __init__(
        self,
        hand: Hand,
        settings: TransitionSettings,
        checks: FingerChecks,
        stats: LocalCounts,
    ) -> None:
        self.hand = hand
        self.settings = settings
        self.checks = checks
        self.stats = stats
        self._finger_of_joint = np.zeros(hand.nq, dtype=np.int64)
        for i, idx in enumerate(hand.finger_q_index):
            self._finger_of_joint[idx] = i

    def transfer(
        self, poses: FloatArray, start: int, q_start: FloatArray, grasp: GraspContacts
    ) -> TransferResult:
        """Follow ``poses[start:]`` with a fixed grasp for as long as it stays valid.

        Args:
            poses: (P, 7) dense object trajectory (see :func:`densify_poses`).
            start: index of the current pose in ``poses``.
            q_start: (nq,) hand configuration at ``poses[start]``.
            grasp: contacts held during the transfer.

        Returns:
            A :class:`TransferResult`; its waypoints start at ``poses[start]``.
        """
        self.stats["transfers"] += 1
        contacts = grasp.as_tuple()
        wps = [Waypoint(poses[start].copy(), q_start.copy(), contacts)]
        q = q_start
        for j in range(start + 1, len(poses)):
            if self.checks.world.object_collides(poses[j]):
                return TransferResult(tuple(wps), j - 1, None, TransferStop.OBJECT_COLLISION, grasp)
            steps = self._advance(poses[j - 1], poses[j], q, grasp, depth=0)
            if isinstance(steps, tuple):
                return TransferResult(tuple(wps), j - 1, steps[0], steps[1], grasp)
            for pose_k, q_k in steps:
                wps.append(Waypoint(pose_k, q_k, contacts))
            q = steps[-1][1]
        return TransferResult(tuple(wps), len(poses) - 1, None, None, grasp)

    def _advance(
        self, pa: FloatArray, pb: FloatArray, q_a: FloatArray, grasp: GraspContacts, depth: int
    ) -> _Steps | _Stop:
        """Waypoints from pose ``pa`` (at ``q_a``) to ``pb``, subdividing big joint steps.

        Returns a list of (pose, q) ending at ``pb``, or (blocking finger, reason).
        """
        solved = self._solve_all(pb, grasp, q_a)
        if isinstance(solved, tuple):
            return solved
        q_b = solved
        if np.max(np.abs(q_b - q_a)) > self.settings.max_step_rad:
            if depth >= _MAX_HALVINGS:
                return (
                    int(self._finger_of_joint[np.argmax(np.abs(q_b - q_a))]),
                    TransferStop.JOINT_JUMP,
                )
            mid = interpolate_pose(pa, pb, 0.5)
            first = self._advance(pa, mid, q_a, grasp, depth + 1)
            if isinstance(first, tuple):
                return first
            second = self._advance(mid, pb, first[-1][1], grasp, depth + 1)
            if isinstance(second, tuple):
                return second
            return first + second
        free, finger = self.checks.collision_finger(q_b, pb, self.checks.all_contact)
        if not free and finger is not None:
            q_alt = self._other_posture(finger, pb, q_a, q_b, grasp)
            if q_alt is not None:
                q_b, free = q_alt, True
        if not free:
            return (finger, TransferStop.COLLISION)
        return [(pb.copy(), q_b)]

    def _solve_all(
        self, pose: FloatArray, grasp: GraspContacts, q_prev: FloatArray
    ) -> FloatArray | tuple[int, TransferStop]:
        """IK of every finger at ``pose``: the joints ``(nq,)``, or (blocking finger, reason)."""
        targets = grasp.tip_centres(pose, self.hand.fingertip_radius)
        R = quat_to_matrix(pose[3:7] / np.linalg.norm(pose[3:7]))
        inward = -grasp.normals_out @ R.T  # (n, 3) world frame
        q = q_prev.copy()
        for i in range(self.hand.n_fingers):
            idx = self.hand.finger_q_index[i]
            lo, hi = self.checks.lo[idx], self.checks.hi[idx]
            q_f = self.hand.finger_ik_fast(i, targets[i], q, inward[i])
            if q_f is None or np.any(q_f < lo) or np.any(q_f > hi):
                # a redundant finger's preferred posture may leave its limits
                # where another one a tracking step away does not (as the
                # landing search follows it: :meth:`FingerFollower.track_score`)
                alt = self._posture_in_limits(i, targets[i], q, inward[i])
                if alt is None:
                    return i, TransferStop.IK if q_f is None else TransferStop.JOINT_LIMIT
                q_f = alt
            q[idx] = q_f
        return q

    def _posture_in_limits(
        self, finger: int, tip: FloatArray, q: FloatArray, inward: FloatArray
    ) -> FloatArray | None:
        """The best of ``finger``'s other postures one tracking step from ``q`` within limits.

        ``tip: (3,)`` fingertip centre, ``inward: (3,)`` inward normal, world
        frame; None for fingers with a single posture per branch.
        """
        idx = self.hand.finger_q_index[finger]
        lo, hi = self.checks.lo[idx], self.checks.hi[idx]
        options = self.hand.finger_ik_alternatives(finger, tip, q, inward)
        for q_f in options[: self.settings.posture_options]:
            if not (np.any(q_f < lo) or np.any(q_f > hi)):
                return q_f
        return None

    def _other_posture(
        self, finger: int, pose: FloatArray, q_a: FloatArray, q_b: FloatArray, grasp: GraspContacts
    ) -> FloatArray | None:
        """``q_b`` with ``finger`` in another collision-free posture one step from ``q_a``.

        Redundant fingers reach a contact in many postures; when the one
        chosen collides, the others within a tracking step are tried (best
        aligned with the surface normal first). None when none is free.
        """
        hand = self.hand
        idx = hand.finger_q_index[finger]
        R = quat_to_matrix(pose[3:7] / np.linalg.norm(pose[3:7]))
        tip = grasp.tip_centres(pose, self.hand.fingertip_radius)[finger]
        inward = -(R @ grasp.normals_out[finger])
        options = hand.finger_ik_alternatives(finger, tip, q_a, inward)
        lo, hi = self.checks.lo[idx], self.checks.hi[idx]
        others = (
            q_f
            for q_f in options[: self.settings.posture_options]
            if not (np.any(q_f < lo) or np.any(q_f > hi) or np.array_equal(q_f, q_b[idx]))
        )
        return self.checks.first_free(q_b, idx, others, pose)
