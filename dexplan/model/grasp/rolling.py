"""Rolling contact kinematics: a fingertip sphere rolls on the object without slipping.

A fingertip is a sphere of radius ``r`` centred on its tip frame. With a fixed
contact (the paper's transfer), the contact point stays put on the object
while the sphere turns with its link, so the fingertip's surface slides over
it. A real fingertip rolls: the two material points in contact have the same
velocity (point contact without slipping, Montana 1988), three equations; the
relative angular velocity is free (rolling and spinning). The contact point
then moves on both surfaces, and by the same arc length: with no sliding,
the contact point's velocities on the two surfaces have equal magnitudes
(Montana's contact equations), which ``dexplan verify`` checks.

Given the object's motion, a finger's joint velocities solve
``J_p(q) dq = dp_obj``, where ``J_p`` is the Jacobian of the fingertip's
material point at the contact (``J_c - [p - c]x J_w`` from the tip frame's
Jacobian) and ``dp_obj`` the displacement of the object's material point
there:

- a 3-joint finger is determined (``J_p`` is square);
- a redundant finger takes the least-norm joint step plus a step in the
  null space of ``J_p`` (which leaves the rolling untouched) away from its
  joint limits: the joints' offsets from mid-range (-1 at the lower limit,
  +1 at the upper) projected onto that null space, times
  :attr:`RollSettings.limit_gain` per radian of object rotation (or per
  10 cm of translation). Least-norm steps alone
  drift a 4-joint finger into a joint limit it could have kept away from,
  which ends the transfer there;
- a finger with fewer joints cannot follow every motion: the least-squares
  step leaves a residual, reported as :attr:`RolledContact.slip`.

Discretised, the object's pose change is split into substeps of at most
:attr:`RollSettings.max_substep_rad` and :attr:`RollSettings.max_substep_m`.
Each substep solves the velocity equation by the midpoint rule (second
order) and moves the joints: the contact's paths on the two surfaces agree
within 0.3 % over a 40 degree roll of the Allegro's fingers at the default
0.02 rad substeps (0.15 % at 0.01 rad); the remaining drift off
the surface is then removed by moving the sphere's centre along the
object's normal only (a normal correction adds no tangential slip), and the
contact is read again on both surfaces: on the
object where the sphere meets it (:meth:`Shape.closest_point`), on the tip in
the tip frame. Joint limits and collisions are the caller's: a transfer ends
where the rolled grasp stops being valid.

Frames: ``p_obj`` object frame; ``p_tip`` the tip link's frame (the sphere's
centre is its origin); world quantities are the hand's base frame, where
object poses are given as ``(x, y, z, qx, qy, qz, qw)``.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

import numpy as np
import pinocchio as pin

from dexplan.core.errors import InvalidInputError
from dexplan.core.pose import interpolate_pose, length, quat_angle, quat_to_matrix
from dexplan.core.typing import FloatArray
from dexplan.model.grasp.contact_jacobians import damped_steps, point_jacobians, rotate_rows

__all__ = [
    "CONTACT_MOTIONS",
    "ContactMotion",
    "FingertipRolling",
    "RollSettings",
    "RollStep",
    "RolledContact",
    "tip_side_contacts",
]


class ContactMotion(StrEnum):
    """How the contacts move during a transfer (``[contact] motion``).

    Attributes:
        FIXED: the paper's transfer: each contact stays put on the object and
            the fingertip slides over it as its link turns.
        ROLLING: each fingertip rolls on the object without slipping; the
            contacts move on both surfaces.
    """

    FIXED = "fixed"
    ROLLING = "rolling"


CONTACT_MOTIONS: tuple[str, ...] = tuple(ContactMotion)
"""The names :class:`ContactMotion` accepts."""


@dataclass(frozen=True)
class RollSettings:
    """Resolution of :meth:`FingertipRolling.roll`.

    Attributes:
        max_substep_rad: largest object rotation (rad) of one substep.
        max_substep_m: largest object translation (m) of one substep.
        normal_iterations: normal corrections per substep (the drift is
            second order in the substep; one or two remove it to 1e-9 m; on
            a concave mesh region about as curved as the fingertip, the
            bean's waist, one correction left a transfer whose contact
            travelled 2.1 mm on the tip but 1.3 mm on the object).
        damping: Tikhonov damping of the joint solves (near singular
            postures take a bounded step instead of a huge one).
        limit_gain: how far (rad per rad of object rotation) a redundant
            finger's null-space step moves its joints away from their
            limits; 0: the least-norm step alone.
    """

    max_substep_rad: float = 0.02
    max_substep_m: float = 0.001
    normal_iterations: int = 2
    damping: float = 1e-9
    limit_gain: float = 1.0

    def __post_init__(self) -> None:
        for name in ("max_substep_rad", "max_substep_m"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise InvalidInputError(f"{name} must be a positive number, got {v!r}")
        if not (math.isfinite(self.limit_gain) and self.limit_gain >= 0.0):
            raise InvalidInputError(
                f"limit_gain must be a finite number >= 0, got {self.limit_gain!r}"
            )
        if self.normal_iterations < 0 or not (self.damping >= 0.0):
            raise InvalidInputError(
                "normal_iterations must be >= 0 and damping >= 0, got "
                f"{self.normal_iterations!r}, {self.damping!r}"
            )


@dataclass(frozen=True)
class RolledContact:
    """A finger after rolling with the object's motion.

    Attributes:
        q: (nq,) the hand's joints, only the finger's changed.
        p_obj: (3,) contact point, object frame.
        normal_obj: (3,) outward unit normal of the object there, object frame.
        p_tip: (3,) contact point in the tip link's frame (on the tip sphere).
        arc_obj: (m) length of the contact's path on the object.
        arc_tip: (m) length of the contact's path on the fingertip.
        slip: (m) the displacement the joints could not follow, summed over
            substeps (0 up to rounding for fingers of 3 joints or more away
            from singular postures).
    """

    q: FloatArray
    p_obj: FloatArray
    normal_obj: FloatArray
    p_tip: FloatArray
    arc_obj: float
    arc_tip: float
    slip: float


@dataclass(frozen=True)
class RollStep:
    """Fingers after one substep of a roll (:meth:`FingertipRolling.step`).

    Attributes:
        q: (nq,) the hand's joints, only the rolled fingers' changed.
        p_obj: (F, 3) per rolled finger, its contact point, object frame.
        normals_obj: (F, 3) the object's outward unit normals there, object frame.
        p_tip: (F, 3) the contact points in each tip link's frame.
        slip: (F,) per finger, the displacement (m) its joints could not follow.
    """

    q: FloatArray
    p_obj: FloatArray
    normals_obj: FloatArray
    p_tip: FloatArray
    slip: FloatArray


class FingertipRolling:
    """Rolling of one hand's fingertips on one object.

    Args:
        hand: the :class:`~dexplan.model.hand.hand.Hand` (its Pinocchio model,
            tip frames, finger joint indexes and fingertip radius).
        obj: the object :class:`~dexplan.model.objects.Shape`.
        settings: resolution (default :class:`RollSettings`).
    """

    def __init__(self, hand: Any, obj: Any, settings: RollSettings | None = None) -> None:
        self.hand, self.obj = hand, obj
        self.settings = settings or RollSettings()
        self.radius = float(hand.fingertip_radius)
        self._data = hand.model.createData()
        self._grouped: dict[tuple[int, ...], list[list[int]]] = {}

    def tip_frame(self, finger: int, q: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """The tip frame at ``q: (nq,)``: ``(R_tip (3, 3), c_world (3,), J6 (6, m))``.

        ``J6`` is the tip frame's Jacobian (``LOCAL_WORLD_ALIGNED``) in the
        finger's own joints.
        """
        model, data = self.hand.model, self._data
        fid = self.hand.tip_frame_ids[finger]
        pin.computeJointJacobians(model, data, q)
        M = pin.updateFramePlacement(model, data, fid)
        J = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
        return M.rotation.copy(), M.translation.copy(), J[:, self.hand.finger_q_index[finger]]

    def tip_placement(self, finger: int, q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The tip frame at ``q: (nq,)``: ``(R_tip (3, 3), c_world (3,))`` (no Jacobian)."""
        model, data = self.hand.model, self._data
        pin.forwardKinematics(model, data, q)
        M = pin.updateFramePlacement(model, data, self.hand.tip_frame_ids[finger])
        return M.rotation.copy(), M.translation.copy()

    def tip_point(
        self, finger: int, q: FloatArray, object_pose: FloatArray, p_obj: FloatArray
    ) -> FloatArray:
        """The contact ``p_obj: (3,)`` (object frame) in the tip link's frame, ``(3,)``."""
        R_t, c = self.tip_placement(finger, q)
        R, x = _pose(object_pose)
        return R_t.T @ (x + R @ p_obj - c)

    def roll(
        self,
        finger: int,
        q: FloatArray,
        pose_a: FloatArray,
        pose_b: FloatArray,
        p_obj: FloatArray,
        *,
        check_touch: bool = True,
    ) -> RolledContact:
        """Roll ``finger``'s tip on the object while it moves from ``pose_a`` to ``pose_b``.

        Args:
            finger: the finger.
            q: (nq,) the hand's joints at ``pose_a``, the tip touching ``p_obj``.
            pose_a: (7,) the object's pose before, world frame, XYZW.
            pose_b: (7,) the object's pose after.
            p_obj: (3,) the contact point at ``pose_a``, object frame.
            check_touch: check that the tip touches ``p_obj``; a caller
                chaining rolls (each ends with the tip tangent) skips it.

        Returns:
            The :class:`RolledContact` at ``pose_b``.

        Raises:
            InvalidInputError: a bad finger index, or the tip does not touch the
                object at ``p_obj`` (farther than 1 mm from tangency there).
        """
        points = np.asarray(p_obj, dtype=float).reshape(1, 3)
        return self.roll_fingers([finger], q, pose_a, pose_b, points, check_touch=check_touch)[0]

    def roll_fingers(
        self,
        fingers: Sequence[int],
        q: FloatArray,
        pose_a: FloatArray,
        pose_b: FloatArray,
        points: FloatArray,
        *,
        check_touch: bool = True,
    ) -> list[RolledContact]:
        """Roll several fingertips at once: :meth:`roll` of each, in one pass.

        The fingers are independent chains, so each rolls exactly as it
        would alone; rolling them together shares the hand's kinematics and
        the linear solves of every substep between them.

        Args:
            fingers: the fingers, each once.
            q: (nq,) the hand's joints at ``pose_a``, each tip touching its contact.
            pose_a: (7,) the object's pose before, world frame, XYZW.
            pose_b: (7,) the object's pose after.
            points: (len(fingers), 3) the contacts at ``pose_a``, object frame.
            check_touch: check that each tip touches its contact.

        Returns:
            Per finger, its :class:`RolledContact` at ``pose_b``; their ``q``
            are the same joints, every rolled finger's changed.

        Raises:
            InvalidInputError: a bad or repeated finger index, or a tip that
                does not touch the object at its contact.
        """
        fs = list(fingers)
        for f in fs:
            if not 0 <= f < self.hand.n_fingers:
                raise InvalidInputError(f"finger must be in [0, {self.hand.n_fingers}), got {f}")
        if len(set(fs)) != len(fs):
            raise InvalidInputError(f"fingers must not repeat, got {fs}")
        q = np.array(q, dtype=float)
        P = np.array(points, dtype=float).reshape(len(fs), 3)
        if check_touch:
            for f, p in zip(fs, P, strict=True):
                self._check_touch(f, q, pose_a, p)
        poses = self.substep_poses(pose_a, pose_b)
        prev = _pose(pose_a)
        R_t, c = self._placements(fs, q)
        T = np.array([R_t[i].T @ (prev[1] + prev[0] @ P[i] - c[i]) for i in range(len(fs))])
        arc_obj, arc_tip, slip = [0.0] * len(fs), [0.0] * len(fs), [0.0] * len(fs)
        for a, b in itertools.pairwise(poses):
            out = self.step(fs, q, a, b, P)
            for i in range(len(fs)):
                arc_obj[i] += length(out.p_obj[i] - P[i])
                arc_tip[i] += length(out.p_tip[i] - T[i])
                slip[i] += float(out.slip[i])
            q, P, normals, T = out.q, out.p_obj, out.normals_obj, out.p_tip
        return [
            RolledContact(q.copy(), P[i], normals[i], T[i], arc_obj[i], arc_tip[i], slip[i])
            for i in range(len(fs))
        ]

    def substep_poses(self, pose_a: FloatArray, pose_b: FloatArray) -> FloatArray:
        """The object poses ``(k + 1, 7)`` a roll from ``pose_a`` to ``pose_b`` steps through.

        ``k`` substeps of at most :attr:`RollSettings.max_substep_rad` and
        :attr:`RollSettings.max_substep_m`, evenly spaced (interpolated as
        :func:`~dexplan.core.pose.interpolate_pose`); the first pose is
        ``pose_a`` and the last ``pose_b``, exactly.
        """
        s = self.settings
        pose_a, pose_b = np.asarray(pose_a, dtype=float), np.asarray(pose_b, dtype=float)
        angle = quat_angle(pose_a[3:7], pose_b[3:7])
        dist = length(pose_b[:3] - pose_a[:3])
        k = max(1, math.ceil(max(angle / s.max_substep_rad, dist / s.max_substep_m)))
        inner = [interpolate_pose(pose_a, pose_b, j / k) for j in range(1, k)]
        return np.array([pose_a, *inner, pose_b])

    def step(
        self,
        fingers: Sequence[int],
        q: FloatArray,
        pose_a: FloatArray,
        pose_b: FloatArray,
        points: FloatArray,
    ) -> RollStep:
        """One substep of :meth:`roll_fingers`: the fingers roll from ``pose_a`` to ``pose_b``.

        The poses must be one substep apart (:meth:`substep_poses`); the
        fingers, as in :meth:`roll_fingers`, are not checked.

        Args:
            fingers: the fingers, each once.
            q: (nq,) the hand's joints at ``pose_a``, each tip touching its contact.
            pose_a: (7,) the object's pose before, world frame, XYZW.
            pose_b: (7,) the object's pose after.
            points: (len(fingers), 3) the contacts at ``pose_a``, object frame.
        """
        fs = list(fingers)
        frame_a, frame = _pose(pose_a), _pose(pose_b)
        q = np.asarray(q, dtype=float)
        points = np.asarray(points, dtype=float).reshape(len(fs), 3)
        P, normals, T = np.empty((3, len(fs), 3))
        slip = np.empty(len(fs))
        # the fingers are independent chains: each group of as many joints
        # rolls in stacked arrays (its Jacobians are all 3 x m)
        for rows in self._groups(fs):
            group = [fs[i] for i in rows]
            q, slip[rows] = self._substep(group, q, frame_a, frame, points[rows])
            P[rows], normals[rows], T[rows] = self._contacts(group, q, frame)
        return RollStep(q, P, normals, T, slip)

    def _groups(self, fingers: list[int]) -> list[list[int]]:
        """Positions in ``fingers`` of the fingers with as many joints, in order of first."""
        key = tuple(fingers)
        groups = self._grouped.get(key)
        if groups is None:
            by_size: dict[int, list[int]] = {}
            for i, f in enumerate(fingers):
                by_size.setdefault(len(self.hand.finger_q_index[f]), []).append(i)
            groups = self._grouped[key] = list(by_size.values())
        return groups

    def _check_touch(self, finger: int, q: FloatArray, pose: FloatArray, p_obj: FloatArray) -> None:
        """Raise unless the tip sphere at ``q`` touches the object at ``p_obj``."""
        _, c = self.tip_placement(finger, q)
        R, x = _pose(pose)
        gap = abs(float(np.linalg.norm(x + R @ p_obj - c)) - self.radius)
        d = float(self.obj.signed_distance(R.T @ (c - x))) - self.radius
        if gap > 1e-3 or abs(d) > 1e-3:
            raise InvalidInputError(
                f"finger {finger}'s tip does not touch the object at the stated contact "
                f"(gap {max(gap, abs(d)) * 1e3:.3g} mm)"
            )

    def _frames(self, fingers: list[int], q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Tip frames at ``q`` of fingers of ``m`` joints each: ``(c_world (F, 3), J6 (F, 6, m))``.

        ``J6`` as in :meth:`tip_frame`; one kinematics pass serves every finger.
        """
        model, data = self.hand.model, self._data
        pin.computeJointJacobians(model, data, q)
        m = len(self.hand.finger_q_index[fingers[0]])
        c, J = np.empty((len(fingers), 3)), np.empty((len(fingers), 6, m))
        for i, f in enumerate(fingers):
            fid = self.hand.tip_frame_ids[f]
            c[i] = pin.updateFramePlacement(model, data, fid).translation
            J6 = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
            J[i] = J6[:, self.hand.finger_q_index[f]]
        return c, J

    def _placements(self, fingers: list[int], q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The fingers' tip placements at ``q``: ``(R_tip (F, 3, 3), c_world (F, 3))``."""
        model, data = self.hand.model, self._data
        pin.forwardKinematics(model, data, q)
        R, c = np.empty((len(fingers), 3, 3)), np.empty((len(fingers), 3))
        for i, f in enumerate(fingers):
            M = pin.updateFramePlacement(model, data, self.hand.tip_frame_ids[f])
            R[i], c[i] = M.rotation, M.translation
        return R, c

    def _substep(
        self, fingers: list[int], q: FloatArray, frame_a: _Frame, frame_b: _Frame, P: FloatArray
    ) -> tuple[FloatArray, list[float]]:
        """One substep: the joints that keep the contacts' material points moving together.

        The midpoint rule (second order): a half Euler step at the contacts
        ``P: (F, 3)`` gives the posture at the substep's middle; there the
        contacts are read again and the whole step solved with those
        contacts' material points (the tip's ``J_p`` at the middle, the
        object's displacement over the substep). ``frame_a``, ``frame_b``:
        the object's ``(R, x)`` before and after. Returns ``(q, slip)``: the
        new joints, and per finger how far (m) the least-squares step misses
        the object point's displacement.
        """
        idx = [self.hand.finger_q_index[f] for f in fingers]
        (R_a, x_a), (R_b, x_b) = frame_a, frame_b
        damping = self.settings.damping
        # the half step, at the substep's first contacts
        c, J6 = self._frames(fingers, q)
        p_a = x_a + rotate_rows(R_a, P)
        J = point_jacobians(J6, p_a, c)
        half = damped_steps(J, (x_b + rotate_rows(R_b, P)) - p_a, damping)
        q_mid = q.copy()
        for ix, dq_i in zip(idx, half, strict=True):
            q_mid[ix] += 0.5 * dq_i
        # the middle: the contacts there, their material points' motion over the substep
        R_m, x_m = _mid_rotation(R_a, R_b), 0.5 * (x_a + x_b)
        c_m, J6_m = self._frames(fingers, q_mid)
        p_m = np.asarray(self.obj.closest_point(rotate_rows(R_m.T, c_m - x_m))[0], dtype=float)
        move = (x_b + rotate_rows(R_b, p_m)) - (x_a + rotate_rows(R_a, p_m))
        J_m = point_jacobians(J6_m, x_m + rotate_rows(R_m, p_m), c_m)
        dq = damped_steps(J_m, move, damping)
        if self.settings.limit_gain > 0.0:
            motion = length(pin.log3(R_b @ R_a.T)) + 10.0 * length(x_b - x_a)
            for i, ix in enumerate(idx):
                if len(ix) > 3:
                    dq[i] = dq[i] + self._away_from_limits(ix, q_mid, J_m[i], motion)
        q = q.copy()
        for ix, dq_i in zip(idx, dq, strict=True):
            q[ix] += dq_i
        slip = [length(r) for r in rotate_rows(J_m, dq) - move]
        for _ in range(self.settings.normal_iterations):
            q = self._onto_surface(fingers, q, frame_b)
        return q, slip

    def _away_from_limits(
        self, idx: Any, q: FloatArray, J: FloatArray, motion: float
    ) -> FloatArray:
        """A redundant finger's null-space step away from its joint limits, ``(len(idx),)``.

        ``J``: (3, m) the material point's Jacobian at ``q`` (the middle of
        the substep). The step is the joints' offsets from mid-range (-1 at
        the lower limit, +1 at the upper) projected onto the null space of
        ``J`` (so the tip's material point does not move), times
        ``limit_gain`` and the substep's object ``motion`` (its rotation in
        radians plus 10 per metre of translation): largest near a limit,
        none at mid-range.
        """
        lo, hi = self.hand.lower[idx], self.hand.upper[idx]
        # each joint's offset from mid-range, -1 at the lower limit, +1 at the upper
        offset = (q[idx] - 0.5 * (lo + hi)) / np.maximum(0.5 * (hi - lo), 1e-6)
        null = offset - J.T @ np.linalg.solve(J @ J.T + 1e-12 * np.eye(3), J @ offset)
        return np.asarray(-self.settings.limit_gain * motion * null, dtype=np.float64)

    def _onto_surface(self, fingers: list[int], q: FloatArray, frame: _Frame) -> FloatArray:
        """Move each tip's centre along the object's normal until its sphere is tangent."""
        c, J6 = self._frames(fingers, q)
        R, x = frame
        d, grad = self.obj.signed_distance_and_gradient(rotate_rows(R.T, c - x))
        steps = (self.radius - np.asarray(d, dtype=float))[:, None] * rotate_rows(R, grad)
        dq = damped_steps(J6[:, :3], steps, self.settings.damping)
        q = q.copy()
        for f, dq_i in zip(fingers, dq, strict=True):
            q[self.hand.finger_q_index[f]] += dq_i
        return q

    def _contacts(
        self, fingers: list[int], q: FloatArray, frame: _Frame
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Where the tip spheres meet the object: ``(p_obj, normal_out, p_tip)``, (F, 3) each.

        ``p_obj`` and ``normal_out`` in the object frame, ``p_tip`` in each tip link's.
        """
        R_t, c = self._placements(fingers, q)
        R, x = frame
        p, n = self.obj.closest_point(rotate_rows(R.T, c - x))
        p = np.asarray(p, dtype=float)
        tips = rotate_rows(R_t.transpose(0, 2, 1), x + rotate_rows(R, p) - c)
        return p, np.asarray(n, dtype=float), tips


#: An object pose as ``(R (3, 3), x (3,))``, world frame.
_Frame = tuple[FloatArray, FloatArray]


def tip_side_contacts(
    hand: Any, q: FloatArray, object_pose: FloatArray, contacts: Sequence[FloatArray | None]
) -> list[FloatArray | None]:
    """The fingertip side of each contact: the point in its tip link's frame, ``(3,)``.

    Args:
        hand: the hand (its Pinocchio model and tip frames).
        q: (nq,) joints.
        object_pose: (7,) object pose, world frame, XYZW.
        contacts: per finger, its contact ``(3,)`` in the object frame, or None.

    Returns:
        Per finger, ``R_tip^T (p_world - c_tip)`` (on the tip sphere when the
        tip touches the contact), or None for a free finger.
    """
    data = hand.data  # the hand's own kinematics buffer (a fresh one per call costs more)
    pin.forwardKinematics(hand.model, data, np.asarray(q, dtype=float))
    R, x = _pose(object_pose)
    out: list[FloatArray | None] = []
    for c, fid in zip(contacts, hand.tip_frame_ids, strict=True):
        if c is None:
            out.append(None)
            continue
        M = pin.updateFramePlacement(hand.model, data, fid)
        out.append(M.rotation.T @ (x + R @ np.asarray(c, dtype=float) - M.translation))
    return out


def _pose(pose: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``(R (3, 3), x (3,))`` of a ``(7,)`` XYZW pose."""
    pose = np.asarray(pose, dtype=float)
    return quat_to_matrix(pose[3:7] / length(pose[3:7])), pose[:3]


def _mid_rotation(R_a: FloatArray, R_b: FloatArray) -> FloatArray:
    """The rotation halfway (geodesically) from ``R_a`` to ``R_b``, (3, 3)."""
    return np.asarray(pin.exp3(0.5 * pin.log3(R_b @ R_a.T)) @ R_a, dtype=np.float64)
