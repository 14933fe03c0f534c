"""Closed-form IK of an axis joint + planar 2R chain with at most one free joint.

A finger whose joints (after fixing at most one *free* joint) are an axis
joint followed by two parallel flexion joints whose plane contains that axis
("abduction + planar 2R": the paper hand's fingers, and the Allegro index,
middle and ring with their distal joint fixed, and the Allegro thumb with its
first joint fixed). A 3-joint finger has one solution per branch; a 4-joint
finger is redundant, and the free joint is resolved on a grid: every grid
value is solved in closed form and the solution nearest a reference
configuration wins (the previous joints when following a moving contact, the
middle of the joint ranges when sampling). See ``docs/hands.md``, "IK and
redundancy".
"""

from __future__ import annotations

import math

import numpy as np

from dexplan.core.typing import FloatArray
from dexplan.model.hand.ik.chain import FingerChain

#: Offsets (rad) of the free joint around its previous value tried when a
#: redundant finger follows a moving contact.
TRACK_DELTAS: tuple[int, ...] = (0, -1, 1, -3, 3, -8, 8)
#: Largest joint change (rad) accepted per tracking step when choosing the posture.
TRACK_MAX_STEP = 0.04
#: Spacing (rad) of the free-joint table used when following a contact (the
#: free joint takes table values; TRACK_DELTAS are steps in that table).
TRACK_RESOLUTION = 0.004
#: Free-joint grid size when solving without a previous configuration.
SAMPLE_GRID = 7


_BRANCH = np.array([1.0, -1.0])


def _wrap(a: FloatArray) -> FloatArray:
    return (a + np.pi) % (2.0 * np.pi) - np.pi


