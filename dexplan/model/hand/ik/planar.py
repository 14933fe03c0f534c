"""Closed-form IK of an abduction joint followed by a planar 2R chain (3 joints).

The builtin paper and three-finger hands' fingers are of this kind. Besides
the solver, :func:`planar_branches` and :func:`nearest_branch` give every
branch of many targets at once with the solver's own scalar arithmetic, so
that a batched caller picks bit for bit the solution :meth:`PlanarFingerIK.solve`
returns.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from dexplan.core.typing import FloatArray, IntArray


class PlanarFingerIK:
    """Closed-form IK of an abduction joint followed by a planar 2R chain.

    Geometry read off the model at q = 0: abduction axis ``a0`` through ``o0``;
    the flexion joints' origins and the tip lie on the ray from ``o0`` along
    ``e`` (perpendicular to ``a0``) at distances ``k``, ``k + l1`` and
    ``k + l1 + l2``; both flexion axes are perpendicular to ``a0`` and ``e``.
    :meth:`detect` verifies the solver against FK before it is used.

    Args:
        o0: (3,) a point of the abduction axis, world frame.
        a0: (3,) unit abduction axis.
        e: (3,) unit direction of the finger at zero abduction.
        k: distance from ``o0`` to the first flexion joint along ``e`` (m).
        l1: first flexion link length (m).
        l2: second flexion link length, to the fingertip centre (m).
        s: +1 or -1, the sense of the flexion axes relative to ``a0 x e``.
        lo: (3,) lower joint limits.
        hi: (3,) upper joint limits.
    """

    def __init__(
        self,
        o0: FloatArray,
        a0: FloatArray,
        e: FloatArray,
        k: float,
        l1: float,
        l2: float,
        s: float,
        lo: FloatArray,
        hi: FloatArray,
    ) -> None:
        self.o0, self.a0, self.e = o0, a0, e
        self.b = np.cross(a0, e)
        self.k, self.l1, self.l2, self.s = k, l1, l2, s
        self.lo, self.hi = lo, hi

    @classmethod
    def detect(
        cls,
        model: pin.Model,
        data: pin.Data,
        idx: IntArray,
        tip_frame_id: int,
        lower: FloatArray,
        upper: FloatArray,
        neutral: FloatArray,
    ) -> PlanarFingerIK | None:
        """The solver for one finger when its structure allows one, else None.

        Args:
            model: the hand's Pinocchio model.
            data: its data (used as scratch: forward kinematics overwrite it).
            idx: (3,) the finger's entries of the hand configuration.
            tip_frame_id: Pinocchio frame id of the fingertip centre.
            lower: (nq,) lower joint limits of the hand.
            upper: (nq,) upper joint limits of the hand.
            neutral: (nq,) hand configuration the other fingers keep.

        Returns:
            The solver, checked against forward kinematics on 20 random
            configurations (fixed seed), or None.
        """
        if len(idx) != 3:
            return None

        def tip_at(q: FloatArray) -> FloatArray:
            pin.forwardKinematics(model, data, q)
            return pin.updateFramePlacement(model, data, tip_frame_id).translation

        q0 = np.zeros(model.nq)
        pin.forwardKinematics(model, data, q0)
        tip = pin.updateFramePlacement(model, data, tip_frame_id).translation.copy()
        jids = [j for i in idx for j in range(1, model.njoints) if model.idx_qs[j] == i]
        origins = [data.oMi[j].translation.copy() for j in jids]
        J = pin.computeJointJacobians(model, data, q0)
        axes = [J[3:, int(i)].copy() for i in idx]
        o0, a0 = origins[0], axes[0]
        ray = tip - o0
        if np.linalg.norm(ray) < 1e-9 or abs(ray @ a0) > 1e-7 * np.linalg.norm(ray):
            return None
        e = ray / np.linalg.norm(ray)
        k = float((origins[1] - o0) @ e)
        l1 = float((origins[2] - origins[1]) @ e)
        l2 = float((tip - origins[2]) @ e)
        f = axes[1]
        s = float(np.cross(f, e) @ a0)
        if min(l1, l2) <= 0 or abs(abs(s) - 1) > 1e-7 or np.linalg.norm(axes[2] - f) > 1e-7:
            return None
        solver = cls(o0, a0, e, k, l1, l2, s, lower[idx], upper[idx])
        rng = np.random.default_rng(0)
        q = neutral.copy()
        for _ in range(20):
            q[idx] = rng.uniform(solver.lo, solver.hi)
            target = tip_at(q).copy()
            sol = solver.solve(target, q[idx])
            if sol is None:
                return None
            q2 = q.copy()
            q2[idx] = sol
            if np.linalg.norm(tip_at(q2) - target) > 1e-8:
                return None
        return solver

    def solve(self, target: FloatArray, q_near: FloatArray) -> FloatArray | None:
        """Joint values within limits reaching ``target`` (closest to ``q_near``), or None."""
        p = target - self.o0
        u = float(p @ self.a0) * self.s
        pe, pb = float(p @ self.e), float(p @ self.b)
        r = math.hypot(pe, pb)
        base = math.atan2(pb, pe)
        best, best_d = None, math.inf
        l1, l2 = self.l1, self.l2
        for th0, w in ((base, r - self.k), (base - math.copysign(math.pi, base), -r - self.k)):
            c2 = (w * w + u * u - l1 * l1 - l2 * l2) / (2 * l1 * l2)
            if abs(c2) > 1.0:
                continue
            for th2 in (math.acos(c2), -math.acos(c2)):
                th1 = math.atan2(u, w) - math.atan2(l2 * math.sin(th2), l1 + l2 * math.cos(th2))
                th1 = (th1 + math.pi) % (2 * math.pi) - math.pi
                sol = np.array([th0, th1, th2])
                if np.all(sol >= self.lo - 1e-12) and np.all(sol <= self.hi + 1e-12):
                    d = float(np.sum((sol - q_near) ** 2))
                    if d < best_d:
                        best, best_d = np.clip(sol, self.lo, self.hi), d
        return best

    def solve_batch(self, targets: FloatArray) -> tuple[FloatArray, np.ndarray]:
        """Vectorized :meth:`solve` without the nearest-solution preference.

        Args:
            targets: (N, 3) fingertip-centre targets, world frame.

        Returns:
            ``q: (N, 3)`` and ``ok: (N,)``; among the branches within limits
            the first found is returned (abduction on the target's side first).
        """
        p = targets - self.o0
        u = (p @ self.a0) * self.s
        pe, pb = p @ self.e, p @ self.b
        r = np.hypot(pe, pb)
        base = np.arctan2(pb, pe)
        l1, l2 = self.l1, self.l2
        q_out = np.zeros((len(targets), 3))
        ok = np.zeros(len(targets), dtype=bool)
        lo, hi = self.lo - 1e-12, self.hi + 1e-12
        # elbow signs the third joint's limits allow at all (pruned for speed)
        signs = [sg for sg in (1.0, -1.0) if sg * hi[2] >= 0.0 or sg * lo[2] >= 0.0]
        for th0, w in ((base, r - self.k), (base - np.copysign(np.pi, base), -r - self.k)):
            cand = (th0 >= lo[0]) & (th0 <= hi[0]) & ~ok
            if not cand.any():
                continue
            c2 = (w * w + u * u - l1 * l1 - l2 * l2) / (2 * l1 * l2)
            cand &= np.abs(c2) <= 1.0
            a2 = np.arccos(np.clip(c2, -1.0, 1.0))
            for sg in signs:
                th2 = sg * a2
                th1 = np.arctan2(u, w) - np.arctan2(l2 * np.sin(th2), l1 + l2 * np.cos(th2))
                th1 = (th1 + np.pi) % (2 * np.pi) - np.pi
                new = cand & ~ok & (th1 >= lo[1]) & (th1 <= hi[1]) & (th2 >= lo[2]) & (th2 <= hi[2])
                q_out[new, 0] = th0[new]
                q_out[new, 1] = th1[new]
                q_out[new, 2] = th2[new]
                ok |= new
        return np.clip(q_out, self.lo, self.hi), ok


def planar_branches(
    solver: PlanarFingerIK, targets: FloatArray
) -> tuple[FloatArray, np.ndarray, FloatArray]:
    """Every branch of a closed-form abduction + planar 2R finger for many targets.

    ``solver`` is a finger's :class:`PlanarFingerIK`. Branch order and
    arithmetic are those of its ``solve`` (the same scalar operations), so
    that :func:`nearest_branch` picks bit for bit the solution ``solve``
    returns.

    Args:
        solver: the closed-form solver.
        targets: (N, 3) fingertip-centre targets, world frame.

    Returns:
        ``q: (N, 4, 3)`` unclipped branch solutions, ``ok: (N, 4)`` branches
        within the limits (1e-12 tolerance), and ``q_clipped: (N, 4, 3)``.
    """
    n = len(targets)
    q = np.zeros((n, 4, 3))
    ok = np.zeros((n, 4), dtype=bool)
    lo, hi = solver.lo - 1e-12, solver.hi + 1e-12
    l1, l2 = solver.l1, solver.l2
    # scalar math, as the solver's own: NumPy's vectorised transcendental
    # functions may differ from libm's in the last bit (numpy 2.4 SIMD loops)
    for i in range(n):
        p = targets[i] - solver.o0
        u = float(p @ solver.a0) * solver.s
        pe, pb = float(p @ solver.e), float(p @ solver.b)
        r = math.hypot(pe, pb)
        base = math.atan2(pb, pe)
        for a, (th0, w) in enumerate(
            ((base, r - solver.k), (base - math.copysign(math.pi, base), -r - solver.k))
        ):
            c2 = (w * w + u * u - l1 * l1 - l2 * l2) / (2 * l1 * l2)
            valid = abs(c2) <= 1.0
            acos = math.acos(min(1.0, max(-1.0, c2)))
            for sgn, th2 in enumerate((acos, -acos)):
                th1 = math.atan2(u, w) - math.atan2(l2 * math.sin(th2), l1 + l2 * math.cos(th2))
                th1 = (th1 + math.pi) % (2 * math.pi) - math.pi
                col = 2 * a + sgn
                q[i, col] = (th0, th1, th2)
                ok[i, col] = valid and bool(np.all((q[i, col] >= lo) & (q[i, col] <= hi)))
    return q, ok, np.clip(q, solver.lo, solver.hi)


def nearest_branch(
    q: FloatArray, ok: np.ndarray, q_clipped: FloatArray, q_near: FloatArray
) -> FloatArray | None:
    """The branch of one target (rows of :func:`planar_branches`) nearest ``q_near``.

    ``q: (4, 3)``, ``ok: (4,)``, ``q_clipped: (4, 3)``; the first of equally
    near branches wins, as in the scalar solver. None when no branch is valid.
    """
    best, best_d = -1, math.inf
    for j in range(4):
        if ok[j]:
            d = float(np.sum((q[j] - q_near) ** 2))
            if d < best_d:
                best, best_d = j, d
    return None if best < 0 else q_clipped[best]
