"""Closed-form IK of a 2-joint finger with parallel axes (a planar 2R finger): both elbows.

The Dex3's index and middle fingers are such: two flexion joints about
parallel axes ``a``. The fingertip centre then moves in one plane
perpendicular to ``a``, at a constant height ``h`` along ``a``: a target off
that plane (beyond :data:`PLANE_TOL`) is not reachable, and one in it is a
planar 2R problem with two solutions (elbow one way or the other). The
fingers' contacts are found from joint space
(:mod:`dexplan.planning.gsn.contact_curve`); this solver serves the
transfers, which follow a fixed contact, and the landings.

:meth:`PlanarPairIK.detect` checks the solver against forward kinematics
before a hand uses it; its interface is :class:`.offset.OffsetFingerIK`'s.
"""

from __future__ import annotations

import numpy as np

from dexplan.core.typing import FloatArray
from dexplan.model.hand.ik.chain import FingerChain
from dexplan.model.hand.ik.closed_form import matches_fk, nearest_branch_of, planar_2r

__all__ = ["PLANE_TOL", "PlanarPairIK"]

_PARALLEL_TOL = 1e-9
#: Largest distance (m) of a target from the fingertip's plane that is reached.
PLANE_TOL = 1e-9


def _wrap(q: FloatArray) -> FloatArray:
    """Angles wrapped into ``[-pi, pi)``."""
    return (q + np.pi) % (2.0 * np.pi) - np.pi


class PlanarPairIK:
    """Both closed-form branches of a 2-joint finger with parallel axes.

    Geometry (world frame, joints at zero) read from a
    :class:`~dexplan.model.hand.ik.chain.FingerChain`: the joints' origins
    ``o1``, ``o2`` and the first joint's unit axis ``a`` (the second's is
    ``s2 a``, ``s2 = +-1``); the plane basis ``e1`` (from the first joint
    towards the second, perpendicular to ``a``) and ``e2 = a x e1``.

    Args:
        chain: the finger's forward kinematics.
        lo: (2,) lower joint limits.
        hi: (2,) upper joint limits.
    """

    def __init__(self, chain: FingerChain, lo: FloatArray, hi: FloatArray) -> None:
        t0, origins, axes = chain.forward(np.zeros((1, 2)))
        self.lo, self.hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
        self.o1, o2 = origins[0]
        self.a = axes[0, 0]
        self.s2 = float(np.sign(axes[0, 1] @ self.a))
        link = (o2 - self.o1) - ((o2 - self.o1) @ self.a) * self.a
        self.n1 = float(np.linalg.norm(link))
        self.e1 = link / max(self.n1, 1e-300)
        self.e2 = np.cross(self.a, self.e1)
        t0 = t0[0]
        self.h = float(self.a @ (t0 - self.o1))  # the fingertip's plane
        self.l2 = np.array([self.e1 @ (t0 - o2), self.e2 @ (t0 - o2)])

    @classmethod
    def detect(
        cls, chain: FingerChain | None, lo: FloatArray, hi: FloatArray
    ) -> PlanarPairIK | None:
        """The solver when ``chain`` has 2 parallel joints and it matches FK, else None."""
        if chain is None or chain.m != 2:
            return None
        _, _, axes = chain.forward(np.zeros((1, 2)))
        if np.linalg.norm(np.cross(axes[0, 0], axes[0, 1])) > _PARALLEL_TOL:
            return None
        solver = cls(chain, lo, hi)
        if min(solver.n1, float(np.linalg.norm(solver.l2))) < 1e-6:
            return None
        return solver if matches_fk(chain, solver.lo, solver.hi, solver.branches) else None

    def branches(self, targets: FloatArray) -> tuple[FloatArray, np.ndarray]:
        """Both branches of many targets.

        Args:
            targets: (N, 3) fingertip-centre targets, world frame.

        Returns:
            ``q: (N, 2, 2)`` joint values and ``ok: (N, 2)``: the target lies
            in the fingertip's plane (:data:`PLANE_TOL`), the branch exists
            and lies within the joint limits (1e-12 tolerance).
        """
        p = np.asarray(targets, dtype=float).reshape(-1, 3) - self.o1
        in_plane = np.abs(p @ self.a - self.h) <= PLANE_TOL
        d = np.stack([p @ self.e1, p @ self.e2], axis=1)
        in_annulus, elbows = planar_2r(d, np.array([self.n1, 0.0]), self.l2)
        inside = in_plane & in_annulus
        q = np.zeros((len(p), 2, 2))
        ok = np.zeros((len(p), 2), dtype=bool)
        for elbow, (q1, phi) in enumerate(elbows):
            q[:, elbow] = _wrap(np.stack([q1, self.s2 * phi], axis=1))
            qe = q[:, elbow]
            within = np.all((qe >= self.lo - 1e-12) & (qe <= self.hi + 1e-12), axis=1)
            ok[:, elbow] = inside & within
        return np.clip(q, self.lo, self.hi), ok

    def nearest(self, targets: FloatArray, q_near: FloatArray) -> tuple[FloatArray, np.ndarray]:
        """Per target the valid branch nearest ``q_near: (2,)`` or ``(N, 2)``.

        Returns:
            ``q: (N, 2)`` and ``ok: (N,)`` (some branch valid).
        """
        return nearest_branch_of(self.branches, targets, q_near)