class SplitFingerIK:
    """Closed-form IK of an axis joint + planar 2R chain, with at most one free joint.

    Sub-chain joints ``sub = (a, f1, f2)`` (indices into the finger's
    joints): ``a`` turns a plane that contains its own axis, ``f1`` and
    ``f2`` are parallel flexion joints perpendicular to that plane, and the
    fingertip lies in it. A 4-joint finger has one more joint, ``free``
    (first or last), whose value is fixed for each closed-form solve.
    :meth:`detect` checks the structure numerically and verifies the solver
    against forward kinematics before it is used.

    Args:
        chain: the finger's forward kinematics.
        lo: (m,) lower joint limits.
        hi: (m,) upper joint limits.
        sub: indices of the axis joint and the two flexion joints.
        free: index of the free joint, or None for a 3-joint finger.
    """

    def __init__(
        self,
        chain: FingerChain,
        lo: FloatArray,
        hi: FloatArray,
        sub: tuple[int, int, int],
        free: int | None,
    ) -> None:
        self.chain = chain
        self.lo, self.hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
        self.sub = sub
        self.free = free
        self.m = chain.m
        self.rest = 0.5 * (self.lo + self.hi)
        self._lo_tol, self._hi_tol = self.lo - 1e-12, self.hi + 1e-12
        self._lo_list = [float(x) for x in self._lo_tol]
        self._hi_list = [float(x) for x in self._hi_tol]
        if free is None:
            self.grid = np.zeros(1)
            self.table = np.zeros(1)
        else:
            span = self.hi[free] - self.lo[free]
            # the fine table holds the sampling grid: sampled solutions track exactly
            per = max(1, int(np.ceil(span / TRACK_RESOLUTION / (SAMPLE_GRID + 1))))
            steps = (SAMPLE_GRID + 1) * per
            self.table = np.linspace(self.lo[free], self.hi[free], steps + 1)
            # grid values inside the range: a solution at a limit cannot move
            self.grid = self.table[per:-per:per]
        self._table_geometry = self.geometry(self.table)
        self._near_cache: dict[int, tuple[dict[str, FloatArray], FloatArray]] = {}
        self._grid_geometry = self.geometry(self.grid)
        self._rows = self._scalar_rows(self._table_geometry) if free is not None else []

    # ------------------------------------------------------------ structure
    @classmethod
    def detect(
        cls, chain: FingerChain | None, lo: FloatArray, hi: FloatArray
    ) -> SplitFingerIK | None:
        """The solver for ``chain`` when its structure allows one, else None."""
        if chain is None or chain.coupled or chain.m not in (3, 4):
            return None
        # a 4-joint finger: the distal joint free, else the first one
        options: list[tuple[tuple[int, int, int], int | None]] = (
            [((0, 1, 2), None)] if chain.m == 3 else [((0, 1, 2), 3), ((1, 2, 3), 0)]
        )
        for sub, free in options:
            solver = cls(chain, lo, hi, sub, free)
            if solver._verified():
                return solver
        return None

    def geometry(self, free_values: FloatArray) -> dict[str, FloatArray]:
        """Sub-chain geometry with the free joint at each of ``free_values: (K,)``.

        Returns arrays with a leading K axis: axis origin ``o: (K, 3)``,
        axis ``a``, plane normal ``n`` (the first flexion axis), in-plane
        direction ``b = n x a``; 2-D plane coordinates ``(u, w)`` (along a,
        along b) of the first flexion joint ``j1: (K, 2)``, the links
        ``L1: (K, 2)`` (first to second flexion joint) and ``L2`` (second
        flexion joint to tip), and the second flexion sign ``s2: (K,)``.
        """
        v = np.asarray(free_values, dtype=float).reshape(-1)
        q = np.zeros((len(v), self.m))
        if self.free is not None:
            q[:, self.free] = v
        tip, origins, axes = self.chain.forward(q)
        ia, i1, i2 = self.sub
        o, a, n = origins[:, ia], axes[:, ia], axes[:, i1]
        b = np.cross(n, a)

        def plane(x: FloatArray) -> FloatArray:
            d = x - o
            return np.stack([np.einsum("ij,ij->i", d, a), np.einsum("ij,ij->i", d, b)], axis=1)

        j1, j2, t = plane(origins[:, i1]), plane(origins[:, i2]), plane(tip)
        off = np.stack(
            [np.einsum("ij,ij->i", x - o, n) for x in (origins[:, i1], origins[:, i2], tip)]
        )
        L1, L2 = j2 - j1, t - j2
        # the last link (last joint to tip), rigid with L2's link beyond the
        # second flexion joint: turns by the same in-plane angle
        last = t - plane(origins[:, -1])
        l1s, l2s = np.einsum("ij,ij->i", L1, L1), np.einsum("ij,ij->i", L2, L2)
        return {
            "o": o,
            "a": a,
            "n": n,
            "b": b,
            "j1": j1,
            "L1": L1,
            "L2": L2,
            "last": last,
            # per free value constants of the solve (computed once, not per call)
            "l1s": l1s,
            "l2s": l2s,
            "l12": 2.0 * np.sqrt(l1s * l2s),
            "dphi": np.arctan2(L2[:, 1], L2[:, 0]) - np.arctan2(L1[:, 1], L1[:, 0]),
            "abn": np.stack([a, b, n], axis=1),
            "l1l2s": l1s + l2s,
            "s2": np.sign(np.einsum("ij,ij->i", axes[:, i2], n)),
            "off": np.abs(off).max(axis=0),
            "dot": np.abs(np.einsum("ij,ij->i", a, n)),
            "par": np.linalg.norm(np.cross(axes[:, i2], n), axis=1),
        }

    def _verified(self) -> bool:
        g = self._grid_geometry
        if np.any(g["off"] > 1e-9) or np.any(g["dot"] > 1e-9) or np.any(g["par"] > 1e-9):
            return False
        if np.any(np.linalg.norm(g["L1"], axis=1) < 1e-6) or np.any(
            np.linalg.norm(g["L2"], axis=1) < 1e-6
        ):
            return False
        rng = np.random.default_rng(0)
        q = rng.uniform(self.lo, self.hi, size=(20, self.m))
        targets = self.chain.tips(q)
        for k in range(len(q)):
            v = None if self.free is None else q[k, self.free : self.free + 1]
            sol, ok = self.solve(targets[k : k + 1], q[k], v)
            if not ok[0] or np.linalg.norm(self.chain.tips(sol)[0] - targets[k]) > 1e-9:
                return False
        return True

    # --------------------------------------------------------------- solving
    def candidates(
        self, targets: FloatArray, free_values: FloatArray | None = None
    ) -> tuple[FloatArray, np.ndarray]:
        """Every closed-form solution for each target.

        Args:
            targets: (N, 3) fingertip-centre targets, world frame.
            free_values: (K,) free-joint values to solve at (default: the
                sampling grid, :data:`SAMPLE_GRID` values across its range).

        Returns:
            ``q: (N, C, m)`` with C = 4 K (two abduction branches, two
            elbows per free value) and ``ok: (N, C)``, True where the
            solution exists and lies within the limits.
        """
        if free_values is None:
            g = self._grid_geometry
            v = self.grid
        else:
            v = np.asarray(free_values, dtype=float).reshape(-1)
            g = self.geometry(v)
        return self._candidates(targets, v, g)

    def _candidates(
        self, targets: FloatArray, v: FloatArray, g: dict[str, FloatArray]
    ) -> tuple[FloatArray, np.ndarray]:
        t = np.asarray(targets, dtype=float).reshape(-1, 3)
        N, K = len(t), len(v)
        p = t[:, None, :] - g["o"][None]  # (N, K, 3)
        # coordinates along a, b and n in one matrix product: (N, K, 3)
        proj = (g["abn"][None] @ p[..., None])[..., 0]
        u, pb, pn = proj[..., 0, None], proj[..., 1], proj[..., 2]
        # abduction branches (axis 2): in-plane coordinate w = +-rho along +-b
        th0 = np.empty((N, K, 2))
        th0[..., 0] = np.arctan2(pn, pb)
        th0[..., 1] = np.arctan2(-pn, -pb)
        rho = np.sqrt(pb * pb + pn * pn)[..., None]
        du = u - g["j1"][:, 0, None]
        dw = rho * _BRANCH - g["j1"][:, 1, None]
        c = (du * du + dw * dw - g["l1l2s"][:, None]) / g["l12"][:, None]
        reach = np.abs(c) <= 1.0
        # elbow branches (axis 3): (N, K, 2, 2)
        al2 = np.arccos(np.clip(c, -1.0, 1.0))[..., None] * _BRANCH - g["dphi"][:, None, None]
        ca, sa = np.cos(al2), np.sin(al2)
        L1, L2 = g["L1"][:, None, None, :], g["L2"][:, None, None, :]
        vu = L1[..., 0] + ca * L2[..., 0] - sa * L2[..., 1]
        vw = L1[..., 1] + sa * L2[..., 0] + ca * L2[..., 1]
        ia, i1, i2 = self.sub
        lo, hi = self._lo_tol, self._hi_tol
        # each joint's values and limits apart (contiguous arrays), then interleaved
        qa = _wrap(th0)
        q1 = _wrap(np.arctan2(dw, du)[..., None] - np.arctan2(vw, vu))
        q2 = _wrap(g["s2"][:, None, None] * al2)
        ok = reach & (qa >= lo[ia]) & (qa <= hi[ia])
        ok = ok[..., None] & (q1 >= lo[i1]) & (q1 <= hi[i1]) & (q2 >= lo[i2]) & (q2 <= hi[i2])
        q = np.empty((N, K, 2, 2, self.m))
        q[..., ia] = np.clip(qa, self.lo[ia], self.hi[ia])[..., None]
        q[..., i1] = np.clip(q1, self.lo[i1], self.hi[i1])
        q[..., i2] = np.clip(q2, self.lo[i2], self.hi[i2])
        if self.free is not None:
            f = self.free
            ok &= ((v >= lo[f]) & (v <= hi[f]))[None, :, None, None]
            q[..., f] = np.clip(v, self.lo[f], self.hi[f])[:, None, None]
        return q.reshape(N, 4 * K, self.m), ok.reshape(N, 4 * K)

    def solve(
        self,
        targets: FloatArray,
        q_ref: FloatArray | None = None,
        free_values: FloatArray | None = None,
    ) -> tuple[FloatArray, np.ndarray]:
        """The solution nearest ``q_ref`` for each target.

        Args:
            targets: (N, 3) fingertip-centre targets, world frame.
            q_ref: (N, m) or (m,) reference configurations (default: the
                middle of the joint ranges).
            free_values: (K,) free-joint values (default: the sampling grid).

        Returns:
            ``q: (N, m)`` within limits and ``ok: (N,)``.
        """
        q, ok = self.candidates(targets, free_values)
        return self._nearest(q, ok, q_ref)

    def _nearest(
        self, q: FloatArray, ok: np.ndarray, q_ref: FloatArray | None
    ) -> tuple[FloatArray, np.ndarray]:
        ref = self.rest if q_ref is None else np.asarray(q_ref, dtype=float)
        diff = q - np.broadcast_to(ref, (q.shape[0], self.m))[:, None, :]
        d = np.einsum("ncm,ncm->nc", diff, diff)
        d[~ok] = np.inf
        best = np.argmin(d, axis=1)
        rows = np.arange(len(q))
        return q[rows, best], ok[rows, best]

    def solve_near(
        self, target: FloatArray, q_prev: FloatArray, approach: FloatArray | None = None
    ) -> FloatArray | None:
        """The solution to one target continuous with ``q_prev: (m,)``, or None.

        The free joint is searched in a table (:data:`TRACK_RESOLUTION`
        apart) around the entry nearest its value in ``q_prev``
        (:data:`TRACK_DELTAS` entries away), so a contact followed in small
        steps gives joints that change in small steps. Without ``approach``
        the solution nearest ``q_prev`` wins. With ``approach: (3,)`` (unit,
        world frame, the direction the fingertip presses in: the inward
        surface normal) the redundancy goes to the finger's posture: among the
        solutions within :data:`TRACK_MAX_STEP` of ``q_prev`` in every joint,
        the one whose last link (last joint to fingertip) points most along
        ``approach``, so the distal link stays off the surface. When no
        solution is found near ``q_prev``, the sampling grid is searched
        (nearest to ``q_prev``).
        """
        if self._rows:
            best, near = self._track_scalar(target, q_prev, approach)
            if best is not None or near is not None:
                return near if best is None else best
            # a far target (a landing, not a small step): the whole grid
            t = np.asarray(target, dtype=float)[None]
            q, ok = self._nearest(*self._candidates(t, self.grid, self._grid_geometry), q_prev)
            return q[0] if ok[0] else None
        t = np.asarray(target, dtype=float)[None]
        g, v = self._table_near(q_prev)
        q, ok = self._candidates(t, v, g)
        if approach is not None and self.free is not None:
            best = self._best_posture(q[0], ok[0], q_prev, approach)
            if best is not None:
                return best
        q, ok = self._nearest(q, ok, q_prev)
        if not ok[0] and self.free is not None:
            # a far target (a landing, not a small step): the whole grid
            q, ok = self._nearest(*self._candidates(t, self.grid, self._grid_geometry), q_prev)
        return q[0] if ok[0] else None

    def _table_near(self, q_prev: FloatArray) -> tuple[dict[str, FloatArray], FloatArray]:
        """Free-joint values (and their geometry) within a tracking step of ``q_prev``."""
        if self.free is None:
            return self._table_geometry, self.table
        k0 = int(np.argmin(np.abs(self.table - q_prev[self.free])))
        near = self._near_cache.get(k0)
        if near is None:
            # a finger follows a contact through the same few table entries
            ks = np.clip(k0 + np.asarray(TRACK_DELTAS), 0, len(self.table) - 1)
            geometry = {key: val[ks] for key, val in self._table_geometry.items()}
            near = self._near_cache[k0] = (geometry, self.table[ks])
        return near

    def _scalar_rows(self, g: dict[str, FloatArray]) -> list[tuple[float, ...]]:
        """Per table entry, the solve's constants as Python floats (for :meth:`_track_scalar`).

        Empty when the last link leaves the flexion plane (its direction would
        not follow from the plane angles); :meth:`solve_near` then uses the
        vectorised path only.
        """
        q = np.zeros((len(self.table), self.m))
        q[:, self.free] = self.table
        _, origins, _ = self.chain.forward(q)
        if np.any(np.abs(np.einsum("ij,ij->i", origins[:, -1] - g["o"], g["n"])) > 1e-9):
            return []
        rows = []
        for k in range(len(self.table)):
            last = g["last"][k]
            rows.append(
                (
                    *g["o"][k],
                    *g["a"][k],
                    *g["b"][k],
                    *g["n"][k],
                    *g["j1"][k],
                    *g["L1"][k],
                    *g["L2"][k],
                    g["l1l2s"][k],
                    g["l12"][k],
                    g["dphi"][k],
                    g["s2"][k],
                    last[0],
                    last[1],
                    1.0 / math.hypot(*last),
                    self.table[k],
                )
            )
        return [tuple(float(x) for x in r) for r in rows]

    def _track_scalar(
        self, target: FloatArray, q_prev: FloatArray, approach: FloatArray | None
    ) -> tuple[FloatArray | None, FloatArray | None]:
        """:meth:`solve_near` on the table entries near ``q_prev``, in scalar arithmetic.

        The same table entries, branches, limits, step bound and scores as
        the vectorised path (:meth:`_candidates`, then :meth:`_best_posture`
        and :meth:`_nearest`), with the last link's direction from the plane
        angles instead of forward kinematics: one target costs a fraction of
        the NumPy calls' overhead.

        Returns:
            ``(best, nearest)``: the best posture within the step (None without
            ``approach`` or when no solution is that near) and the solution
            nearest ``q_prev`` (None when there is none at these entries).
        """
        fr = self.free
        assert fr is not None  # only redundant fingers have scalar rows
        t = (float(target[0]), float(target[1]), float(target[2]))
        app = (0.0, 0.0, 0.0) if approach is None else (float(x) for x in approach)
        ax_, ay_, az_ = app
        prev = [float(x) for x in q_prev]
        ia, i1, i2 = self.sub
        step = TRACK_MAX_STEP
        k0 = int(np.argmin(np.abs(self.table - prev[fr])))
        top = len(self.table) - 1
        best_score, best = -math.inf, None
        near_d, near = math.inf, None
        for d in TRACK_DELTAS:
            row = self._rows[min(max(k0 + d, 0), top)]
            lu, lw, inv_last, v = row[-4:]
            dv = v - prev[fr]
            for th0, q1, q2, turn, app_a, app_w in self._row_solutions(row, t, ax_, ay_, az_):
                d0, d1, d2 = th0 - prev[ia], q1 - prev[i1], q2 - prev[i2]
                dist = d0 * d0 + d1 * d1 + d2 * d2 + dv * dv
                sol = None
                if dist < near_d:
                    sol = [0.0] * self.m
                    sol[ia], sol[i1], sol[i2], sol[fr] = th0, q1, q2, v
                    near_d, near = dist, sol
                if approach is None or max(abs(d0), abs(d1), abs(d2), abs(dv)) > step:
                    continue
                ct, st = math.cos(turn), math.sin(turn)
                align = ((ct * lu - st * lw) * app_a + (st * lu + ct * lw) * app_w) * inv_last
                if align - dist > best_score:
                    if sol is None:
                        sol = [0.0] * self.m
                        sol[ia], sol[i1], sol[i2], sol[fr] = th0, q1, q2, v
                    best_score, best = align - dist, sol
        return self._clipped(best), self._clipped(near)

    def _clipped(self, q: list[float] | None) -> FloatArray | None:
        return None if q is None else np.clip(np.array(q), self.lo, self.hi)

    def _row_solutions(
        self,
        row: tuple[float, ...],
        target: tuple[float, float, float],
        ax_: float,
        ay_: float,
        az_: float,
    ) -> list[tuple[float, float, float, float, float, float]]:
        """The closed-form solutions within limits at one table entry, in scalar arithmetic.

        Args:
            row: the entry's constants (see :meth:`_scalar_rows`).
            target: fingertip-centre target, world frame.
            ax_: the approach direction's world x (0 without one).
            ay_: its world y.
            az_: its world z.

        Returns:
            Per solution ``(q_axis, q_flex1, q_flex2, turn, app_a, app_w)``:
            the three sub-chain joints, the last link's in-plane turn, and the
            approach direction's coordinates along the axis and the plane's
            in-plane direction.
        """
        (ox, oy, oz, ax, ay, az, bx, by, bz, nx, ny, nz, j1u, j1w, L1u, L1w, L2u, L2w,
         l1l2s, l12, dphi, s2, _, _, _, _) = row  # fmt: skip
        ia, i1, i2 = self.sub
        lo, hi = self._lo_list, self._hi_list
        pi, two_pi = math.pi, 2.0 * math.pi
        px, py, pz = target[0] - ox, target[1] - oy, target[2] - oz
        u = px * ax + py * ay + pz * az
        pb = px * bx + py * by + pz * bz
        pn = px * nx + py * ny + pz * nz
        rho = math.sqrt(pb * pb + pn * pn)
        app_a = ax_ * ax + ay_ * ay + az_ * az
        app_b = ax_ * bx + ay_ * by + az_ * bz
        app_n = ax_ * nx + ay_ * ny + az_ * nz
        du = u - j1u
        out = []
        for sgn in (1.0, -1.0):
            th0 = (math.atan2(sgn * pn, sgn * pb) + pi) % two_pi - pi
            if not (lo[ia] <= th0 <= hi[ia]):
                continue
            dw = sgn * rho - j1w
            c = (du * du + dw * dw - l1l2s) / l12
            if abs(c) > 1.0:
                continue
            acs = math.acos(c)
            base = math.atan2(dw, du)
            # the plane's in-plane normal direction w is cos th0 b + sin th0 n
            app_w = math.cos(th0) * app_b + math.sin(th0) * app_n
            for elbow in (1.0, -1.0):
                al2 = elbow * acs - dphi
                ca, sa = math.cos(al2), math.sin(al2)
                psi = base - math.atan2(L1w + sa * L2u + ca * L2w, L1u + ca * L2u - sa * L2w)
                q1 = (psi + pi) % two_pi - pi
                q2 = (s2 * al2 + pi) % two_pi - pi
                if lo[i1] <= q1 <= hi[i1] and lo[i2] <= q2 <= hi[i2]:
                    out.append((th0, q1, q2, psi + al2, app_a, app_w))
        return out

    def options_near(
        self, target: FloatArray, q_prev: FloatArray, approach: FloatArray
    ) -> FloatArray:
        """Every solution within :data:`TRACK_MAX_STEP` of ``q_prev``, best posture first.

        Args:
            target: (3,) fingertip-centre target, world frame.
            q_prev: (m,) previous joints.
            approach: (3,) unit inward surface normal, world frame.

        Returns:
            (C, m) solutions within limits, sorted by the alignment of the last
            link with ``approach`` minus the squared joint step (C may be 0).
        """
        g, v = self._table_near(q_prev)
        q, ok = self._candidates(np.asarray(target, dtype=float)[None], v, g)
        q, ok = q[0], ok[0]
        rows = np.flatnonzero(ok & np.all(np.abs(q - q_prev) <= TRACK_MAX_STEP, axis=1))
        if not len(rows):
            return np.zeros((0, self.m))
        score = self.alignment(q[rows], approach) - np.sum((q[rows] - q_prev) ** 2, axis=1)
        return q[rows[np.argsort(-score, kind="stable")]]

    def _best_posture(
        self, q: FloatArray, ok: np.ndarray, q_prev: FloatArray, approach: FloatArray
    ) -> FloatArray | None:
        """Among ``q: (C, m)`` (``ok``) within the step of ``q_prev``, the best aligned."""
        near = ok & np.all(np.abs(q - q_prev) <= TRACK_MAX_STEP, axis=1)
        rows = np.flatnonzero(near)
        if not len(rows):
            return None
        align = self.alignment(q[rows], approach)
        step = np.sum((q[rows] - q_prev) ** 2, axis=1)
        return q[rows[int(np.argmax(align - step))]]

    def alignment(self, q: FloatArray, approach: FloatArray) -> FloatArray:
        """Cosines ``(C,)`` of the last link of ``q: (C, m)`` with ``approach: (3,)`` or (C, 3)."""
        return np.einsum("ij,ij->i", self.directions(q)[0], np.broadcast_to(approach, (len(q), 3)))

    def directions(self, q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Last-link direction and flexion-plane normal of configurations ``q: (C, m)``.

        From the plane angles when every free-joint value lies on the table
        (solutions of this solver do): the last link turns in the flexion
        plane by ``q[f1] + s2 q[f2]`` and the plane turns about the axis
        joint by ``q[a]``; otherwise by forward kinematics.

        Returns:
            ``last: (C, 3)`` unit vectors from the last joint to the
            fingertip and ``normal: (C, 3)`` the first flexion axis, world frame.
        """
        q = np.asarray(q, dtype=float).reshape(-1, self.m)
        ia, i1, i2 = self.sub
        k = None
        if self.free is not None and self._rows:
            step = (self.table[-1] - self.table[0]) / (len(self.table) - 1)
            k = np.rint((q[:, self.free] - self.table[0]) / step).astype(np.int64)
            k = np.clip(k, 0, len(self.table) - 1)
            if np.any(np.abs(self.table[k] - q[:, self.free]) > 1e-12):
                k = None
        if k is None:
            tip, origins, axes = self.chain.forward(q)
            d = tip - origins[:, -1]
            return d / np.linalg.norm(d, axis=1, keepdims=True), axes[:, i1]
        g = self._table_geometry
        a, b, n = g["a"][k], g["b"][k], g["n"][k]
        th0 = q[:, ia, None]
        w = np.cos(th0) * b + np.sin(th0) * n  # the plane's in-plane direction after abduction
        turn = q[:, i1] + g["s2"][k] * q[:, i2]
        ct, st = np.cos(turn), np.sin(turn)
        lu, lw = g["last"][k, 0], g["last"][k, 1]
        last = (ct * lu - st * lw)[:, None] * a + (st * lu + ct * lw)[:, None] * w
        last /= np.hypot(lu, lw)[:, None]
        return last, np.cos(th0) * n - np.sin(th0) * b
