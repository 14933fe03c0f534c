"""Holds: can the fingers in contact hold the object's weight within the joints' effort limits?

A *hold* is one configuration of a plan with its loaded contacts (every
contact on a transfer waypoint, the n-1 holding fingers during a regrasp).
It counts when contact forces exist that

- lie in the friction cones (the plan's contact model and linearization:
  the pyramid's edges lie on the round Coulomb cone, so a hold of the
  pyramid is a hold of the round cone),
- press every contact with at least ``min_normal_force``,
- balance the object's weight (``mass`` times ``gravity``, world frame, at
  the object-frame origin) plus any extra wrench,
- need joint torques ``tau = sum_c J_c^T [f_c; m_c]`` within every joint's
  effort limit,

and it still counts with **each contact moved** ``shift_m`` (default 2 mm)
along the surface, one contact at a time, in each of four tangent
directions (``+-t1``, ``+-t2`` of the contact's tangent basis): the
fingertip sphere's centre moves that far and the contact is where the
sphere then meets the surface, pushing towards the centre. A real fingertip never lands exactly
where the plan says, and a hold on a knife edge of the torque limits or of
force closure would drop the object.

The figure of a hold is its **torque ratio**: the least, over admissible
forces, of the largest ``|tau_j| / effort_j``, maximised over the nominal
contacts and every shifted set. It is one linear program (HiGHS) with one
block of force variables per contact set sharing the ratio ``t``:
``min t`` s.t. each block balances the wrench in its cones with
``|T_s x_s| <= t e``. The hold counts iff the ratio is at most 1; it is
``inf`` when some contact set cannot balance the wrench at all (not force
closure). A hand without effort limits has ratio 0 wherever it can hold.
A checker built with ``effort_share`` s < 1 takes the ratio against s times
the limits: the planner's holds then leave the hand torque headroom to
execute the plan with (a servo needs some to correct errors), while the
verifier checks the limits themselves.

Frames and units as :mod:`dexplan.model.grasp.grip_forces`: contacts and
normals in the object frame, forces in newtons, torques in N m.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin
import scipy.sparse as sp
from scipy.optimize import Bounds, LinearConstraint, milp

from dexplan.core.errors import InvalidInputError
from dexplan.core.typing import FloatArray
from dexplan.model.grasp.cones import tangent_basis
from dexplan.model.grasp.grip_forces import ForceSettings
from dexplan.model.grasp.grip_program import (
    contact_torque_columns,
    grip_program,
    joint_effort_limits,
)
from dexplan.model.objects.fingertip import fingertip_contact

__all__ = ["DEFAULT_HOLD_SHIFT", "MAX_HOLD_SHIFT", "HoldChecker"]

#: How far (m) each contact is moved along the surface when a hold is checked.
DEFAULT_HOLD_SHIFT = 0.002
#: Largest accepted shift (m): a larger one is a unit mistake.
MAX_HOLD_SHIFT = 0.05


class HoldChecker:
    """Torque ratios of holds for one plan's hand, object, friction and load.

    Args:
        hand: the plan's :class:`~dexplan.model.hand.hand.Hand` (its effort limits).
        obj: the object :class:`~dexplan.model.objects.Shape`.
        mu: friction coefficient.
        edges: friction-cone edges of the linearization.
        contact_model: ``"point"`` or ``"soft"``.
        torsion: soft-finger torsion coefficient (m).
        forces: mass, gravity, extra wrench and least normal force
            (``cone_margin`` is not used: the shifts are the margin); default
            :class:`~dexplan.model.grasp.grip_forces.ForceSettings`.
        shift_m: how far each contact is moved along the surface (m), in [0, 0.05].
        effort_share: the share of each joint's effort limit a hold may use,
            in (0, 1]: the ratio is taken against ``effort_share`` times the
            limits (1: the limits themselves, as the verifier checks them; a
            planner leaves headroom for execution with less).
    """

    def __init__(
        self,
        hand: Any,
        obj: Any,
        mu: float,
        edges: int = 8,
        contact_model: str = "point",
        torsion: float = 0.0,
        forces: ForceSettings | None = None,
        shift_m: float = DEFAULT_HOLD_SHIFT,
        effort_share: float = 1.0,
    ) -> None:
        if not (
            isinstance(shift_m, int | float)
            and math.isfinite(shift_m)
            and 0.0 <= shift_m <= MAX_HOLD_SHIFT
        ):
            raise InvalidInputError(
                f"hold shift must be a number in [0, {MAX_HOLD_SHIFT}] m, got {shift_m!r}"
            )
        self.hand, self.obj = hand, obj
        self.mu, self.edges = float(mu), int(edges)
        self.soft = contact_model == "soft"
        self.torsion = float(torsion)
        self.forces = forces if forces is not None else ForceSettings()
        if not (isinstance(effort_share, int | float) and 0.0 < effort_share <= 1.0):
            raise InvalidInputError(f"effort share must be in (0, 1], got {effort_share!r}")
        self.shift_m = float(shift_m)
        self.effort_share = float(effort_share)
        self.L = float(obj.characteristic_length)
        self._data = hand.model.createData()
        e = joint_effort_limits(hand.model)
        self._limited = np.flatnonzero(~np.isnan(e))
        self._effort = self.effort_share * e[self._limited]
        self._memo: dict[bytes, float] = {}

    def holds(
        self, q: FloatArray, object_pose: FloatArray, contacts: Sequence[FloatArray | None]
    ) -> bool:
        """Whether the loaded contacts hold the object within the effort limits (ratio <= 1)."""
        return self.ratio(q, object_pose, contacts) <= 1.0

    def ratio(
        self,
        q: FloatArray,
        object_pose: FloatArray,
        contacts: Sequence[FloatArray | None],
        *,
        shifted: bool = True,
    ) -> float:
        """The hold's torque ratio (see the module); ``inf`` when it cannot hold at all.

        Args:
            q: (nq,) joints (rad).
            object_pose: (7,) object pose, world frame, XYZW.
            contacts: per finger, its contact point (3,) in the object frame,
                or None for a finger that carries no load.
            shifted: also with each contact moved ``shift_m`` (False: the
                stated contacts only).
        """
        hold = _Hold(np.asarray(q, dtype=float), np.asarray(object_pose, dtype=float), contacts)
        w_ext = self._wrench(hold.pose)
        idx = hold.loaded()
        if not idx:
            return 0.0 if float(np.linalg.norm(w_ext)) <= 1e-9 else math.inf
        P = np.array([np.asarray(contacts[i], dtype=float).reshape(3) for i in idx])
        held = np.concatenate([self.hand.finger_q_index[i] for i in idx]).astype(int)
        key = np.round(np.concatenate([P.ravel(), w_ext, hold.q[held], [shifted]]), 12).tobytes()
        hit = self._memo.get(key)
        if hit is None and shifted:
            # the shifted sets only add blocks: a hold that fails at its stated
            # contacts fails with them, and that one block is cheap
            nominal = self.ratio(q, object_pose, contacts, shifted=False)
            if not nominal <= 1.0:
                hit = nominal
        if hit is None:
            hit = _shared_ratio(self._blocks(hold, shifted=shifted))
            if len(self._memo) > 4096:
                self._memo.clear()
            self._memo[key] = hit
        return hit

    def worst_ratio(
        self, holds: Sequence[tuple[FloatArray, FloatArray, Sequence[FloatArray | None]]]
    ) -> float:
        """The largest torque ratio of many holds at their stated contacts, in one program.

        One linear program for all of them (their blocks share the ratio), far
        cheaper than one program each: along a transfer every waypoint is a hold.

        Args:
            holds: ``(q, object_pose, contacts)`` per hold, as :meth:`ratio` takes them.
        """
        blocks: list[_Block] = []
        for q, pose, contacts in holds:
            hold = _Hold(np.asarray(q, dtype=float), np.asarray(pose, dtype=float), contacts)
            if not hold.loaded():
                return 0.0 if float(np.linalg.norm(self._wrench(hold.pose))) <= 1e-9 else math.inf
            blocks += self._blocks(hold, shifted=False)
        return _shared_ratio(blocks) if blocks else 0.0

    def _wrench(self, pose: FloatArray) -> FloatArray:
        """(6,) the external wrench in the object frame (torque about its origin)."""
        R = pin.Quaternion(pose[6], pose[3], pose[4], pose[5]).normalized().toRotationMatrix()
        w = self.forces.wrench_world()
        return np.concatenate([R.T @ w[:3], R.T @ w[3:]])

    def _blocks(self, hold: _Hold, *, shifted: bool) -> list[_Block]:
        """A hold's blocks: its stated contacts, then (``shifted``) the moved ones."""
        q, pose = hold.q, hold.pose
        R = pin.Quaternion(pose[6], pose[3], pose[4], pose[5]).normalized().toRotationMatrix()
        w_ext = self._wrench(pose)
        idx = hold.loaded()
        P = np.array([np.asarray(hold.contacts[i], dtype=float).reshape(3) for i in idx])
        tips = (self.hand.fingertip_positions(q) - pose[:3]) @ R  # object frame
        N = np.array(
            [
                -fingertip_contact(self.obj, P[c], tips[i], self.hand.fingertip_radius)[1]
                for c, i in enumerate(idx)
            ]
        ).reshape(-1, 3)
        jac = self._jacobians(q, idx)
        used = self._used(idx)
        sets = [(P, N)]
        for c in range(len(idx)) if shifted and self.shift_m > 0 else ():
            sets += self._shifted(P, N, c)
        return [self._block(P2, N2, w_ext, pose, R, jac, used) for P2, N2 in sets]

    def _shifted(self, P: FloatArray, N: FloatArray, c: int) -> list[tuple[FloatArray, FloatArray]]:
        """Contact sets with contact ``c`` moved ``shift_m`` along the surface, 4 ways.

        The fingertip sphere's centre is moved ``shift_m`` along each tangent
        direction; the contact is then where the sphere meets the surface
        (the closest surface point to the centre) and pushes along the
        direction to the centre, as the verifier reads a contact. On a smooth
        surface the contact moves ``shift_m`` (to first order) and its normal
        turns with the surface; a fingertip on a box edge rolls over it, its
        normal turning gradually, rather than jumping onto a face's normal.
        """
        r = self.hand.fingertip_radius
        centre = P[c] - r * N[c]  # N is inward
        t1, t2 = tangent_basis(N[c][None, :])
        out = []
        for d in (t1[0], -t1[0], t2[0], -t2[0]):
            moved = centre + self.shift_m * d
            p, n_surf = self.obj.closest_point(moved)
            p = np.asarray(p, dtype=float).reshape(3)
            gap = moved - p
            norm = float(np.linalg.norm(gap))
            n_out = gap / norm if norm > 1e-9 else np.asarray(n_surf, dtype=float).reshape(3)
            P2, N2 = P.copy(), N.copy()
            P2[c], N2[c] = p, -n_out
            out.append((P2, N2))
        return out

    def _jacobians(self, q: FloatArray, idx: list[int]) -> list[tuple[FloatArray, FloatArray]]:
        """Per loaded finger: its tip frame's (6, nv) LOCAL_WORLD_ALIGNED Jacobian and centre."""
        model, data = self.hand.model, self._data
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        out = []
        for i in idx:
            fid = self.hand.tip_frame_ids[i]
            J = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
            out.append((np.asarray(J), data.oMf[fid].translation.copy()))
        return out

    def _block(
        self,
        P: FloatArray,
        N: FloatArray,
        w_ext: FloatArray,
        pose: FloatArray,
        R: FloatArray,
        jac: list[tuple[FloatArray, FloatArray]],
        used: np.ndarray,
    ) -> _Block:
        """One contact set's balance, normal-force and cone rows and its torque rows."""
        prog = grip_program(
            P,
            N,
            w_ext,
            mu_eff=self.mu,
            torsion_eff=self.torsion if self.soft else None,
            L=self.L,
            edges=self.edges,
            min_normal_force=self.forces.min_normal_force,
            torque=None,
        )
        r = 4 if self.soft else 3
        T = np.zeros((self.hand.model.nv, P.shape[0] * r))
        for c, (J, centre) in enumerate(jac):
            d = pose[:3] + R @ P[c] - centre  # tip centre to contact, world frame
            T[:, c * r : (c + 1) * r] = contact_torque_columns(
                J, d, R, N[c], self.L if self.soft else None
            )
        joints = self._limited[used]
        return _Block(prog.A, prog.lo, prog.hi, T[joints], self._effort[used])

    def _used(self, idx: list[int]) -> np.ndarray:
        """Positions in the limited joints of the joints of the loaded fingers ``idx``."""
        held = np.concatenate([self.hand.finger_q_index[i] for i in idx])
        return np.flatnonzero(np.isin(self._limited, held))


