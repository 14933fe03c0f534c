"""Transfers with rolling fingertips: the contacts move on both surfaces as the object turns.

The fixed-contact transfer (:mod:`.transfer`, the paper's) keeps each contact
put on the object while the tip sphere turns with its link: the fingertip
slides. Here each holding fingertip rolls on the object without slipping
(:class:`~dexplan.model.grasp.rolling.FingertipRolling`): given the object's
motion, a 3-joint finger's motion is determined, a redundant finger takes the
least-norm joint step. The contacts then move on the object and on the
fingertips, so the grasp changes along the transfer and everything is
checked at every waypoint:

- joint limits (kept :attr:`TransitionSettings.joint_margin` away);
- link collisions (palm, object, obstacles, other fingers);
- force closure of the rolled grasp and of every (n-1)-finger subgrasp
  (:attr:`ValiditySettings.fc_margin`);
- a finger of 2 joints rolls only under the object motions it can follow
  (three no-slip equations, two joints): where it would slip, it blocks
  the transfer with reason ``ik``.

The transfer ends where the rolled grasp stops being valid; the finger
blamed is the one that failed (limits, collisions), or for force closure
the one whose contact rolled farthest. Each waypoint records the contacts on
the object (object frame); the fingertip side of each is where the tip
sphere touches it (the plan file writes it in the tip link's frame).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from dexplan.core.pose import interpolate_pose, inverse_transform_points
from dexplan.core.segments import Waypoint
from dexplan.core.typing import FloatArray
from dexplan.model.grasp.rolling import FingertipRolling
from dexplan.model.hand.hand import Hand
from dexplan.model.objects import Shape
from dexplan.model.objects.fingertip import fingertip_contact
from dexplan.planning.local.transitions.checks import FingerChecks
from dexplan.planning.local.transitions.contacts import GraspContacts
from dexplan.planning.local.transitions.counts import LocalCounts
from dexplan.planning.local.transitions.settings import TransitionSettings
from dexplan.planning.local.transitions.transfer import TransferResult, TransferStop

#: Times a rolling step whose joints change too much is halved before it gives up.
_MAX_HALVINGS = 4
#: Slip (m) of one step above which a finger of fewer than 3 joints cannot roll
#: (the verifier's no-slip rule allows 1e-4 m over a whole transfer).
LOW_DOF_SLIP = 1e-6
#: Finger substeps remembered (:meth:`RollingTransferPlanner._step_all`)
#: before the memory is cleared.
_ROLL_MEMORY = 20_000


class RollingTransferPlanner:
    """Transfers of a rolling grasp along object poses.

    Args:
        hand: the hand.
        obj: the object.
        settings: the local planners' settings (step sizes, joint margin).
        checks: the per-finger collision checks and joint bounds.
        stats: the local planners' counters (``transfers`` counted here).
        quality: the least force-closure quality of a grasp and its (n-1)
            subgrasps (:meth:`Transitions.grasp_quality`).
        fc_margin: the rolled grasp must keep a quality above this.
    """

    def __init__(
        self,
        hand: Hand,
        obj: Shape,
        settings: TransitionSettings,
        checks: FingerChecks,
        stats: LocalCounts,
        quality: Callable[[GraspContacts], float],
        fc_margin: float,
    ) -> None:
        self.hand = hand
        self.obj = obj
        self.settings = settings
        self.checks = checks
        self.stats = stats
        self.quality = quality
        self.fc_margin = fc_margin
        self.rolling = FingertipRolling(hand, obj)
        # every finger's substeps, by (finger, poses, joints, contact): _step_all
        self._rolls: dict[tuple[int, bytes, bytes, bytes], _FingerRoll] = {}
        moved = np.concatenate([np.asarray(ix, dtype=int) for ix in hand.finger_q_index])
        self._shared_q = np.setdiff1d(np.arange(hand.nq), moved)

    def transfer(
        self, poses: FloatArray, start: int, q_start: FloatArray, grasp: GraspContacts
    ) -> TransferResult:
        """Follow ``poses[start:]`` rolling the fingertips, for as long as the grasp stays valid.

        Args:
            poses: (P, 7) dense object trajectory.
            start: index of the current pose in ``poses``.
            q_start: (nq,) hand configuration at ``poses[start]``, touching ``grasp``.
            grasp: the contacts at ``poses[start]``, object frame.

        Returns:
            A :class:`TransferResult` whose ``grasp`` is the rolled grasp at the
            last waypoint.
        """
        self.stats["transfers"] += 1
        state = _Rolled(q_start.copy(), grasp.points.copy(), grasp.normals_out.copy())
        wps = [state.waypoint(poses[start])]
        for j in range(start + 1, len(poses)):
            if self.checks.world.object_collides(poses[j]):
                return self._result(wps, state, j - 1, None, TransferStop.OBJECT_COLLISION)
            # a step is taken whole or not at all: the reduction regrasps at poses[j - 1]
            trial, steps = _Rolled(state.q, state.points, state.normals), list[Waypoint]()
            stop = self._advance(poses[j - 1], poses[j], trial, steps, depth=0)
            if stop is not None:
                return self._result(wps, state, j - 1, *stop)
            state.take(trial)
            wps.extend(steps)
        return self._result(wps, state, len(poses) - 1, None, None)

    def _result(
        self,
        wps: list[Waypoint],
        state: _Rolled,
        reached: int,
        blocking: int | None,
        reason: TransferStop | None,
    ) -> TransferResult:
        """The result at the last valid waypoint (``state`` is there)."""
        return TransferResult(
            tuple(wps), reached, blocking, reason, GraspContacts(state.points, state.normals)
        )

    def _advance(
        self, pa: FloatArray, pb: FloatArray, state: _Rolled, wps: list[Waypoint], depth: int
    ) -> tuple[int | None, TransferStop] | None:
        """Roll from ``pa`` to ``pb``, appending waypoints; a stop ``(finger, reason)`` or None.

        A step whose joints change by more than ``max_step_rad`` is halved.
        ``state`` and ``wps`` are left at the last valid waypoint (the caller
        drops them when the whole step fails).
        """
        rolled, slipped = self._roll_all(pa, pb, state)
        if slipped is not None:
            return slipped, TransferStop.IK
        if np.max(np.abs(rolled.q - state.q)) > self.settings.max_step_rad:
            if depth >= _MAX_HALVINGS:
                jump = int(np.argmax(np.abs(rolled.q - state.q)))
                finger = next(f for f, idx in enumerate(self.hand.finger_q_index) if jump in idx)
                return finger, TransferStop.JOINT_JUMP
            mid = interpolate_pose(pa, pb, 0.5)
            return self._advance(pa, mid, state, wps, depth + 1) or self._advance(
                mid, pb, state, wps, depth + 1
            )
        stop = self._invalid(pb, rolled, state)
        if stop is not None:
            return stop
        state.take(rolled)
        wps.append(state.waypoint(pb))
        return None

    def _roll_all(
        self, pa: FloatArray, pb: FloatArray, state: _Rolled
    ) -> tuple[_Rolled, int | None]:
        """Every finger rolled from ``pa`` to ``pb`` (fingers are independent chains).

        Returns the rolled state and the first finger of fewer than 3 joints
        that cannot roll with the object (None: every finger rolls). Rolling
        without slipping is three equations: a finger of 3 joints or more
        solves them exactly, a 2-joint finger only under the object motions
        its fingertip can follow; elsewhere its least-squares step misses by
        :attr:`RolledContact.slip`, which would be a slip, not a roll.
        """
        out = _Rolled(state.q.copy(), state.points.copy(), state.normals.copy())
        slip = np.zeros(self.hand.n_fingers)
        poses = self.rolling.substep_poses(pa, pb)
        for a, b in itertools.pairwise(poses):
            slip += self._step_all(a, b, out)
        slipped = None
        for f, idx in enumerate(self.hand.finger_q_index):
            if len(idx) < 3 and slip[f] > LOW_DOF_SLIP:
                slipped = f
                break
        return out, slipped

    def _step_all(self, a: FloatArray, b: FloatArray, state: _Rolled) -> FloatArray:
        """Roll every finger one substep, from pose ``a`` to ``b``, in place; ``(n,)`` slips.

        A finger's substep is remembered: it depends on that finger alone
        (its joints and contact, the two poses, and joints no finger moves,
        such as a wrist's). The gait search runs the transfers after a few
        regrasps from the same state, and the fingers those regrasps leave in
        place roll the same way in each; a step halved for its joints
        (:meth:`_advance`) rolls again through its own substeps' poses.
        Rolled together or alone, a finger rolls exactly alike.
        """
        steps = a.tobytes() + b.tobytes() + state.q[self._shared_q].tobytes()
        keys = [
            (f, steps, state.q[idx].tobytes(), state.points[f].tobytes())
            for f, idx in enumerate(self.hand.finger_q_index)
        ]
        todo = [f for f, key in enumerate(keys) if key not in self._rolls]
        if todo:
            if len(self._rolls) + len(todo) > _ROLL_MEMORY:
                self._rolls.clear()
            done = self.rolling.step(todo, state.q, a, b, state.points[todo])
            for i, f in enumerate(todo):
                idx = self.hand.finger_q_index[f]
                self._rolls[keys[f]] = _FingerRoll(
                    done.q[idx], done.p_obj[i], done.normals_obj[i], float(done.slip[i])
                )
        slip = np.empty(self.hand.n_fingers)
        for f, idx in enumerate(self.hand.finger_q_index):
            r = self._rolls[keys[f]]
            state.q[idx], state.points[f], state.normals[f], slip[f] = (
                r.q,
                r.p_obj,
                r.normal_obj,
                r.slip,
            )
        return slip

    def verifier_normals(self, pose: FloatArray, q: FloatArray, points: FloatArray) -> FloatArray:
        """(n, 3) outward normals, object frame, of contacts as the verifier reads them.

        ``pose: (7,)`` object pose (world frame), ``q: (nq,)`` the joints,
        ``points: (n, 3)`` the contacts (object frame), every finger touching.

        :func:`~dexplan.model.objects.fingertip.fingertip_contact`: within
        1 mm, the stated contact's own closest-point normal. On a box edge
        or a mesh's triangle edge that is a face's normal, degrees from the
        direction to the tip's centre (the rolled normal, which places the
        tip), and force closure near its margin flips between the two.
        """
        tips = inverse_transform_points(pose, self.hand.fingertip_positions(q))
        r = self.hand.fingertip_radius
        return np.array(
            [fingertip_contact(self.obj, p, t, r)[1] for p, t in zip(points, tips, strict=True)]
        )

    def _invalid(
        self, pose: FloatArray, rolled: _Rolled, before: _Rolled
    ) -> tuple[int | None, TransferStop] | None:
        """Why the rolled grasp at ``pose`` is not valid (``(finger, reason)``), or None."""
        out = (rolled.q < self.checks.lo) | (rolled.q > self.checks.hi)
        if out.any():  # one test for the whole hand; the finger only when one fails
            for f, idx in enumerate(self.hand.finger_q_index):
                if out[idx].any():
                    return f, TransferStop.JOINT_LIMIT
        free, finger = self.checks.collision_finger(rolled.q, pose, self.checks.all_contact)
        if not free:
            return finger, TransferStop.COLLISION
        normals = self.verifier_normals(pose, rolled.q, rolled.points)
        if self.quality(GraspContacts(rolled.points, normals)) <= self.fc_margin:
            moved = np.linalg.norm(rolled.points - before.points, axis=1)
            return int(np.argmax(moved)), TransferStop.FORCE_CLOSURE
        return None


@dataclass(frozen=True)
class _FingerRoll:
    """One finger's substep of a roll, as :meth:`RollingTransferPlanner._step_all` keeps it.

    Attributes:
        q: (m,) the finger's joints after it.
        p_obj: (3,) its contact, object frame.
        normal_obj: (3,) the outward normal there, object frame.
        slip: (m) what its joints could not follow (:attr:`RolledContact.slip`).
    """

    q: FloatArray
    p_obj: FloatArray
    normal_obj: FloatArray
    slip: float


class _Rolled:
    """The hand's joints and the contacts on the object, as a transfer rolls on.

    Attributes:
        q: (nq,) joints.
        points: (n, 3) contacts on the object, object frame.
        normals: (n, 3) outward normals there, object frame.
    """

    def __init__(self, q: FloatArray, points: FloatArray, normals: FloatArray) -> None:
        self.q, self.points, self.normals = q, points, normals

    def take(self, other: _Rolled) -> None:
        """Move to ``other``'s state."""
        self.q, self.points = other.q.copy(), other.points.copy()
        self.normals = other.normals.copy()

    def waypoint(self, pose: FloatArray) -> Waypoint:
        """The waypoint of this state at object pose ``pose: (7,)``."""
        contacts = tuple(self.points[i].copy() for i in range(len(self.points)))
        return Waypoint(pose.copy(), self.q.copy(), contacts)
