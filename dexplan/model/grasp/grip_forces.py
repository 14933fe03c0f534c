"""Grip forces: contact forces inside the friction cones that hold the object still.

The model (this module) answers for one configuration; :mod:`dexplan.execution.forces`
reads a plan file's waypoints into it. The planner asks :meth:`GripForceSolver.holds`
before a regrasp lets a finger go.

At a configuration of a plan (object pose, joints, contacts), the *loaded*
contacts (the fingers in contact, minus a regrasp's free finger) must balance
the external wrench on the object: gravity on its mass at the object-frame
origin (taken as the centre of mass) plus an optional extra wrench. Among the
forces that do, :class:`GripForceSolver` returns the one of least norm that
keeps a margin from the cone boundary:

- each force lies in the linearized cone of :mod:`dexplan.model.grasp` (the plan's
  contact model, ``point`` or ``soft``, and ``friction_edges``; the facets of
  :func:`~dexplan.model.grasp.friction_cone_facets` /
  :func:`~dexplan.model.grasp.soft_finger_facets`,
  the H-representation of the cones the generators of
  :func:`~dexplan.model.grasp.contact_wrenches` span)
  built with the friction ``mu (1 - cone_margin)`` (and the torsion
  ``torsion (1 - cone_margin)`` for soft contacts): the angle to the boundary
  of the true cone is then at least the difference of the two half-angles.
  Where no balance exists with that margin (a marginal 3-finger subgrasp
  during a regrasp), half, a quarter and then none of it are tried, then no
  margin with the densest pyramid (64 edges, closer to the round cone the
  verifier judges force closure by), and :attr:`GripForces.margin` says which
  was kept;
- each normal force is at least ``min_normal_force`` (N): the fingers always
  squeeze, which also keeps a margin from the cone's apex;
- the joint torques they need (below) within the URDF's effort limits, always:
  a grasp the joints can hold keeps a smaller margin rather than asking for
  more torque than the joints have (a wide margin can need several times the
  torque a narrower one does), and where no margin works within them there
  are no grip forces (:class:`GripForceError`): a limit is never relaxed;
- objective ``sum |f_c|^2 + (tau_c / L)^2`` (``tau_c`` the soft-finger
  torsional moment, ``L`` the object's characteristic length), solved by OSQP
  over the contact forces (strictly convex; balance as equalities, the cones
  as facet inequalities), after a linear program (HiGHS) has decided that a
  solution exists (OSQP alone misjudged badly conditioned grasps infeasible).

Frames and units: forces in newtons, in the **object frame** (as the
trajectory document reports them) and in the world frame; moments in N m.
``f_c`` is the force the finger applies *on the object* at its contact.

Joint torques: the torques the finger joints must produce to apply those
forces, ``tau = sum_c J_c^T [f_c; m_c]`` with ``J_c`` the 6 x nq Pinocchio
frame Jacobian of the fingertip frame (``LOCAL_WORLD_ALIGNED``: velocity of
the tip-sphere centre and angular velocity, world frame), ``f_c`` in the world
frame and ``m_c = (p_contact - p_tip) x f_c + tau_c n_c`` the moment about the
tip centre. The links' own weight is not included.

Defaults: mass 0.1 kg (the plan's ``object.mass`` when present),
gravity ``(0, 0, -9.81)`` m/s^2 in the world frame (the plan's
``world.gravity`` when present; palm-up for the builtin hands).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from dexplan.core.errors import DexplanError, InvalidInputError
from dexplan.core.typing import FloatArray
from dexplan.model.grasp.cones import MAX_FRICTION_EDGES, check_contact_model
from dexplan.model.grasp.grip_program import (
    BALANCE_TOL,
    GripProgram,
    contact_torque_columns,
    feasible_point,
    grip_program,
    joint_effort_limits,
    least_norm,
)
from dexplan.model.objects.fingertip import fingertip_contact

__all__ = [
    "DEFAULT_CONE_MARGIN",
    "DEFAULT_GRAVITY",
    "DEFAULT_MASS",
    "DEFAULT_MIN_NORMAL_FORCE",
    "ForceSettings",
    "GripForceError",
    "GripForceSolver",
    "GripForces",
    "loaded_fingers",
]

#: Object mass (kg) when the plan has no ``object.mass``.
DEFAULT_MASS = 0.1
#: Gravity (m/s^2, world frame) when the plan has no ``world.gravity``.
DEFAULT_GRAVITY = (0.0, 0.0, -9.81)
#: Fraction of ``mu`` (and of the torsion) given up as a margin from the cone boundary.
DEFAULT_CONE_MARGIN = 0.2
#: Least normal force of every loaded contact (N).
DEFAULT_MIN_NORMAL_FORCE = 0.2


class GripForceError(DexplanError):
    """No forces inside the cones balance the wrench (the grasp is not force closure)."""


@dataclass(frozen=True)
class ForceSettings:
    """What the grip forces balance and how far from the cone boundary they stay.

    Attributes:
        mass: object mass (kg), >= 0.
        gravity: (3,) gravity acceleration (m/s^2), world frame.
        external_wrench: (6,) extra wrench on the object ``[force, torque]``
            (N, N m), world frame, torque about the object-frame origin.
        cone_margin: fraction of ``mu`` and of the torsion kept as margin, in [0, 1).
        min_normal_force: least normal force per loaded contact (N), >= 0.
    """

    mass: float = DEFAULT_MASS
    gravity: tuple[float, float, float] = DEFAULT_GRAVITY
    external_wrench: tuple[float, ...] = (0.0,) * 6
    cone_margin: float = DEFAULT_CONE_MARGIN
    min_normal_force: float = DEFAULT_MIN_NORMAL_FORCE

    def __post_init__(self) -> None:
        if not (_finite(self.mass) and 0.0 <= self.mass <= 1e4):
            raise InvalidInputError(f"mass must be in [0, 1e4] kg, got {self.mass!r}")
        g = self.gravity
        if len(g) != 3 or not all(_finite(v) and abs(v) <= 1e3 for v in g):
            raise InvalidInputError(f"gravity must be 3 finite numbers (m/s^2), got {g!r}")
        w = self.external_wrench
        if len(w) != 6 or not all(_finite(v) and abs(v) <= 1e6 for v in w):
            raise InvalidInputError(f"external_wrench must be 6 finite numbers, got {w!r}")
        if not (_finite(self.cone_margin) and 0.0 <= self.cone_margin < 1.0):
            raise InvalidInputError(f"cone_margin must be in [0, 1), got {self.cone_margin!r}")
        if not (_finite(self.min_normal_force) and 0.0 <= self.min_normal_force <= 1e4):
            raise InvalidInputError(
                f"min_normal_force must be in [0, 1e4] N, got {self.min_normal_force!r}"
            )

    def wrench_world(self) -> FloatArray:
        """(6,) the external wrench on the object, world frame: weight plus the extra one."""
        w = np.asarray(self.external_wrench, dtype=float).copy()
        w[:3] += self.mass * np.asarray(self.gravity, dtype=float)
        return w


def _finite(v: object) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


@dataclass(frozen=True)
class GripForces:
    """Grip forces at one configuration (``n`` fingers).

    Attributes:
        loaded: (n,) the fingers that carry load.
        contacts: (n, 3) contact points, object frame (m); NaN rows for free fingers.
        normals: (n, 3) inward unit normals at the contacts, object frame; NaN when free.
        forces: (n, 3) force of each finger on the object, object frame (N);
            zero for fingers that carry no load.
        forces_world: (n, 3) the same forces, world frame (N).
        torsion: (n,) soft-finger torsional moments about the normals (N m); 0
            for point contacts.
        joint_torques: (nq,) joint torques that apply the forces (N m),
            ``hand.joint_names`` order.
        residual: (6,) ``sum of contact wrenches + external wrench`` (world
            frame, torque about the object origin); ~0.
        margin: the cone margin the forces keep (a fraction of ``mu``): the
            settings' ``cone_margin``, or half, a quarter or none of it where
            the larger margin admits no balance.
    """

    loaded: tuple[bool, ...]
    contacts: FloatArray
    normals: FloatArray
    forces: FloatArray
    forces_world: FloatArray
    torsion: FloatArray
    joint_torques: FloatArray
    residual: FloatArray
    margin: float


def loaded_fingers(contacts: Sequence[object], free_finger: int | None) -> tuple[bool, ...]:
    """Fingers that carry load: in contact, and not the free finger of a regrasp."""
    return tuple(c is not None and i != free_finger for i, c in enumerate(contacts))


class GripForceSolver:
    """Least-norm grip forces with a cone margin for one plan's hand, object and friction.

    Args:
        hand: the plan's :class:`~dexplan.model.hand.hand.Hand`.
        obj: the object :class:`~dexplan.model.objects.Shape`.
        mu: friction coefficient.
        edges: friction-cone edges (``friction_edges``).
        contact_model: ``"point"`` or ``"soft"``.
        torsion: soft-finger torsion coefficient (m); 0 for point contacts.
        settings: the wrench and margins.
    """

    def __init__(
        self,
        hand: Any,
        obj: Any,
        mu: float,
        edges: int = 8,
        contact_model: str = "point",
        torsion: float = 0.0,
        settings: ForceSettings = ForceSettings(),
    ) -> None:
        self.hand, self.obj = hand, obj
        self.mu, self.edges = float(mu), int(edges)
        self.contact_model = contact_model
        self.torsion = float(torsion)
        check_contact_model(contact_model, self.torsion)
        self.settings = settings
        self.L = float(obj.characteristic_length)
        self._data = hand.model.createData()
        # the same loaded contacts under the same wrench (a regrasp: the object
        # is still) give the same forces
        self._memo: dict[bytes, tuple[FloatArray, FloatArray, float]] = {}
        self._holds_memo: dict[bytes, bool] = {}

    def solve(
        self,
        q: FloatArray,
        object_pose: FloatArray,
        contacts: Sequence[FloatArray | None],
        loaded: Sequence[bool] | None = None,
        *,
        where: str = "configuration",
    ) -> GripForces:
        """Grip forces at one configuration.

        Args:
            q: (nq,) joints (rad).
            object_pose: (7,) object pose, world frame, XYZW.
            contacts: per finger, the contact point (3,) in the object frame or None.
            loaded: (n,) fingers that carry load (default: those in contact).
            where: the configuration in error messages (``segment 2, waypoint 5``).

        Raises:
            GripForceError: no forces in the (margin-shrunk) cones balance the wrench.
        """
        n = len(contacts)
        if loaded is None:
            loaded = tuple(c is not None for c in contacts)
        q = np.asarray(q, dtype=float)
        pose, R, w_ext_world, w_ext = self._frame(object_pose)
        P, N = self._contacts(q, pose, R, contacts)
        idx = [i for i in range(n) if loaded[i] and contacts[i] is not None]
        forces = np.zeros((n, 3))
        tors = np.zeros(n)
        margin = self.settings.cone_margin
        if idx:
            key = self._key(q, P, w_ext, idx)
            hit = self._memo.get(key)
            if hit is None:
                torque = self._torque_rows(q, pose, R, P, N, idx)
                hit = _remember(
                    self._memo, key, self._qp_margins(P[idx], N[idx], w_ext, where, torque)
                )
            f, t, margin = hit
            forces[idx] = f
            tors[idx] = t
        elif np.linalg.norm(w_ext) > BALANCE_TOL and any(loaded):
            raise GripForceError(f"{where}: no finger holds the object against its weight")
        fw = forces @ R.T
        # residual (world): sum f + F_ext, sum (R p) x f + tau n + T_ext
        res = np.zeros(6)
        res[:3] = fw.sum(axis=0) + w_ext_world[:3]
        for i in idx:
            res[3:] += np.cross(R @ P[i], fw[i]) + tors[i] * (R @ N[i])
        res[3:] += w_ext_world[3:]
        tau = self._torques(q, pose, R, P, N, fw, tors, idx)
        return GripForces(
            tuple(bool(b) for b in loaded), P, N, forces, fw, tors, tau, res, float(margin)
        )

    def holds(
        self,
        q: FloatArray,
        object_pose: FloatArray,
        contacts: Sequence[FloatArray | None],
    ) -> bool:
        """Whether the fingers in contact can hold the object within the joints' effort limits.

        The question the planner asks before a regrasp lets a finger go (the
        others then hold the object still, in one configuration, for the
        whole regrasp): do forces exist in the cones of the plan's
        linearization (no margin) that balance the external wrench with
        every normal force at least ``min_normal_force`` and every limited
        joint torque within its effort limit? A linear program decides it;
        :meth:`solve` then finds such forces (it tries the same problem among
        its margins), so the export's limits check passes there. A hand with
        no effort limits holds whatever its force-closure grasps hold: True.

        Args:
            q: (nq,) joints (rad).
            object_pose: (7,) object pose, world frame, XYZW.
            contacts: per finger, the contact point (3,) in the object frame,
                or None for a finger that carries no load.
        """
        idx = [i for i in range(len(contacts)) if contacts[i] is not None]
        pose, R, _, w_ext = self._frame(object_pose)
        if not idx:
            return bool(np.linalg.norm(w_ext) <= BALANCE_TOL)
        q = np.asarray(q, dtype=float)
        P, N = self._contacts(q, pose, R, contacts)
        key = self._key(q, P, w_ext, idx)
        hit = self._holds_memo.get(key)
        if hit is None:
            torque = self._torque_rows(q, pose, R, P, N, idx)
            if torque is None:
                hit = True
            else:
                prog = self._program(P[idx], N[idx], w_ext, 0.0, self.edges, torque)
                hit = feasible_point(prog.A, prog.lo, prog.hi) is not None
            _remember(self._holds_memo, key, hit)
        return hit

    def _frame(
        self, object_pose: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """The pose, its rotation, and the external wrench in both frames.

        Returns:
            ``(pose, R, w_ext_world, w_ext)``: (7,) pose, (3, 3) rotation, (6,)
            external wrench in the world and in the object frame (torque about
            the object origin).
        """
        pose = np.asarray(object_pose, dtype=float)
        R = pin.Quaternion(pose[6], pose[3], pose[4], pose[5]).normalized().toRotationMatrix()
        w_ext_world = self.settings.wrench_world()
        w_ext = np.concatenate([R.T @ w_ext_world[:3], R.T @ w_ext_world[3:]])
        return pose, R, w_ext_world, w_ext

    def _key(self, q: FloatArray, P: FloatArray, w_ext: FloatArray, idx: list[int]) -> bytes:
        """Memo key of a grip problem at the loaded fingers ``idx``.

        The loaded contacts, the wrench, and the loaded fingers' joints (they
        enter through the torque limits).
        """
        held = np.concatenate([self.hand.finger_q_index[i] for i in idx]).astype(int)
        return np.round(np.concatenate([P[idx].ravel(), w_ext, q[held]]), 12).tobytes()

    def _contacts(
        self, q: FloatArray, pose: FloatArray, R: FloatArray, contacts: Sequence[FloatArray | None]
    ) -> tuple[FloatArray, FloatArray]:
        """The stated contacts and the inward normals the fingertips push along.

        Read as the plan verifier reads them
        (:func:`~dexplan.model.objects.fingertip.fingertip_contact`): a fingertip
        on a box edge pushes along the direction from the edge to its centre,
        not along the normal of the face the edge point's closest point
        names (that normal is not the direction a sphere on an edge can
        push in, and with it many grasps of a box by its edges would look
        unable to hold it).

        Returns:
            ``(P, N)``: (n, 3) contact points and inward unit normals, object
            frame; NaN rows for fingers without a contact.
        """
        n = len(contacts)
        P = np.full((n, 3), np.nan)
        N = np.full((n, 3), np.nan)
        tips = (self.hand.fingertip_positions(q) - pose[:3]) @ R  # object frame
        r = self.hand.fingertip_radius
        for i, c in enumerate(contacts):
            if c is None:
                continue
            c = np.asarray(c, dtype=float).reshape(3)
            _, n_out, _ = fingertip_contact(self.obj, c, tips[i], r)
            P[i], N[i] = c, -n_out
        return P, N

    def _qp_margins(
        self,
        P: FloatArray,
        N: FloatArray,
        w_ext: FloatArray,
        where: str,
        torque: tuple[FloatArray, FloatArray] | None = None,
    ) -> tuple[FloatArray, FloatArray, float]:
        """:meth:`_qp` with the largest margin of ``cone_margin * (1, 1/2, 1/4, 0)`` that works.

        With ``torque`` (the joint torque rows and effort limits of
        :meth:`_torque_rows`), every margin is tried within the effort
        limits, never without them.
        """
        m0 = self.settings.cone_margin
        margins = [m0, m0 / 2, m0 / 4, 0.0] if m0 > 0 else [0.0]
        # the plan's linearization, then the densest one (closer to the round
        # cone the verifier judges by) without margin
        tries = [(mg, self.edges) for mg in margins] + [(0.0, MAX_FRICTION_EDGES)]
        for margin, edges in tries:
            out = self._qp(P, N, w_ext, margin, edges, torque)
            if out is not None:
                return (*out, margin)
        st = self.settings
        if torque is not None and self._qp(P, N, w_ext, 0.0, MAX_FRICTION_EDGES, None) is not None:
            raise GripForceError(
                f"{where}: the {P.shape[0]} loaded contact(s) hold the object's weight "
                f"({st.mass:g} kg) only with joint torques beyond the hand's effort limits "
                "(a limit is never relaxed)"
            )
        model = (
            f"soft contacts, mu {self.mu:g}, torsion {self.torsion:g} m"
            if self.contact_model == "soft"
            else f"point contacts, mu {self.mu:g}"
        )
        raise GripForceError(
            f"{where}: no contact forces inside the friction cones ({model}, normal force >= "
            f"{st.min_normal_force:g} N) balance the object's weight ({st.mass:g} kg) and "
            f"the external wrench: the {P.shape[0]} loaded contact(s) are not force closure"
        )

    def _qp(
        self,
        P: FloatArray,
        N: FloatArray,
        w_ext: FloatArray,
        margin: float,
        edges: int,
        torque: tuple[FloatArray, FloatArray] | None = None,
    ) -> tuple[FloatArray, FloatArray] | None:
        """Least-norm contact forces, cones shrunk by ``margin``; None if infeasible.

        Variables ``x_c = (f_c, sigma_c)`` per contact (``sigma_c = tau_c / L``,
        soft contacts only), object frame; the cone facets of
        :func:`dexplan.model.grasp.friction_cone_facets` or
        :func:`dexplan.model.grasp.soft_finger_facets` (``a . x_c <= 0``).

        Returns:
            ``(f, tau)``: (k, 3) forces (N) and (k,) torsional moments (N m).
        """
        prog = self._program(P, N, w_ext, margin, edges, torque)
        E, nrm, cone, extra = prog.E, prog.nrm, prog.cone, prog.extra
        st = self.settings
        k = P.shape[0]
        soft = self.contact_model == "soft"
        r = 4 if soft else 3
        L = self.L
        x = least_norm(prog.A, prog.lo, prog.hi)
        if x is None:
            return None
        resid = max(
            float(np.max(np.abs(E @ x - np.concatenate([-w_ext, np.zeros(len(extra))])))),
            float(np.max(cone @ x, initial=0.0)),
            float(np.max(st.min_normal_force - nrm @ x, initial=0.0)),
        )
        if resid > BALANCE_TOL * max(1.0, float(np.max(np.abs(x)))):
            return None
        X = x.reshape(k, r)
        return X[:, :3].copy(), (L * X[:, 3] if soft else np.zeros(k))

    def _program(
        self,
        P: FloatArray,
        N: FloatArray,
        w_ext: FloatArray,
        margin: float,
        edges: int,
        torque: tuple[FloatArray, FloatArray] | None,
    ) -> GripProgram:
        """The grip-force problem of :meth:`_qp`, cones (and torsion) shrunk by ``margin``."""
        soft = self.contact_model == "soft"
        return grip_program(
            P,
            N,
            w_ext,
            mu_eff=self.mu * (1.0 - margin),
            torsion_eff=self.torsion * (1.0 - margin) if soft else None,
            L=self.L,
            edges=edges,
            min_normal_force=self.settings.min_normal_force,
            torque=torque,
        )

    def _torque_rows(
        self,
        q: FloatArray,
        pose: FloatArray,
        R: FloatArray,
        P: FloatArray,
        N: FloatArray,
        idx: list[int],
    ) -> tuple[FloatArray, FloatArray] | None:
        """The joint torques of the QP variables and the joints' effort limits.

        ``tau = T x`` with ``x`` the loaded contacts' object-frame variables
        (as :meth:`_qp`), the same map as :meth:`_torques`; only joints with
        an effort limit get a row.

        Returns:
            ``(T, effort)``: (j, m) rows and (j,) limits (N m) of the limited
            joints, or None when no joint has a limit.
        """
        model = self.hand.model
        e = joint_effort_limits(model)
        limited = np.flatnonzero(~np.isnan(e))
        if limited.size == 0:
            return None
        soft = self.contact_model == "soft"
        r = 4 if soft else 3
        T = np.zeros((model.nv, len(idx) * r))
        for c, (i, J, d) in enumerate(self._tip_jacobians(q, pose, R, P, idx)):
            T[:, c * r : (c + 1) * r] = contact_torque_columns(
                J, d, R, N[i], self.L if soft else None
            )
        return T[limited], e[limited]

    def _torques(
        self,
        q: FloatArray,
        pose: FloatArray,
        R: FloatArray,
        P: FloatArray,
        N: FloatArray,
        fw: FloatArray,
        tors: FloatArray,
        idx: list[int],
    ) -> FloatArray:
        tau = np.zeros(self.hand.model.nv)
        for i, J, d in self._tip_jacobians(np.asarray(q, dtype=float), pose, R, P, idx):
            m = np.cross(d, fw[i]) + tors[i] * (R @ N[i])
            tau += J.T @ np.concatenate([fw[i], m])
        return tau

    def _tip_jacobians(
        self, q: FloatArray, pose: FloatArray, R: FloatArray, P: FloatArray, idx: list[int]
    ) -> list[tuple[int, FloatArray, FloatArray]]:
        """Per loaded finger ``i``: its tip frame Jacobian and the lever from tip to contact.

        Returns:
            ``(i, J, d)``: ``J`` the (6, nv) ``LOCAL_WORLD_ALIGNED`` Jacobian of
            the fingertip frame at ``q``, ``d`` (3,) contact point minus tip
            centre, world frame.
        """
        if not idx:
            return []
        model, data = self.hand.model, self._data
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        out = []
        for i in idx:
            fid = self.hand.tip_frame_ids[i]
            J = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
            out.append((i, J, pose[:3] + R @ P[i] - data.oMf[fid].translation))
        return out


def _remember(memo: dict, key: bytes, value: Any) -> Any:
    """Store ``value`` under ``key`` (the memo is emptied past 4096 entries); return it."""
    if len(memo) > 4096:
        memo.clear()
    memo[key] = value
    return value