@dataclass(frozen=True)
class _Hold:
    """One hold: joints (nq,), object pose (7,), world frame, and per-finger contacts or None."""

    q: FloatArray
    pose: FloatArray
    contacts: Sequence[FloatArray | None]

    def loaded(self) -> list[int]:
        """The fingers that carry load."""
        return [i for i, c in enumerate(self.contacts) if c is not None]


@dataclass(frozen=True)
class _Block:
    """One contact set of the shared-ratio program.

    ``lo <= A x <= hi``; joint torques ``T x`` of the limited joints of its
    loaded fingers, whose effort limits are ``effort``.
    """

    A: FloatArray
    lo: FloatArray
    hi: FloatArray
    T: FloatArray
    effort: FloatArray


def _shared_ratio(blocks: list[_Block]) -> float:
    """``min t`` such that every block is feasible with ``|T_s x_s| <= t effort``; inf if none.

    Variables ``(x_1, ..., x_S, t)``; with no limited joint the program only
    decides feasibility and the ratio is 0. The blocks share only ``t``, so
    the matrix is block diagonal plus the ``t`` column: sparse, and
    ``milp`` takes its two-sided rows as they are (a transfer's program has
    a block per waypoint; a dense matrix of it costs more to build and
    convert than HiGHS takes to solve it).
    """
    rows, t_col, lo, hi = [], [], [], []
    for b in blocks:
        ne = len(b.effort)
        rows.append(np.vstack([b.A, b.T, -b.T]) if ne else b.A)
        t_col.append(np.concatenate([np.zeros(b.A.shape[0]), -b.effort, -b.effort]))
        lo.append(np.concatenate([b.lo, np.full(2 * ne, -np.inf)]))
        hi.append(np.concatenate([b.hi, np.zeros(2 * ne)]))
    t = np.concatenate(t_col)[:, None]
    A: Any = (
        np.hstack([rows[0], t])
        if len(rows) == 1
        else sp.hstack([sp.block_diag(rows, format="csr"), sp.csr_matrix(t)], format="csr")
    )
    m = A.shape[1] - 1
    lp = milp(
        np.r_[np.zeros(m), 1.0],
        constraints=LinearConstraint(A, np.concatenate(lo), np.concatenate(hi)),
        bounds=Bounds(np.r_[np.full(m, -np.inf), 0.0], np.full(m + 1, np.inf)),
        options={"presolve": False},
    )
    if lp.status != 0 or lp.x is None:
        return math.inf
    return float(lp.x[-1])
