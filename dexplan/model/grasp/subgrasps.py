"""Subgrasps: per-contact blocks, per-subset least-distance data, the exact screen, pair bounds.

The force-closure quality of a grasp (or the minimum over its (k-1)-contact
subgrasps) is computed on *subsets* of its contacts; the derivation, the
bounds and their proofs are in the package docstring (:mod:`dexplan.model.grasp`).
Here: :class:`Contacts` (``G_c`` and the cone facet rows of every contact),
:class:`Subsets` (``B = A Pi`` and ``A G^+`` of equal-size subsets, vectorised),
:func:`screen_groups` (the exact force-closure sign) and :class:`PairBounds`
(certified bounds on every (subset, direction) pair's quality).
"""

from __future__ import annotations

from typing import cast

import numpy as np

from dexplan.core.errors import InvalidInputError
from dexplan.core.typing import FloatArray
from dexplan.model.grasp.cones import check_contact_model, pyramid_facets, soft_pyramid_facets
from dexplan.model.grasp.least_distance import ldp, ldp_norm

__all__ = [
    "MAX_INTERIOR_NORM",
    "RANK_TOL",
    "THETAS",
    "Contacts",
    "PairBounds",
    "Subsets",
    "drop_one",
    "scaled_torsion",
    "screen_groups",
]

#: ``G G^T`` whose smallest eigenvalue estimate is below this times its largest
#: diagonal entry is treated as rank deficient (not force closure).
RANK_TOL = 1e-10
#: A grasp whose best-centred internal force needs a norm above this (in units of
#: the unit-normalized facet margins) is reported as not force closure.
MAX_INTERIOR_NORM = 1e9

_EYE_R = np.array([0, 1, 2])
_EYE_C = np.array([0, 1, 2])
# [p]_x rows 3..5: entries (row, col) = sign * p[index]
_SKEW_R = np.array([3, 3, 4, 4, 5, 5])
_SKEW_C = np.array([1, 2, 0, 2, 0, 1])
_SKEW_P = np.array([2, 1, 2, 0, 1, 0])
_SKEW_SIGN = np.array([-1.0, 1.0, 1.0, -1.0, -1.0, 1.0])


class Contacts:
    """Per-contact blocks: ``G_c`` (6 x r) and facet rows ``A_c`` (rows x r).

    Point contacts (``tau is None``): ``r = 3`` (force vector) when ``mu > 0``;
    ``r = 1`` (normal force, one row ``-a <= 0``) when ``mu = 0``. Soft contacts
    (``tau = torsion / L``): ``r = 4``, ``x_c = (f_c, sigma_c)`` with ``G_c = [I, 0;
    [p_c]_x / L, n_c]`` when ``mu > 0``; ``r = 2``, ``(f_n, sigma)`` when ``mu = 0``.
    ``rows`` overrides the facet rows (same ``r``), e.g. a dense elliptic polytope.
    """

    __slots__ = ("g", "push", "r", "rows")

    def __init__(
        self,
        pts: FloatArray,
        nrm: FloatArray,
        mu: float,
        edges: int,
        scale: float,
        tau: float | None = None,
        rows: FloatArray | None = None,
    ):
        k = pts.shape[0]
        if tau is not None:
            self._soft(pts, nrm, mu, edges, scale, tau, rows)
            return
        if mu > 0.0:
            self.r = 3
            g = np.zeros((k, 6, 3))
            g[:, _EYE_R, _EYE_C] = 1.0
            g[:, _SKEW_R, _SKEW_C] = pts[:, _SKEW_P] * (_SKEW_SIGN / scale)
            self.rows = pyramid_facets(nrm, mu, edges) if rows is None else rows
            self.push = nrm
        else:
            self.r = 1
            g = np.empty((k, 6, 1))
            g[:, :3, 0] = nrm
            g[:, 3:, 0] = np.cross(pts, nrm) / scale
            self.rows = -np.ones((k, 1, 1))
            self.push = np.ones((k, 1))
        self.g = g

    def _soft(
        self,
        pts: FloatArray,
        nrm: FloatArray,
        mu: float,
        edges: int,
        scale: float,
        tau: float,
        rows: FloatArray | None,
    ) -> None:
        k = pts.shape[0]
        if mu > 0.0:
            self.r = 4
            g = np.zeros((k, 6, 4))
            g[:, _EYE_R, _EYE_C] = 1.0
            g[:, _SKEW_R, _SKEW_C] = pts[:, _SKEW_P] * (_SKEW_SIGN / scale)
            g[:, 3:, 3] = nrm
            push = np.zeros((k, 4))
            push[:, :3] = nrm
        else:
            self.r = 2
            g = np.zeros((k, 6, 2))
            g[:, :3, 0] = nrm
            g[:, 3:, 0] = np.cross(pts, nrm) / scale
            g[:, 3:, 1] = nrm
            push = np.zeros((k, 2))
            push[:, 0] = 1.0
        self.rows = soft_pyramid_facets(nrm, mu, edges, tau) if rows is None else rows
        self.g = g
        self.push = push


