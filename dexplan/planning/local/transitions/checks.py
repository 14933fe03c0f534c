"""Collision and joint-limit checks of one finger, shared by transfers, regrasps and landings."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
import pinocchio as pin

from dexplan.core.pose import quat_to_matrix
from dexplan.core.typing import FloatArray, IntArray
from dexplan.model.collision import CollisionWorld, pose_to_se3
from dexplan.model.hand.hand import Hand
from dexplan.planning.local.transitions.settings import TransitionSettings

#: Object poses whose frames :meth:`FingerChecks.frames` keeps (tracks revisit them).
_FRAME_CACHE = 4096


class FingerChecks:
    """Per-finger collision checks and joint bounds for one hand and world.

    Each finger's collision pairs are kept as one geometry data (checked in one
    C++ call): its links alone against palm, object and obstacles (tracks,
    landings), and the pairs a free finger's moves can change.

    Args:
        hand: the hand.
        world: collision world of hand, object and obstacles.
        settings: the local planners' settings (the joint margin).

    Attributes:
        hand: the hand.
        world: the collision world.
        lo: (nq,) lower joint bounds, ``joint_margin`` inside the limits.
        hi: (nq,) upper joint bounds, ``joint_margin`` inside the limits.
        all_contact: the contact mask with every finger in contact.
    """

    def __init__(self, hand: Hand, world: CollisionWorld, settings: TransitionSettings) -> None:
        self.hand = hand
        self.world = world
        self.all_contact = (True,) * hand.n_fingers
        self.lo = hand.lower + settings.joint_margin
        self.hi = hand.upper - settings.joint_margin
        n_f = range(hand.n_fingers)
        self._own_data = [world.pairs_data(world.finger_pairs(i)) for i in n_f]
        self._move_data = [world.pairs_data(world.free_finger_pairs(i)) for i in n_f]
        self._pose_frames: dict[bytes, tuple[FloatArray, pin.SE3]] = {}
        n = hand.n_fingers
        self._free_masks = [tuple(j != i for j in range(n)) for i in range(n)]
        self._rest_q = [np.setdiff1d(np.arange(hand.nq), idx) for idx in hand.finger_q_index]

    def frames(self, pose: FloatArray) -> tuple[FloatArray, pin.SE3]:
        """Rotation matrix ``(3, 3)`` and SE3 of an object pose ``(7,)``, cached."""
        key = pose.tobytes()
        out = self._pose_frames.get(key)
        if out is None:
            if len(self._pose_frames) >= _FRAME_CACHE:
                self._pose_frames.clear()
            R = quat_to_matrix(pose[3:7] / np.linalg.norm(pose[3:7]))
            out = self._pose_frames[key] = (R, pose_to_se3(pose))
        return out

    def finger_free(self, finger: int, q: FloatArray, M_obj: pin.SE3) -> bool:
        """``finger``'s links at ``q: (nq,)`` clear of palm, object (pose ``M_obj``), obstacles."""
        return not self.world.pairs_collide(self._own_data[finger], q, M_obj)

    def moved_free(
        self, finger: int, q: FloatArray, ref: FloatArray, pose: FloatArray, mask: tuple[bool, ...]
    ) -> bool:
        """``world.is_free(q, pose, mask)`` when ``ref`` is a configuration it accepted.

        ``q`` must differ from ``ref`` in ``finger``'s joints only, with only
        ``finger`` free in ``mask``: every other pair, and the contact fingers'
        penetration, are then as they were at ``ref`` (free), so only the
        finger's own pairs (:meth:`CollisionWorld.free_finger_pairs`) are
        checked. The answer is the full check's; anything else gets the full
        check.
        """
        rest = self._rest_q[finger]
        if mask != self._free_masks[finger] or not np.array_equal(q[rest], ref[rest]):
            return self.world.is_free(q, pose, mask)
        return not self.world.pairs_collide(self._move_data[finger], q, self.frames(pose)[1])

    def collision_finger(
        self, q: FloatArray, pose: FloatArray, mask: tuple[bool, ...]
    ) -> tuple[bool, int | None]:
        """(collision-free, finger involved in the first collision or None) at ``q``, ``pose``.

        A contact fingertip's penetration blames nobody in particular (None).
        """
        rep = self.world.check(q, pose, mask)
        if rep.free:
            return True, None
        if rep.pair is None:
            return False, None
        fingers = [f for f in (self.world.finger_of(n) for n in rep.pair) if f is not None]
        return False, (fingers[0] if fingers else None)

    def first_free(
        self, q: FloatArray, idx: IntArray, postures: Iterable[FloatArray], pose: FloatArray
    ) -> FloatArray | None:
        """``q`` with the finger joints ``idx`` set to the first collision-free posture, or None.

        Args:
            q: (nq,) the hand's joints.
            idx: the finger's joint indexes.
            postures: candidate finger joint values (len(idx),), tried in order.
            pose: (7,) the object pose, world frame.
        """
        for q_f in postures:
            q1 = q.copy()
            q1[idx] = q_f
            if self.world.is_free(q1, pose, self.all_contact):
                return q1
        return None
