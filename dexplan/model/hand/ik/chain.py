"""Forward kinematics of one revolute finger, vectorised over configurations.

Frames: everything is in the world (= palm) frame. ``q`` arrays hold one
finger's joints in chain order (root to tip), which is also the order of
``Hand.finger_q_index[i]``.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from dexplan.core.typing import FloatArray

_REVOLUTE = {"JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned"}


def _skew(a: FloatArray) -> FloatArray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


class FingerChain:
    """Forward kinematics of one finger, vectorised over configurations.

    Built from the Pinocchio model: the finger's joints must all be revolute
    and form a chain from the root to the fingertip frame (every joint of a
    finger belongs to it, so the chain's base is fixed in the world).

    Args:
        placements: per joint, ``(R, t)`` of the joint frame in its parent
            joint's frame at zero angle; ``R: (3, 3)``, ``t: (3,)``.
        axes: (m, 3) joint axes in their own joint frames (unit).
        tip: (3,) fingertip centre in the last joint's frame.
    """

    def __init__(
        self, placements: list[tuple[FloatArray, FloatArray]], axes: FloatArray, tip: FloatArray
    ) -> None:
        self.placements = placements
        self.axes = axes
        self.tip = tip
        self.m = len(placements)
        # joint j's local transform at angle q, Rodrigues folded into its
        # placement: [R_j + sin q (R_j K_j) + (1 - cos q) (R_j K_j^2), t_j],
        # as (m, 3, 9) coefficients of (1, sin q, 1 - cos q) and a 4x4 template
        terms = []
        for (Rj, _), a in zip(placements, axes, strict=True):
            K = _skew(a)
            terms.append(np.stack([Rj, Rj @ K, Rj @ K @ K]).reshape(3, 9))
        self._rodrigues = np.array(terms)
        self._template = np.zeros((self.m, 4, 4))
        for j, (_, tj) in enumerate(placements):
            self._template[j, :3, 3] = tj
            self._template[j, 3, 3] = 1.0
        self._tip_h = np.append(np.asarray(tip, dtype=float), 1.0)

    @classmethod
    def from_model(cls, model: pin.Model, tip_frame_id: int) -> FingerChain | None:
        """The chain ending in frame ``tip_frame_id``, or None if not all revolute."""
        frame = model.frames[tip_frame_id]
        jids = []
        jid = frame.parentJoint
        while jid > 0:
            jids.append(jid)
            jid = model.parents[jid]
        jids.reverse()
        if not jids or any(model.joints[j].shortname() not in _REVOLUTE for j in jids):
            return None
        data = model.createData()
        q0 = pin.neutral(model)
        J = pin.computeJointJacobians(model, data, q0)
        placements, axes = [], []
        for j in jids:
            M = model.jointPlacements[j]
            placements.append((np.array(M.rotation), np.array(M.translation)))
            # idx_vExtended: with <mimic> joints the columns of J include theirs
            w = J[3:, model.joints[j].idx_vExtended]
            axes.append(data.oMi[j].rotation.T @ w)
        axes_arr = np.array(axes)
        axes_arr /= np.linalg.norm(axes_arr, axis=1, keepdims=True)
        return cls(placements, axes_arr, np.array(frame.placement.translation))

    def forward(self, q: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Forward kinematics of many configurations.

        Args:
            q: (N, m) joint values.

        Returns:
            ``tip: (N, 3)`` fingertip centres, ``origins: (N, m, 3)`` joint
            origins and ``axes: (N, m, 3)`` unit joint axes, world frame.
        """
        q = np.asarray(q, dtype=float)
        n = len(q)
        # every joint's local 4x4 transform at once, then the chain products
        coef = np.empty((n, self.m, 3))
        coef[..., 0] = 1.0
        coef[..., 1] = np.sin(q)
        coef[..., 2] = 1.0 - np.cos(q)
        A = np.repeat(self._template[None], n, axis=0)
        A[..., :3, :3] = (coef[:, :, None, :] @ self._rodrigues).reshape(n, self.m, 3, 3)
        T = np.empty((n, self.m, 4, 4))
        T[:, 0] = A[:, 0]
        for j in range(1, self.m):
            T[:, j] = T[:, j - 1] @ A[:, j]
        # joint j's origin is T_j's translation; its axis is fixed by its own rotation
        origins = T[..., :3, 3]
        axes = (T[..., :3, :3] @ self.axes[:, :, None])[..., 0]
        return T[:, -1, :3, :] @ self._tip_h, origins, axes

    def tips(self, q: FloatArray) -> FloatArray:
        """Fingertip centres ``(N, 3)`` of configurations ``q: (N, m)``."""
        return self.forward(q)[0]

    def jacobian(self, q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Tip centres ``(N, 3)`` and position Jacobians ``(N, 3, m)`` (world frame)."""
        tip, origins, axes = self.forward(q)
        return tip, np.cross(axes, tip[:, None, :] - origins).transpose(0, 2, 1)
