"""Closed-form IK of a 3-joint finger with offset axes: every branch by subproblem decomposition.

The TriFinger's finger_edu is the case in point: a first joint whose axis
``e`` is perpendicular to two parallel flexion axes ``a``, with the joints
and the fingertip offset sideways along ``a`` (so the finger is not of the
"abduction + planar 2R" kind :mod:`.planar` solves, nor :mod:`.split`'s).
The decomposition (Paden-Kahan subproblems, worked out for this geometry):

1. the flexion joints move the fingertip in a plane perpendicular to ``a``,
   at a constant offset ``A0`` along ``a`` from the first joint's origin;
2. the first joint turns about ``e``, so the fingertip's coordinate along
   ``e`` and its distance ``rho`` from the axis ``e`` do not depend on it:
   the target fixes the in-plane point up to the sign of
   ``sqrt(rho^2 - A0^2)`` (two branches);
3. each in-plane point is a planar 2R problem (knee one way or the other:
   two branches each);
4. the first joint's angle turns the solved fingertip onto the target.

Up to four solutions per target, all computed at once for many targets;
:meth:`OffsetFingerIK.detect` checks the solver against forward kinematics
before a hand uses it.
"""

from __future__ import annotations

import numpy as np

from dexplan.core.typing import FloatArray
from dexplan.model.hand.ik.chain import FingerChain
from dexplan.model.hand.ik.closed_form import matches_fk, nearest_branch_of, planar_2r

__all__ = ["OffsetFingerIK"]

_PARALLEL_TOL = 1e-9


def _wrap(q: FloatArray) -> FloatArray:
    """Angles wrapped into ``[-pi, pi)``."""
    return (q + np.pi) % (2.0 * np.pi) - np.pi


class OffsetFingerIK:
    """All closed-form branches of a 3-joint finger with offset parallel flexion axes.

    Geometry (world frame, all joints at zero) read from a
    :class:`~dexplan.model.hand.ik.chain.FingerChain`: the first joint's
    origin ``o1`` and unit axis ``e``; the flexion joints' origins ``o2``,
    ``o3`` and the unit axis ``a`` of the second joint (the third's is
    ``s3 a``, ``s3 = +-1``); the fingertip centre ``t0``.

    Args:
        chain: the finger's forward kinematics.
        lo: (3,) lower joint limits.
        hi: (3,) upper joint limits.
    """

    def __init__(self, chain: FingerChain, lo: FloatArray, hi: FloatArray) -> None:
        t0, origins, axes = chain.forward(np.zeros((1, 3)))
        self.lo, self.hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
        self.o1, self.o2, o3 = origins[0]
        self.e, self.a = axes[0, 0], axes[0, 1]
        self.s3 = float(np.sign(axes[0, 2] @ self.a))
        self.c = np.cross(self.a, self.e)  # with e: the flexion plane's axes
        self.b = np.cross(self.e, self.a)  # with a: the plane the first joint turns in
        t0 = t0[0]
        self.A0 = float(self.a @ (t0 - self.o1))
        self.l1 = np.array([self.e @ (o3 - self.o2), self.c @ (o3 - self.o2)])
        self.l2 = np.array([self.e @ (t0 - o3), self.c @ (t0 - o3)])
        self.c_o2 = float(self.c @ (self.o2 - self.o1))

    @classmethod
    def detect(
        cls, chain: FingerChain | None, lo: FloatArray, hi: FloatArray
    ) -> OffsetFingerIK | None:
        """The solver when ``chain`` has this geometry and it matches FK, else None."""
        if chain is None or chain.coupled or chain.m != 3:
            return None
        _, _, axes = chain.forward(np.zeros((1, 3)))
        e, a, a3 = axes[0]
        if np.linalg.norm(np.cross(a, a3)) > _PARALLEL_TOL or abs(e @ a) > _PARALLEL_TOL:
            return None
        solver = cls(chain, lo, hi)
        if min(np.linalg.norm(solver.l1), np.linalg.norm(solver.l2)) < 1e-6:
            return None
        return solver if matches_fk(chain, solver.lo, solver.hi, solver.branches) else None

    def branches(self, targets: FloatArray) -> tuple[FloatArray, np.ndarray]:
        """Every branch of many targets.

        Args:
            targets: (N, 3) fingertip-centre targets, world frame.

        Returns:
            ``q: (N, 4, 3)`` joint values and ``ok: (N, 4)``: the branch
            exists and lies within the joint limits (1e-12 tolerance).
        """
        p = np.asarray(targets, dtype=float).reshape(-1, 3) - self.o1
        n = len(p)
        pe = p @ self.e
        rho2 = np.einsum("ij,ij->i", p, p) - pe * pe
        cy = np.sqrt(np.maximum(rho2 - self.A0 * self.A0, 0.0))
        reach = rho2 >= self.A0 * self.A0 - 1e-15
        dx = pe - self.e @ (self.o2 - self.o1)
        q = np.zeros((n, 4, 3))
        ok = np.zeros((n, 4), dtype=bool)
        for side, c in enumerate((cy, -cy)):
            d = np.stack([dx, c - self.c_o2], axis=1)  # fingertip from o2, flexion plane
            in_annulus, elbows = planar_2r(d, self.l1, self.l2)
            inside = reach & in_annulus
            # the second link at angle phi from the first: D = Rot(q2) (l1 + Rot(phi) l2)
            for knee, (q2, phi) in enumerate(elbows):
                # the first joint turns (A0, -c) in the (a, b) plane onto the target's
                q1 = np.arctan2(p @ self.b, p @ self.a) - np.arctan2(-c, self.A0)
                col = 2 * side + knee
                q[:, col] = _wrap(np.stack([q1, q2, self.s3 * phi], axis=1))
                within = np.all(
                    (q[:, col] >= self.lo - 1e-12) & (q[:, col] <= self.hi + 1e-12), axis=1
                )
                ok[:, col] = inside & within
        return np.clip(q, self.lo, self.hi), ok

    def nearest(self, targets: FloatArray, q_near: FloatArray) -> tuple[FloatArray, np.ndarray]:
        """Per target the valid branch nearest ``q_near: (3,)`` or ``(N, 3)``.

        Returns:
            ``q: (N, 3)`` and ``ok: (N,)`` (some branch valid).
        """
        return nearest_branch_of(self.branches, targets, q_near)
