"""Forward kinematics of one revolute finger, vectorised over configurations.

Frames: everything is in the world (= palm) frame. ``q`` arrays hold one
finger's joints in chain order (root to tip), which is also the order of
``Hand.finger_q_index[i]``.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from dexplan.core.typing import FloatArray, IntArray

_REVOLUTE = {"JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned"}
_MIMIC = "JointModelMimic"


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
        self,
        placements: list[tuple[FloatArray, FloatArray]],
        axes: FloatArray,
        tip: FloatArray,
        coupling: tuple[IntArray, FloatArray, FloatArray] | None = None,
    ) -> None:
        self.placements = placements
        self.axes = axes
        self.tip = tip
        #: joint k's angle is ``scale[k] * q[:, var[k]] + offset[k]``: a coupled
        #: (URDF ``<mimic>``) joint follows another of the chain's values
        var, scale, offset = coupling or (
            np.arange(len(placements)),
            np.ones(len(placements)),
            np.zeros(len(placements)),
        )
        self._var, self._scale, self._offset = var, scale, offset
        #: True when some joint follows another (the closed forms do not apply)
        self.coupled = coupling is not None
        #: the chain's values (its joints that have their own)
        self.m = int(var.max()) + 1 if len(var) else 0
        self.n_joints = len(placements)
        # joint j's local transform at angle q, Rodrigues folded into its
        # placement: [R_j + sin q (R_j K_j) + (1 - cos q) (R_j K_j^2), t_j],
        # as (m, 3, 9) coefficients of (1, sin q, 1 - cos q) and a 4x4 template
        terms = []
        for (Rj, _), a in zip(placements, axes, strict=True):
            K = _skew(a)
            terms.append(np.stack([Rj, Rj @ K, Rj @ K @ K]).reshape(3, 9))
        self._rodrigues = np.array(terms)
        self._template = np.zeros((self.n_joints, 4, 4))
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
        kinds = [model.joints[j].shortname() for j in jids]
        if not jids or any(k not in _REVOLUTE and k != _MIMIC for k in kinds):
            return None
        data = model.createData()
        q0 = pin.neutral(model)
        J = pin.computeJointJacobians(model, data, q0)
        own = [model.joints[j].idx_q for j, k in zip(jids, kinds, strict=True) if k != _MIMIC]
        placements, axes, var, scale, offset = [], [], [], [], []
        for j, kind in zip(jids, kinds, strict=True):
            jm = model.joints[j]
            M = model.jointPlacements[j]
            placements.append((np.array(M.rotation), np.array(M.translation)))
            # idx_vExtended: with <mimic> joints the columns of J include theirs
            w = J[3:, jm.idx_vExtended]
            if np.linalg.norm(w) < 1e-9 or jm.idx_q not in own:  # a prismatic mimic joint
                return None
            axes.append(data.oMi[j].rotation.T @ w)
            mimic = jm.extract() if kind == _MIMIC else None
            var.append(own.index(jm.idx_q))
            scale.append(1.0 if mimic is None else float(mimic.scaling))
            offset.append(0.0 if mimic is None else float(mimic.offset))
        axes_arr = np.array(axes)
        axes_arr /= np.linalg.norm(axes_arr, axis=1, keepdims=True)
        coupled = _MIMIC in kinds
        coupling = (np.array(var), np.array(scale), np.array(offset)) if coupled else None
        return cls(placements, axes_arr, np.array(frame.placement.translation), coupling)

    def forward(self, q: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Forward kinematics of many configurations.

        Args:
            q: (N, m) joint values (the chain's own: a coupled joint follows one).

        Returns:
            ``tip: (N, 3)`` fingertip centres, ``origins: (N, n_joints, 3)``
            joint origins and ``axes: (N, n_joints, 3)`` unit joint axes,
            world frame.
        """
        n, nj = len(q), self.n_joints
        # every joint's local 4x4 transform at once, then the chain products
        A = np.repeat(self._template[None], n, axis=0)
        A[..., :3, :3] = self._local_rotations(q)
        T = np.empty((n, nj, 4, 4))
        T[:, 0] = A[:, 0]
        for j in range(1, nj):
            T[:, j] = T[:, j - 1] @ A[:, j]
        # joint j's origin is T_j's translation; its axis is fixed by its own rotation
        origins = T[..., :3, 3]
        axes = (T[..., :3, :3] @ self.axes[:, :, None])[..., 0]
        return T[:, -1, :3, :] @ self._tip_h, origins, axes

    def tips(self, q: FloatArray) -> FloatArray:
        """Fingertip centres ``(N, 3)`` of configurations ``q: (N, m)``, world frame.

        The tip point is carried from the last joint to the first, a
        rotation and a translation per joint: matrix-vector products, a
        third of the work of :meth:`forward`'s chain of 4x4 products (the
        reach voxels take tens of thousands of configurations per finger).
        """
        R = self._local_rotations(q)
        t = self._template[:, :3, 3]
        p = np.broadcast_to(self._tip_h[:3], (len(R), 3))
        for j in range(self.n_joints - 1, -1, -1):
            p = np.einsum("nij,nj->ni", R[:, j], p) + t[j]
        return np.asarray(p, dtype=np.float64)

    def _local_rotations(self, q: FloatArray) -> FloatArray:
        """Each joint's rotation in its parent's frame ``(N, n_joints, 3, 3)`` at ``q: (N, m)``."""
        q = np.asarray(q, dtype=float)
        theta = q if not self.coupled else q[:, self._var] * self._scale + self._offset
        coef = np.empty((len(q), self.n_joints, 3))
        coef[..., 0] = 1.0
        coef[..., 1] = np.sin(theta)
        coef[..., 2] = 1.0 - np.cos(theta)
        # optimize: a BLAS product per joint, not a Python-level loop over N small ones
        rot = np.einsum("njk,jkl->njl", coef, self._rodrigues, optimize=True)
        return np.asarray(rot.reshape(len(q), self.n_joints, 3, 3))

    def jacobian(self, q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Tip centres ``(N, 3)`` and position Jacobians ``(N, 3, m)`` (world frame)."""
        tip, origins, axes = self.forward(q)
        J = np.cross(axes, tip[:, None, :] - origins).transpose(0, 2, 1)
        if not self.coupled:
            return tip, J
        # a value moves every joint that follows it, each by its scale
        out = np.zeros((len(J), 3, self.m))
        for k, v in enumerate(self._var):
            out[:, :, v] += J[:, :, k] * self._scale[k]
        return tip, out