class Subsets:
    """Least-distance data of several contact subsets of equal size ``m``.

    Shapes (S subsets, m contacts, r force coordinates per contact, R = m * rows,
    n = m r): ``bh`` (S, R, n) unit rows of ``B = A Pi``; ``ch`` (S, R, 6) rows of
    ``A G^+`` divided by the same norms; ``a`` (S, 6) norms ``|G^+ e_i|``; ``ok``
    (S,) rank 6; ``guess`` (S, n) the internal force nearest to every finger
    pushing along its normal (``Pi n``), a cheap interior candidate.
    """

    __slots__ = ("a", "bh", "ch", "guess", "ldp_buffers", "ok")

    def __init__(self, con: Contacts, subsets: np.ndarray):
        s_count, m = subsets.shape
        r = con.r
        n = m * r
        g = con.g[subsets].transpose(0, 2, 1, 3).reshape(s_count, 6, n)
        gt = g.transpose(0, 2, 1)
        ggt = g @ gt
        self.ok = np.ones(s_count, dtype=bool)
        try:
            inv = np.linalg.inv(ggt)
        except np.linalg.LinAlgError:
            inv = np.tile(np.eye(6), (s_count, 1, 1))
            for i in range(s_count):
                try:
                    inv[i] = np.linalg.inv(ggt[i])
                except np.linalg.LinAlgError:
                    self.ok[i] = False
        # lambda_min(G G^T) >= 1 / |inv|_F; trace(G G^T) >= lambda_max
        frob2 = np.einsum("sij,sij->s", inv, inv)
        trace = np.einsum("sii->s", ggt)
        self.ok &= frob2 * (RANK_TOL * trace) ** 2 < 1.0
        gp = gt @ inv  # (S, n, 6)
        proj = -(gp @ g)  # Pi = I - G^+ G
        proj.reshape(s_count, n * n)[:, :: n + 1] += 1.0
        rows = con.rows[subsets]  # (S, m, q, r)
        q = rows.shape[2]
        b = (rows @ proj.reshape(s_count, m, r, n)).reshape(s_count, m * q, n)
        c = (rows @ gp.reshape(s_count, m, r, 6)).reshape(s_count, m * q, 6)
        nb = np.sqrt(np.einsum("sqn,sqn->sq", b, b))[:, :, None]
        nb[nb == 0.0] = 1.0
        self.bh = b / nb
        self.ch = c / nb
        self.a = np.sqrt(np.einsum("snj,snj->sj", gp, gp))
        self.guess = (proj @ con.push[subsets].reshape(s_count, n, 1))[:, :, 0]
        self.ldp_buffers: dict[int, FloatArray] = {}

    def take(self, rows: np.ndarray) -> Subsets:
        """The subsets ``rows`` of these (a new object sharing nothing mutable)."""
        out = Subsets.__new__(Subsets)
        out.ok, out.bh, out.ch = self.ok[rows], self.bh[rows], self.ch[rows]
        out.a, out.guess = self.a[rows], self.guess[rows]
        out.ldp_buffers = {}
        return out

    def ldp_norm(self, s: int, b: FloatArray) -> float | None:
        """``min |z| s.t. bh_s z <= b`` exactly (Lawson-Hanson), or None if infeasible.

        The NNLS matrix ``E = [-bh_s^T; -b^T]`` is kept per subset: only its last
        row changes between the 12 directions.
        """
        e = self.ldp_buffers.get(s)
        if e is None:
            bh = self.bh[s]
            e = self.ldp_buffers[s] = np.empty((bh.shape[1] + 1, bh.shape[0]))
            e[:-1] = -bh.T
        return ldp_norm(e, b)


