"""The grasp subspace GSk as a constraint on an ambient vector.

Ambient layout, ``x: (7 + nq,)``::

    [x, y, z, qx, qy, qz, qw, q_hand...]

object position and orientation (quaternion XYZW) in the world (palm) frame,
then the hand joints in :attr:`Hand.joint_names` order.

Constraint rows, ``f(x): (k + 1,)``:

- for each contact finger i: ``sdf_O(R^T (p_i(q) - t)) - r``, the signed
  distance from fingertip-sphere centre to the object surface minus the tip
  radius (zero when the tip touches the surface);
- ``|quat|^2 - 1``.

The object rotation is that of the normalised quaternion, so the position rows
do not depend on the quaternion's norm and the last row alone fixes it. The
Jacobian is analytic: Pinocchio's fingertip Jacobians and the SDF gradient,

- d/dt       = -n_w^T
- d/dq_i     =  n_w^T J_i
- d/dquat    =  n_o^T d(R^T v)/d(quat_hat) (I - quat_hat quat_hat^T) / |quat|

with ``n_o`` the SDF gradient (outward normal) in the object frame,
``n_w = R n_o`` and ``v = p_i - t``. No finite differences anywhere. The last
evaluation is cached: OMPL asks for f and J at the same point in a row.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dexplan.core.errors import InvalidInputError
from dexplan.core.pose import quat_to_matrix
from dexplan.core.typing import FloatArray, as_vector
from dexplan.model.hand.hand import Hand
from dexplan.model.objects import Shape

POSE_DIM = 7


def _cross_rows(a: FloatArray, b: FloatArray) -> FloatArray:
    """Row-wise cross products of ``a, b: (k, 3)`` (np.cross is slow for small arrays)."""
    out = np.empty_like(a)
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


class GraspSubspace:
    """GSk for a hand, an object and a set of contact fingers.

    Args:
        hand: the hand.
        obj: the object shape (object frame).
        contact_fingers: (n,) True for the fingers in contact; all by default (GSn).
        workspace_center: (3,) nominal object position, world frame.
        workspace_half_extent: (3,) half size of the box the object centre
            stays in (m).
    """

    def __init__(
        self,
        hand: Hand,
        obj: Shape,
        contact_fingers: Sequence[bool] | None = None,
        *,
        workspace_center: FloatArray,
        workspace_half_extent: FloatArray,
    ) -> None:
        self.hand = hand
        self.obj = obj
        mask = [True] * hand.n_fingers if contact_fingers is None else list(contact_fingers)
        if len(mask) != hand.n_fingers:
            raise InvalidInputError(
                f"contact_fingers must have {hand.n_fingers} entries, got {len(mask)}"
            )
        self.contact_fingers: tuple[bool, ...] = tuple(bool(c) for c in mask)
        self.contact_ids: tuple[int, ...] = tuple(i for i, c in enumerate(mask) if c)
        self.workspace_center = as_vector(workspace_center, "workspace_center", 3)
        self.workspace_half_extent = as_vector(workspace_half_extent, "workspace_half_extent", 3)
        if np.any(self.workspace_half_extent < 0):
            raise InvalidInputError(
                f"workspace_half_extent must be >= 0, got {self.workspace_half_extent.tolist()}"
            )
        self.ambient_dim = POSE_DIM + hand.nq
        self.co_dim = len(self.contact_ids) + 1
        self.lower = np.concatenate(
            [self.workspace_center - self.workspace_half_extent, -np.ones(4), hand.lower]
        )
        self.upper = np.concatenate(
            [self.workspace_center + self.workspace_half_extent, np.ones(4), hand.upper]
        )
        # column blocks of each contact finger's joints in the ambient vector
        self._q_cols = [POSE_DIM + hand.finger_q_index[i] for i in self.contact_ids]
        self._eye4 = np.eye(4)
        self._ids = list(self.contact_ids)
        self._cache_key: bytes | None = None
        self._cache_f = np.zeros(self.co_dim)
        self._cache_J = np.zeros((self.co_dim, self.ambient_dim))

    # ---------------------------------------------------------------- layout
    def split(self, x: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(object_pose_xyzquat (7,), q_hand (nq,))`` of an ambient vector."""
        return x[:POSE_DIM], x[POSE_DIM:]

    def join(self, object_pose_xyzquat: FloatArray, q_hand: FloatArray) -> FloatArray:
        """Ambient vector from an object pose (XYZW) and hand joints."""
        return np.concatenate([object_pose_xyzquat, q_hand])

    def check_state(self, x: object, name: str = "state") -> FloatArray:
        """Return ``x`` as a finite ambient vector or raise InvalidInputError."""
        return as_vector(x, name, self.ambient_dim)

    # ----------------------------------------------------------- constraint
    def _evaluate(self, x: FloatArray) -> None:
        key = x.tobytes()
        if key == self._cache_key:
            return
        t, quat, q = x[:3], x[3:7], x[POSE_DIM:]
        norm = float(np.sqrt(quat @ quat))
        qh = quat / norm
        R = quat_to_matrix(qh)
        p_all, jacs = self.hand.fingertip_jacobians(q)
        ids = self.contact_ids
        v = p_all[self._ids] - t  # (k, 3) world-frame offsets from object origin
        p_obj = v @ R
        d, n_obj = self.obj.signed_distance_and_gradient(p_obj)
        n_world = n_obj @ R.T
        f = self._cache_f
        J = self._cache_J
        J.fill(0.0)
        f[:-1] = np.atleast_1d(d) - self.hand.fingertip_radius
        f[-1] = norm * norm - 1.0
        u, w = qh[:3], qh[3]
        # d(n_o . R^T v)/d(quat_hat), all contact rows at once, from
        # R^T v = (w^2 - |u|^2) v + 2 u (u.v) - 2 w (u x v)
        nv = np.einsum("ij,ij->i", n_obj, v)
        n_x_v = _cross_rows(n_obj, v)
        dq_hat = np.empty((len(ids), 4))
        dq_hat[:, :3] = (
            -2.0 * nv[:, None] * u
            + 2.0 * (v @ u)[:, None] * n_obj
            + 2.0 * (n_obj @ u)[:, None] * v
            + 2.0 * w * n_x_v
        )
        dq_hat[:, 3] = 2.0 * w * nv + 2.0 * (n_x_v @ u)
        proj = (self._eye4 - np.outer(qh, qh)) / norm
        J[:-1, :3] = -n_world
        J[:-1, 3:7] = dq_hat @ proj
        for row, i in enumerate(ids):
            J[row, self._q_cols[row]] = n_world[row] @ jacs[i]
        J[-1, 3:7] = 2.0 * quat
        self._cache_key = key

    def function(self, x: FloatArray) -> FloatArray:
        """Constraint value ``f(x): (k + 1,)``; zero on GSk.

        Cheaper than :meth:`jacobian` (no Jacobians): OMPL evaluates f far
        more often than J.
        """
        if x.tobytes() == self._cache_key:
            return self._cache_f.copy()
        t, quat = x[:3], x[3:7]
        norm = float(np.sqrt(quat @ quat))
        R = quat_to_matrix(quat / norm)
        p = self.hand.fingertip_positions(x[POSE_DIM:])[self._ids]
        f = np.empty(self.co_dim)
        f[:-1] = self.obj.signed_distance((p - t) @ R) - self.hand.fingertip_radius
        f[-1] = norm * norm - 1.0
        return f

    def jacobian(self, x: FloatArray) -> FloatArray:
        """Constraint Jacobian ``J(x): (k + 1, 7 + nq)``."""
        self._evaluate(x)
        return self._cache_J.copy()

    def residual(self, x: FloatArray) -> float:
        """Max absolute constraint violation at ``x``."""
        return float(np.max(np.abs(self.function(x))))

    # -------------------------------------------------------------- contacts
    def fingertips_object_frame(self, x: FloatArray) -> FloatArray:
        """Fingertip centres of all fingers in the object frame, ``(n, 3)``."""
        t, quat = x[:3], x[3:7]
        R = quat_to_matrix(quat / np.linalg.norm(quat))
        return (self.hand.fingertip_positions(x[POSE_DIM:]) - t) @ R

    def contacts(self, x: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Contact points and inward normals of the contact fingers, object frame.

        Returns:
            ``p_contact_obj: (k, 3)`` closest surface points to the fingertip
            centres and ``n_in_obj: (k, 3)`` inward unit surface normals there.
        """
        tips = self.fingertips_object_frame(x)[list(self.contact_ids)]
        pts, n_out = self.obj.closest_point(tips)
        return pts, -n_out
