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
contacts and every shifted set. Each set's is one small linear program
(HiGHS, :mod:`dexplan.model.grasp.ratio_lp`): ``min t`` s.t. its forces
balance the wrench in its cones with ``|T_s x_s| <= t e``; the hold's is the
largest (the program of all sets sharing ``t`` has that optimum). The hold
counts iff the ratio is at most 1; it is ``inf`` when some contact set
cannot balance the wrench at all (not force closure). A hand without
effort limits has ratio 0 wherever it can hold.
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

from dexplan.core.errors import InvalidInputError
from dexplan.core.typing import FloatArray
from dexplan.model.grasp.cones import friction_cone_facets, tangent_basis
from dexplan.model.grasp.grip_forces import ForceSettings
from dexplan.model.grasp.grip_program import (
    grip_program,
    joint_effort_limits,
)
from dexplan.model.grasp.ratio_lp import RatioLP
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
        self._used_memo: dict[tuple[int, ...], np.ndarray] = {}

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
        if hit is None:
            hit = self._ratio_of(hold, shifted=shifted)
            if len(self._memo) > 4096:
                self._memo.clear()
            self._memo[key] = hit
        return hit

    def stated_ratios(
        self,
        holds: Sequence[tuple[FloatArray, FloatArray, Sequence[FloatArray | None]]],
        normals: Sequence[FloatArray] | None = None,
    ) -> list[float]:
        """The torque ratios of many holds at their stated contacts (a transfer's waypoints).

        Each is :meth:`ratio` without shifts. The programs of holds of the
        same loaded fingers (point contacts with friction) are built together,
        and consecutive holds differ little, so each program starts from the
        previous one's solution (:class:`~dexplan.model.grasp.ratio_lp.RatioLP`).

        Args:
            holds: ``(q, object_pose, contacts)`` per hold, as :meth:`ratio` takes them.
            normals: per hold, the (k, 3) inward normals of its loaded
                contacts, object frame, as
                :func:`~dexplan.model.objects.fingertip.fingertip_contact`
                reads them, when the caller has read them already (the
                verifier has, for every waypoint).
        """
        hs = [_Hold(np.asarray(q, dtype=float), np.asarray(p, dtype=float), c) for q, p, c in holds]
        lp = RatioLP()
        fingers = {tuple(h.loaded()) for h in hs}
        if self.soft or self.mu <= 0.0 or len(fingers) != 1 or not next(iter(fingers)):
            return [self._ratio_of(h, shifted=False, lp=lp) for h in hs]
        frames = [self._frame(h, None if normals is None else normals[j]) for j, h in enumerate(hs)]
        P, N = np.array([f.P for f in frames]), np.array([f.N for f in frames])
        A, lo, hi = self._point_rows(P, N, np.array([f.w_ext for f in frames]))
        T = self._torques(P, N, frames)
        effort = frames[0].effort
        return [lp.ratio(A[j], lo[j], hi[j], T[j], effort) for j in range(len(hs))]

    def _ratio_of(self, hold: _Hold, *, shifted: bool, lp: RatioLP | None = None) -> float:
        """A hold's ratio: its stated contacts, then (``shifted``) each moved set.

        The shifted sets only add programs, so a hold that fails at its stated
        contacts fails with them: its figure is then the stated one, and the
        moved sets are not built.
        """
        if not hold.loaded():
            return 0.0 if float(np.linalg.norm(self._wrench(hold.pose))) <= 1e-9 else math.inf
        lp = RatioLP() if lp is None else lp
        frame = self._frame(hold)
        worst = lp.ratio(*self._block(frame.P, frame.N, frame))
        if not shifted or self.shift_m <= 0 or not worst <= 1.0:
            return worst
        sets = [s for c in range(len(frame.P)) for s in self._shifted(frame.P, frame.N, c)]
        if self.soft or self.mu <= 0.0:
            blocks = [self._block(P2, N2, frame) for P2, N2 in sets]
        else:  # the moved sets' rows and torques at once
            P2, N2 = np.array([P2 for P2, _ in sets]), np.array([N2 for _, N2 in sets])
            A, lo, hi = self._point_rows(P2, N2, np.broadcast_to(frame.w_ext, (len(sets), 6)))
            T = self._torques(P2, N2, [frame] * len(sets))
            blocks = [(A[j], lo[j], hi[j], T[j], frame.effort) for j in range(len(sets))]
        for block in blocks:
            worst = max(worst, lp.ratio(*block))
            if worst == math.inf:
                return worst
        return worst

    def _wrench(self, pose: FloatArray, R: FloatArray | None = None) -> FloatArray:
        """(6,) the external wrench in the object frame (torque about its origin).

        ``R``: the pose's (3, 3) rotation when the caller has it already.
        """
        if R is None:
            R = pin.Quaternion(pose[6], pose[3], pose[4], pose[5]).normalized().toRotationMatrix()
        w = self.forces.wrench_world()
        return np.concatenate([R.T @ w[:3], R.T @ w[3:]])

    def _frame(self, hold: _Hold, N: FloatArray | None = None) -> _Frame:
        """What every contact set of a hold shares: pose, load, contacts, Jacobians.

        ``N``: the (k, 3) inward normals of the loaded contacts when the
        caller has read them (else they are read here, the same way).
        """
        q, pose = hold.q, hold.pose
        R = pin.Quaternion(pose[6], pose[3], pose[4], pose[5]).normalized().toRotationMatrix()
        idx = hold.loaded()
        P = np.array([np.asarray(hold.contacts[i], dtype=float).reshape(3) for i in idx])
        if N is None:
            tips = (self.hand.fingertip_positions(q) - pose[:3]) @ R  # object frame
            N = np.array(
                [
                    -fingertip_contact(self.obj, P[c], tips[i], self.hand.fingertip_radius)[1]
                    for c, i in enumerate(idx)
                ]
            ).reshape(-1, 3)
        used = self._used(idx)
        joints = self._limited[used]
        jac = self._jacobians(q, idx)
        return _Frame(
            pose,
            R,
            self._wrench(pose, R),
            P,
            N,
            np.array([J.T[joints] for J, _ in jac]).reshape(len(idx), len(joints), 6),
            np.array([centre for _, centre in jac]).reshape(-1, 3),
            self._effort[used],
        )

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
        self, P: FloatArray, N: FloatArray, f: _Frame
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
        """One contact set's program: ``A``, ``lo``, ``hi``, its torque rows ``T``, ``effort``.

        ``lo <= A x <= hi`` are the balance, normal-force and cone rows of
        :func:`grip_program` (point contacts with friction, the common case,
        built here at once: the same rows); ``T x`` the torques of the limited
        joints of the loaded fingers, whose effort limits are ``effort``
        (:meth:`RatioLP.ratio`'s arguments).
        """
        if self.soft or self.mu <= 0.0:
            prog = grip_program(
                P,
                N,
                f.w_ext,
                mu_eff=self.mu,
                torsion_eff=self.torsion if self.soft else None,
                L=self.L,
                edges=self.edges,
                min_normal_force=self.forces.min_normal_force,
                torque=None,
            )
            A, lo, hi = prog.A, prog.lo, prog.hi
        else:
            A3, lo2, hi2 = self._point_rows(P[None], N[None], f.w_ext[None])
            A, lo, hi = A3[0], lo2[0], hi2[0]
        return A, lo, hi, self._torques(P[None], N[None], [f])[0], f.effort

    def _point_rows(
        self, P: FloatArray, N: FloatArray, w_ext: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """:func:`grip_program`'s rows for point contacts with friction, of H contact sets at once.

        Rows: balance ``sum f_c = -F``, ``sum p_c x f_c = -T`` (6), normal
        forces ``n_c . f_c >= min_normal_force`` (k), cone facets ``<= 0``
        (k edges); variables ``f_c``, three per contact.

        Args:
            P: (H, k, 3) contact points, object frame.
            N: (H, k, 3) inward unit normals, object frame.
            w_ext: (H, 6) the load, object frame.

        Returns:
            ``A`` (H, rows, 3 k), ``lo`` and ``hi`` (H, rows).
        """
        H, k, _ = P.shape
        E = self.edges
        c3 = 3 * np.arange(k)
        G = np.zeros((H, 6, 3 * k))
        G[:, :3] = np.tile(np.eye(3), k)
        G[:, 3, c3 + 1], G[:, 3, c3 + 2] = -P[:, :, 2], P[:, :, 1]  # [p_c]_x, contact by contact
        G[:, 4, c3], G[:, 4, c3 + 2] = P[:, :, 2], -P[:, :, 0]
        G[:, 5, c3], G[:, 5, c3 + 1] = -P[:, :, 1], P[:, :, 0]
        nrm = np.zeros((H, k, 3 * k))
        nrm[:, np.arange(k)[:, None], c3[:, None] + np.arange(3)] = N
        facets = friction_cone_facets(N.reshape(-1, 3), self.mu, E).reshape(H, k, E, 3)
        cone = np.zeros((H, k * E, 3 * k))
        r_idx = (E * np.arange(k))[:, None, None] + np.arange(E)[None, :, None]
        cone[:, r_idx, c3[:, None, None] + np.arange(3)] = facets
        f_min = self.forces.min_normal_force
        lo = np.concatenate([-w_ext, np.full((H, k), f_min), np.full((H, k * E), -np.inf)], axis=1)
        hi = np.concatenate([-w_ext, np.full((H, k), np.inf), np.zeros((H, k * E))], axis=1)
        return np.concatenate([G, nrm, cone], axis=1), lo, hi

    def _torques(self, P: FloatArray, N: FloatArray, frames: Sequence[_Frame]) -> FloatArray:
        """(H, joints, k r) the limited joints' torques per unit of each contact's variables.

        ``tau = J^T [f_w; d x f_w (+ tau_n R n)]`` with ``f_w = R f`` the force
        in the world frame and ``d`` the tip centre to the contact
        (:func:`~dexplan.model.grasp.grip_program.contact_torque_columns`, for
        H contact sets of k contacts at once, set j at ``frames[j]``'s pose).
        """
        H, k, _ = P.shape
        R = np.array([f.R for f in frames])  # (H, 3, 3)
        jt = np.array([f.jt for f in frames])  # (H, k, joints, 6)
        origin = np.array([f.pose[:3] for f in frames])[:, None, :]
        d = origin + P @ R.transpose(0, 2, 1) - np.array([f.centres for f in frames])
        S = np.zeros((H, k, 3, 3))  # [d]_x: tip centre to contact, world frame
        S[..., 0, 1], S[..., 0, 2] = -d[..., 2], d[..., 1]
        S[..., 1, 0], S[..., 1, 2] = d[..., 2], -d[..., 0]
        S[..., 2, 0], S[..., 2, 1] = -d[..., 1], d[..., 0]
        Rk = np.broadcast_to(R[:, None], (H, k, 3, 3))
        cols = jt @ np.concatenate([Rk, S @ Rk], axis=2)  # (H, k, joints, 3)
        if self.soft:  # the torsion variable: tau_n R n_c, scaled by L
            twist = np.einsum("hcjs,hcs->hcj", jt[..., 3:], N @ R.transpose(0, 2, 1)) * self.L
            cols = np.concatenate([cols, twist[..., None]], axis=3)
        return cols.transpose(0, 2, 1, 3).reshape(H, cols.shape[2], -1)

    def _used(self, idx: list[int]) -> np.ndarray:
        """Positions in the limited joints of the joints of the loaded fingers ``idx``."""
        key = tuple(idx)
        out = self._used_memo.get(key)
        if out is None:
            held = np.concatenate([self.hand.finger_q_index[i] for i in idx])
            out = self._used_memo[key] = np.flatnonzero(np.isin(self._limited, held))
        return out


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
class _Frame:
    """What the contact sets of one hold share.

    ``pose`` (7,) and ``R`` (3, 3) the object's pose, world frame; ``w_ext``
    (6,) the load, object frame; ``P``, ``N`` (k, 3) the stated contacts and
    inward normals, object frame; ``jt`` (k, joints, 6) per loaded finger the
    limited joints' rows of its tip frame's transposed ``LOCAL_WORLD_ALIGNED``
    Jacobian, ``centres`` (k, 3) its tip centre, world frame; ``effort``
    (joints,) those joints' effort limits (N m).
    """

    pose: FloatArray
    R: FloatArray
    w_ext: FloatArray
    P: FloatArray
    N: FloatArray
    jt: FloatArray
    centres: FloatArray
    effort: FloatArray