def screen_groups(sub: Subsets, k: int) -> tuple[FloatArray, np.ndarray]:
    """Exact FC screen of the subsets, in consecutive groups of ``k`` (one grasp each).

    The cheap candidate ``Pi n`` (every finger pushing along its normal, made
    internal) settles most force-closure subsets; the others get the exact
    least-distance program ``min |z| s.t. bh z <= -1`` (Lawson-Hanson), which is
    infeasible iff the subset is not force closure. Once a subset of a group
    fails (or is rank deficient), the group's other subsets are not examined.

    Returns:
        Interior points ``z0: (S, n)`` (``bh z0 <= -1``) and ``ok: (S,)``, False
        where the subset failed; a failed group's other entries are meaningless.
    """
    bh, guess = sub.bh, sub.guess
    ok = sub.ok.copy()
    margin = -(bh @ guess[:, :, None]).max(axis=1)  # (S, 1)
    good = margin[:, 0] > 1e-6 * np.sqrt(np.einsum("sn,sn->s", guess, guess))
    z0 = guess / np.where(good[:, None], margin, 1.0)
    if good.all():
        return z0, ok
    h = -np.ones(bh.shape[1])
    failed = cast(np.ndarray, ~ok.reshape(-1, k).all(axis=1))
    for s in np.flatnonzero(ok & ~good):
        if failed[s // k]:
            continue
        z = ldp(bh[s], h)
        # certificate: bh z < 0 strictly (rescaled so that bh z0 <= -1)
        worst = -float(np.max(bh[s] @ z)) if z is not None else 0.0
        if z is None or not z @ z < MAX_INTERIOR_NORM**2 or not worst > 0.5:  # NaN too
            ok[s] = False
            failed[s // k] = True
            continue
        z0[s] = z / worst
    return z0, ok


#: Mixing weights of the feasible points ``theta z1 + c z0`` tried per pair.
THETAS = np.linspace(0.0, 1.0, 5)[:, None, None, None]


class PairBounds:
    """Certified bounds on ``|z*|`` for every (subset, direction) pair of a screen.

    A pair is ``min |z| s.t. bh_s z <= b_sj`` with ``b(d_j) = -A G^+ d_j``; its
    quality is ``1 / sqrt(|G^+ d_j|^2 + |z*|^2)``. Shapes (S subsets, 12 directions,
    R facet rows, n force coordinates): ``b`` (S, 12, R); ``a2`` (S, 12) the
    ``|G^+ d_j|^2``; ``lo`` (S, 12) the exact lower bound of the relaxation to the
    most violated halfspace, ``q_hi`` the quality bound it gives. :meth:`refine`
    adds the feasible points ``theta z1 + c z0``: ``hi2`` (S, 12) the upper bound
    of ``|z*|^2``, ``q_lo`` the quality bound it gives, ``exact`` where ``z1``
    itself is feasible.
    """

    __slots__ = (
        "a2", "b", "best_t", "beta", "c", "exact", "hi2", "inv_slack", "lo", "lo2",
        "q_hi", "q_lo", "sub", "z0", "z0z0", "z1",
    )  # fmt: skip

    def __init__(self, sub: Subsets, z0: FloatArray):
        self.sub = sub
        self.z0 = z0
        # b(d_j) = -A G^+ d_j with unit rows: (S, 12, R)
        self.b = b = np.concatenate([-sub.ch, sub.ch], axis=2).transpose(0, 2, 1)
        a2h = sub.a * sub.a
        self.a2 = np.concatenate([a2h, a2h], axis=1)  # |G^+ d_j|^2, (S, 12)
        # Relaxation to the most violated halfspace: exact lower bound lo <= |z*|.
        self.lo = np.maximum(-b.min(axis=2), 0.0)  # (S, 12)
        self.lo2 = self.lo * self.lo
        self.q_hi = 1.0 / np.sqrt(self.a2 + self.lo2)  # each pair's quality is in [q_lo, q_hi]
        self.inv_slack = 1.0 / -(sub.bh @ z0[:, :, None])[:, None, :, 0]  # (S, 1, R)
        self.beta = b * self.inv_slack
        self.z0z0 = np.einsum("sn,sn->s", z0, z0)[:, None]

    def first_lower(self) -> FloatArray:
        """(S, 12) certified lower bounds on each pair's quality from ``c z0`` alone."""
        c0 = np.maximum(-self.beta.min(axis=2), 0.0)
        return 1.0 / np.sqrt(self.a2 + c0 * c0 * self.z0z0)

    def first_decision(self, margin: float) -> float | None:
        """The validity fast path: ``theta = 0`` alone (``c z0``) often decides.

        Returns:
            A certified bound on the other side of ``margin`` from the quality's
            (lower bound above it, or upper bound at most it), or None.
        """
        worst_lo = float(self.first_lower().min())
        if worst_lo > margin:
            return worst_lo
        worst_hi = float(self.q_hi.min())
        if worst_hi <= margin:
            return worst_hi
        return None

    def refine(self) -> None:
        """Upper bounds from the feasible points ``theta z1 + c z0``.

        ``bh z0 <= -1`` and ``z1`` is the relaxed optimum: the smallest feasible ``c``
        for each ``theta`` of a small grid, then the best ``theta``. Sets ``z1``,
        ``c``, ``best_t``, ``exact``, ``hi2`` and ``q_lo``.
        """
        bh, b, lo = self.sub.bh, self.b, self.lo
        s_count = b.shape[0]
        i1 = np.argmin(b, axis=2)
        self.z1 = bh[np.arange(s_count)[:, None], i1] * -lo[:, :, None]  # (S, 12, n)
        alpha = (self.z1 @ bh.transpose(0, 2, 1)) * self.inv_slack  # (S, 12, R)
        self.c = c = np.maximum((THETAS * alpha - self.beta).max(axis=3), 0.0)  # (T, S, 12)
        z1z0 = np.einsum("sjn,sn->sj", self.z1, self.z0)
        t = THETAS[..., 0]
        norm2 = t * t * self.lo2 + c * (2.0 * t * z1z0 + c * self.z0z0)
        self.best_t = np.argmin(norm2, axis=0)
        self.exact = c[-1] <= 0.0  # z1 itself is feasible
        self.hi2 = np.where(self.exact, self.lo2, np.maximum(norm2.min(axis=0), self.lo2))
        self.q_lo = 1.0 / np.sqrt(self.a2 + self.hi2)

    def feasible_point(self, s: int, j: int) -> FloatArray:
        """(n,) the best feasible point ``theta z1 + c z0`` of pair ``(s, j)``."""
        t = self.best_t[s, j]
        return float(THETAS[t, 0, 0, 0]) * self.z1[s, j] + float(self.c[t, s, j]) * self.z0[s]


_DROP_ONE: dict[int, np.ndarray] = {}


def drop_one(k: int) -> np.ndarray:
    """(k, k-1) indices of the subsets that leave out one contact each."""
    out = _DROP_ONE.get(k)
    if out is None:
        idx = np.arange(k)
        out = _DROP_ONE[k] = np.array([np.delete(idx, s) for s in range(k)], dtype=np.intp)
    return out


def batch_subsets(n_grasps: int, k: int, subgrasps: bool) -> tuple[np.ndarray, int]:
    """The subsets of ``n_grasps`` stacked grasps of ``k`` contacts each.

    Grasp ``b``'s contacts are rows ``k b .. k b + k - 1`` of the stacked
    contacts; its subsets are those of one grasp (every (k-1)-subset with
    ``subgrasps``, else the whole grasp) offset by ``k b``.

    Returns:
        ``(subsets (n_grasps S, m), S)``: the index rows, grasp by grasp, and
        the number ``S`` of subsets per grasp.
    """
    one = drop_one(k) if subgrasps else np.arange(k)[None, :]
    subsets = (one[None] + k * np.arange(n_grasps)[:, None, None]).reshape(-1, one.shape[1])
    return subsets, len(one)


def stacked_grasps(points: object, normals: object) -> tuple[FloatArray, FloatArray]:
    """``points`` and ``normals`` as float arrays of one shape (B, k, 3), checked.

    Raises:
        InvalidInputError: other shapes.
    """
    pts_b = np.asarray(points, dtype=float)
    nrm_b = np.asarray(normals, dtype=float)
    if pts_b.ndim != 3 or pts_b.shape[2] != 3 or pts_b.shape != nrm_b.shape:
        raise InvalidInputError(
            "points and normals must both have shape (B, k, 3), got "
            f"{pts_b.shape} and {nrm_b.shape}"
        )
    return pts_b, nrm_b


def scaled_torsion(contact_model: object, torsion: object, scale: float) -> float | None:
    """None for point contacts; ``torsion / L`` for soft ones (validated)."""
    if contact_model == "point" and torsion == 0.0 and not isinstance(torsion, bool):
        return None  # the point path: no further work
    t = check_contact_model(contact_model, torsion)
    return None if t is None else t / scale
