"""The force-closure quality ``Q`` and its solver (see :mod:`dexplan.model.grasp`).

The derivation, the bounds and the algorithm are in the package docstring and
docs/force_closure.md; the contact models' cones are in
:mod:`dexplan.model.grasp.cones`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Literal

import numpy as np
import osqp
import scipy.sparse as sp
from scipy.optimize import nnls

from dexplan.core.errors import InvalidInputError
from dexplan.core.typing import FloatArray, as_positive
from dexplan.model.grasp.cones import (
    ContactModel,
    _check_grasp,
    _ellipsoid_facets,
    _facets,
    _soft_facets,
    check_contact_model,
    min_contacts,
)

__all__ = [
    "DEFAULT",
    "DIRECTIONS",
    "MAX_INTERIOR_NORM",
    "RANK_TOL",
    "ForceClosure",
    "force_closure_quality",
    "is_force_closure",
    "min_subgrasp_quality",
]

#: The 12 signed unit axes ``+-e_i`` of the scaled wrench space, shape (12, 6).
DIRECTIONS: FloatArray = np.vstack([np.eye(6), -np.eye(6)])

#: ``G G^T`` whose smallest eigenvalue estimate is below this times its largest
#: diagonal entry is treated as rank deficient (not force closure).
RANK_TOL = 1e-10
#: A grasp whose best-centred internal force needs a norm above this (in units of
#: the unit-normalized facet margins) is reported as not force closure.
MAX_INTERIOR_NORM = 1e9

Solver = Literal["osqp", "nnls"]

# ---------------------------------------------------------------------------
# Per-contact data and per-subset analysis
# ---------------------------------------------------------------------------


_EYE_R = np.array([0, 1, 2])
_EYE_C = np.array([0, 1, 2])
# [p]_x rows 3..5: entries (row, col) = sign * p[index]
_SKEW_R = np.array([3, 3, 4, 4, 5, 5])
_SKEW_C = np.array([1, 2, 0, 2, 0, 1])
_SKEW_P = np.array([2, 1, 2, 0, 1, 0])
_SKEW_SIGN = np.array([-1.0, 1.0, 1.0, -1.0, -1.0, 1.0])


class _Contacts:
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
            self.rows = _facets(nrm, mu, edges) if rows is None else rows
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
        self.rows = _soft_facets(nrm, mu, edges, tau) if rows is None else rows
        self.g = g
        self.push = push


class _Subsets:
    """Least-distance data of several contact subsets of equal size ``m``.

    Shapes (S subsets, m contacts, r force coordinates per contact, R = m * rows,
    n = m r): ``bh`` (S, R, n) unit rows of ``B = A Pi``; ``ch`` (S, R, 6) rows of
    ``A G^+`` divided by the same norms; ``a`` (S, 6) norms ``|G^+ e_i|``; ``ok``
    (S,) rank 6; ``guess`` (S, n) the internal force nearest to every finger
    pushing along its normal (``Pi n``), a cheap interior candidate.
    """

    __slots__ = ("a", "bh", "ch", "guess", "ldp_buffers", "ok")

    def __init__(self, con: _Contacts, subsets: np.ndarray):
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

    def take(self, rows: np.ndarray) -> _Subsets:
        """The subsets ``rows`` of these (a new object sharing nothing mutable)."""
        out = _Subsets.__new__(_Subsets)
        out.ok, out.bh, out.ch = self.ok[rows], self.bh[rows], self.ch[rows]
        out.a, out.guess = self.a[rows], self.guess[rows]
        out.ldp_buffers = {}
        return out


def _public_nnls(e: FloatArray, f: FloatArray, maxiter: int) -> FloatArray:
    return nnls(e, f, maxiter=maxiter)[0]


def _fast_nnls_or_public() -> Callable[[FloatArray, FloatArray, int], FloatArray]:
    """Return the compiled Lawson-Hanson kernel of scipy (no input checks) if usable."""
    try:
        from scipy.optimize._slsqplib import nnls as kernel  # private: guarded

        x = kernel(np.eye(2), np.array([1.0, -1.0]), 6)[0]
        if np.allclose(x, [1.0, 0.0]):
            return lambda e, f, maxiter: kernel(e, f, maxiter)[0]
    except Exception:  # any failure: use the public function
        pass
    return _public_nnls


_NNLS = _fast_nnls_or_public()


def _ldp(bh: FloatArray, h: FloatArray) -> FloatArray | None:
    """Exact least-distance program ``min |z| s.t. bh z <= h`` (Lawson-Hanson ch. 23).

    The dual is the NNLS ``min |E u - f|, u >= 0`` with ``E = [-bh^T; -h^T]`` and
    ``f = e_last``; then ``z = -res[:n] / res[n]`` and ``res = 0`` means infeasible.

    Args:
        bh: (R, n) constraint rows.
        h: (R,) right-hand sides.

    Returns:
        (n,) minimizer, or None if the constraints are infeasible.
    """
    rows, n = bh.shape
    e = np.empty((n + 1, rows))
    e[:n] = bh.T
    e[n] = h
    e *= -1.0
    f = np.zeros(n + 1)
    f[n] = 1.0
    u = _NNLS(e, f, 50 * rows)
    res = e @ u
    res[n] -= 1.0
    if not res[n] < -1e-14:
        return None
    return res[:n] / -res[n]


def screen_groups(sub: _Subsets, k: int) -> tuple[FloatArray, np.ndarray]:
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
    failed = ~ok.reshape(-1, k).all(axis=1)
    for s in np.flatnonzero(ok & ~good):
        if failed[s // k]:
            continue
        z = _ldp(bh[s], h)
        # certificate: bh z < 0 strictly (rescaled so that bh z0 <= -1)
        worst = -float(np.max(bh[s] @ z)) if z is not None else 0.0
        if z is None or not z @ z < MAX_INTERIOR_NORM**2 or not worst > 0.5:  # NaN too
            ok[s] = False
            failed[s // k] = True
            continue
        z0[s] = z / worst
    return z0, ok


# ---------------------------------------------------------------------------
# OSQP pair solver
# ---------------------------------------------------------------------------


class _PairQP:
    """One OSQP problem ``min 1/2 |x|^2 s.t. bh x <= u`` for a fixed (R, n) shape.

    Set up once with a dense pattern for ``bh``; per solve only ``Ax`` (a
    refactorization, skipped when ``bh`` has not changed) and ``u`` are updated.
    """

    def __init__(self, rows: int, n: int, eps: float, max_iter: int):
        pattern = sp.csc_matrix(np.ones((rows, n)))
        self.prob = osqp.OSQP()
        self.prob.setup(
            sp.identity(n, format="csc"),
            np.zeros(n),
            pattern,
            np.full(rows, -1e30),
            np.ones(rows),
            verbose=False,
            eps_abs=eps,
            eps_rel=eps,
            eps_prim_inf=1e-9,
            eps_dual_inf=1e-9,
            max_iter=max_iter,
            polishing=True,
            polish_refine_iter=5,
            scaling=0,
            rho=1.0,
            adaptive_rho=True,
            check_termination=5,
            warm_starting=True,
        )
        self.current: tuple[int, int] | None = None  # key of the matrix loaded

    def solve(
        self, key: tuple[int, int], bh: FloatArray, u: FloatArray, x0: FloatArray, y0: FloatArray
    ) -> tuple[FloatArray, bool]:
        """Return ``(x, solved)``; ``key`` identifies ``bh`` to skip refactorizations."""
        if key != self.current:
            self.prob.update(Ax=np.ascontiguousarray(bh.T).ravel(), u=u)
            self.current = key
        else:
            self.prob.update(u=u)
        self.prob.warm_start(x=x0, y=y0)
        res = self.prob.solve(raise_error=False)
        solved = res.info.status_val == 1 and bool(np.all(np.isfinite(res.x)))
        return np.asarray(res.x, dtype=np.float64), solved


# ---------------------------------------------------------------------------
# Public solver object
# ---------------------------------------------------------------------------

#: Mixing weights of the feasible points ``theta z1 + c z0`` tried per pair.
_THETAS = np.linspace(0.0, 1.0, 5)[:, None, None, None]


class _PairBounds:
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

    def __init__(self, sub: _Subsets, z0: FloatArray):
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
        self.c = c = np.maximum((_THETAS * alpha - self.beta).max(axis=3), 0.0)  # (T, S, 12)
        z1z0 = np.einsum("sjn,sn->sj", self.z1, self.z0)
        t = _THETAS[..., 0]
        norm2 = t * t * self.lo2 + c * (2.0 * t * z1z0 + c * self.z0z0)
        self.best_t = np.argmin(norm2, axis=0)
        self.exact = c[-1] <= 0.0  # z1 itself is feasible
        self.hi2 = np.where(self.exact, self.lo2, np.maximum(norm2.min(axis=0), self.lo2))
        self.q_lo = 1.0 / np.sqrt(self.a2 + self.hi2)

    def feasible_point(self, s: int, j: int) -> FloatArray:
        """(n,) the best feasible point ``theta z1 + c z0`` of pair ``(s, j)``."""
        t = self.best_t[s, j]
        return float(_THETAS[t, 0, 0, 0]) * self.z1[s, j] + float(self.c[t, s, j]) * self.z0[s]


class _Grasp:
    """A checked grasp: the arrays and settings every public method starts from.

    ``pts``/``nrm`` (k, 3) object frame, ``mu``, ``edges``, ``scale`` (the torque
    length L, metres) and ``tau`` (``torsion / L``, None for point contacts).
    """

    __slots__ = ("edges", "k", "model", "mu", "nrm", "pts", "scale", "tau")

    def __init__(
        self,
        points: object,
        normals: object,
        mu: float,
        edges: int,
        torque_scale: float | None,
        contact_model: ContactModel,
        torsion: float,
    ):
        self.pts, self.nrm, self.mu, self.edges, self.scale = _check_grasp(
            points, normals, mu, edges, torque_scale
        )
        self.tau = _scaled_torsion(contact_model, torsion, self.scale)
        self.model = contact_model
        self.k = self.pts.shape[0]

    def too_few(self, subgrasps: bool) -> bool:
        """Whether the grasp (or its subgrasps) has fewer contacts than FC needs."""
        m = self.k - 1 if subgrasps else self.k
        return m < min_contacts(self.mu, self.model)

    def subsets(self, subgrasps: bool) -> np.ndarray:
        """(S, m) contact indices: the grasp itself, or its k (k-1)-subgrasps."""
        return _drop_one(self.k) if subgrasps else np.arange(self.k)[None, :]

    def contacts(
        self, mu: float | None = None, edges: int | None = None, rows: FloatArray | None = None
    ) -> _Contacts:
        """The per-contact blocks, with the grasp's own ``mu`` and ``edges`` by default."""
        return _Contacts(
            self.pts,
            self.nrm,
            self.mu if mu is None else mu,
            self.edges if edges is None else edges,
            self.scale,
            self.tau,
            rows,
        )


class ForceClosure:
    """Force-closure quality with cached OSQP problems (see the module docstring).

    Not thread-safe: the OSQP problems are mutated by every call. Use one instance per
    thread; the module-level functions are the bound methods of a shared default
    instance, :data:`DEFAULT`.

    Args:
        solver: ``"osqp"`` (default) solves the undecided (grasp, direction) pairs with
            OSQP, falling back to exact NNLS if OSQP does not report solved;
            ``"nnls"`` solves them exactly with Lawson-Hanson.
        eps: OSQP absolute and relative tolerance (on the normalized problem).
        max_iter: OSQP iteration cap per pair.
    """

    def __init__(self, *, solver: Solver = "osqp", eps: float = 1e-7, max_iter: int = 400):
        if solver not in ("osqp", "nnls"):
            raise InvalidInputError(f"solver must be 'osqp' or 'nnls', got {solver!r}")
        self.solver: Solver = solver
        self.eps = as_positive(eps, "eps")
        if isinstance(max_iter, bool) or not isinstance(max_iter, int) or max_iter < 1:
            raise InvalidInputError(f"max_iter must be a positive integer, got {max_iter!r}")
        self.max_iter = max_iter
        self._qps: dict[tuple[int, int], _PairQP] = {}
        self._calls = 0
        #: Counters (for benchmarks): quality evaluations, pairs sent to the pair
        #: solver, OSQP runs that fell back to NNLS.
        self.stats = {"evaluations": 0, "pairs_solved": 0, "osqp_fallbacks": 0}

    # -- public API (the module-level functions are DEFAULT's bound methods) --

    def quality(
        self,
        points: object,
        normals: object,
        mu: float,
        *,
        edges: int = 8,
        torque_scale: float | None = None,
        margin: float | None = None,
        solve: bool = True,
        contact_model: ContactModel = "point",
        torsion: float = 0.0,
    ) -> float:
        """Force-closure quality ``Q`` of a grasp; ``> 0`` iff force closure.

        ``Q = min_j 1 / phi(d_j)`` over the 12 signed unit axes of the scaled wrench
        space, ``phi(d)`` the least Euclidean norm of contact forces in the linearized
        cones producing the wrench ``d``; ``0.0`` if not force closure (never negative).
        Bounds (module docstring): ``eps <= Q <= sqrt(6 k (1 + mu^2)) eps`` for the
        Ferrari-Canny epsilon ``eps`` of the unit edge wrenches (L1 hull), and
        ``q <= Q <= sqrt(k (1 + mu^2)) q`` for the 12-direction LP quality ``q``. Soft
        contacts: ``|x_c|^2 = |f_c|^2 + (tau_c / L)^2`` and the lower bounds divide by
        ``sqrt(1 + (torsion / L)^2)``: ``q / sqrt(1 + t^2) <= Q``.

        Args:
            points: (k, 3) contact points, object frame, metres.
            normals: (k, 3) inward contact normals (into the object), object frame.
            mu: friction coefficient, >= 0 (0: frictionless, the cone is the normal).
            edges: pyramid edges per contact, >= 3.
            torque_scale: length dividing torques (metres), e.g. the object's
                characteristic length; default: the largest ``|points|`` (1 if 0).
            margin: decision threshold (validity checks). When given, the result ``r``
                satisfies ``r > margin`` iff ``Q > margin``; ``r`` is exact only when
                that needs it: otherwise a certified lower bound ``margin < r <= Q``
                or a certified upper bound ``Q <= r <= margin``.
            solve: with ``margin``, False never runs the pair solver: undecided grasps
                return their certified lower bound (a "no" may then be a false
                negative; for cheap conservative filtering of many candidates).
            contact_model: ``"point"`` (Coulomb cone, the paper) or ``"soft"`` (plus
                torsional friction about the normal; :mod:`dexplan.model.grasp.cones`).
            torsion: soft-finger torsion coefficient (m), ``|tau_n| <= torsion f_n``,
                in (0, ``MAX_TORSION``] for soft contacts, 0 for point contacts.

        Returns:
            The quality, in (scaled wrench) per (unit contact force).

        Raises:
            InvalidInputError: bad shapes, non-finite values, zero-length normal,
                ``mu < 0``, ``edges < 3``, ``torque_scale <= 0``, ``margin < 0``.
        """
        grasp = _Grasp(points, normals, mu, edges, torque_scale, contact_model, torsion)
        return self._quality(grasp, False, margin, solve)

    def min_subgrasp_quality(
        self,
        points: object,
        normals: object,
        mu: float,
        *,
        edges: int = 8,
        torque_scale: float | None = None,
        margin: float | None = None,
        solve: bool = True,
        contact_model: ContactModel = "point",
        torsion: float = 0.0,
    ) -> float:
        """Minimum quality over the full grasp and each of its (k-1)-contact subgrasps.

        Monotonicity makes the full grasp redundant: a subgrasp's feasible contact
        forces extended by a zero force at the missing contact are feasible for the
        full grasp (same ``torque_scale``), so every ``phi(d_j)`` of the full grasp is
        at most the subgrasp's, i.e. ``Q(full) >= Q(subgrasp)``; the minimum is over
        the k subgrasps only. A subgrasp that fails the exact screens returns 0.0 at
        once.

        The torque scale of every subgrasp is the full grasp's (default: the largest
        ``|points|`` over all k contacts), so this equals
        ``min(force_closure_quality(subgrasp, torque_scale=L) for each subgrasp)``.

        Args:
            points: (k, 3) contact points, object frame, metres.
            normals: (k, 3) inward contact normals, object frame.
            mu: friction coefficient, >= 0.
            edges: pyramid edges per contact, >= 3.
            torque_scale: torque length (metres); see :func:`force_closure_quality`.
            margin: decision threshold; see :func:`force_closure_quality`.
            solve: with ``margin``, False never runs the pair solver (as above).
            contact_model: ``"point"`` or ``"soft"``.
            torsion: soft-finger torsion coefficient (m); 0 for point contacts.

        Returns:
            The minimum quality (0.0 if some subgrasp is not force closure, or k < 4
            with friction, k < 8 without).

        Raises:
            InvalidInputError: as :func:`force_closure_quality`.
        """
        grasp = _Grasp(points, normals, mu, edges, torque_scale, contact_model, torsion)
        return self._quality(grasp, True, margin, solve)

    def is_force_closure(
        self,
        points: object,
        normals: object,
        mu: float,
        *,
        edges: int = 8,
        torque_scale: float | None = None,
        margin: float = 0.0,
        subgrasps: bool = False,
        contact_model: ContactModel = "point",
        torsion: float = 0.0,
    ) -> bool:
        """Whether the grasp's quality exceeds ``margin`` (exact screens only if 0).

        Args:
            points: (k, 3) contact points, object frame, metres.
            normals: (k, 3) inward contact normals, object frame.
            mu: friction coefficient, >= 0.
            edges: pyramid edges per contact, >= 3.
            torque_scale: torque length (metres); see :func:`force_closure_quality`.
            margin: threshold, >= 0.
            subgrasps: test every (k-1)-contact subgrasp instead of the full grasp (the
                DESIGN validity rule; with ``margin = 0`` the full grasp is then FC too).
            contact_model: ``"point"`` or ``"soft"``.
            torsion: soft-finger torsion coefficient (m); 0 for point contacts.

        Returns:
            ``Q > margin`` (``min_subgrasp_quality > margin`` with ``subgrasps``).
        """
        grasp = _Grasp(points, normals, mu, edges, torque_scale, contact_model, torsion)
        thr = as_positive(margin, "margin", allow_zero=True)
        if grasp.too_few(subgrasps):
            return False
        con, subsets = grasp.contacts(), grasp.subsets(subgrasps)
        if thr == 0.0:
            return self._screen(_Subsets(con, subsets)) is not None
        return self._min_quality(con, subsets, thr, True) > thr

    def exact_set_verdict(
        self,
        points: object,
        normals: object,
        mu: float,
        *,
        edges: int = 8,
        torque_scale: float | None = None,
        subgrasps: bool = False,
        contact_model: ContactModel = "point",
        torsion: float = 0.0,
    ) -> str:
        """Force closure under the exact sets: the round cone, the elliptic soft set.

        The exact sets are the round Coulomb cone (point contacts) and the elliptic
        soft-finger set (soft contacts); they are judged by inner and outer polytopes.

        Every linearization used here is either inscribed in the exact set (a "yes"
        for it is a "yes" for the exact set) or circumscribed about it (a "no" for it
        is a "no"): first the model's own ``edges`` linearization (the planner's),
        then a dense inscribed one (64-edge pyramid; the hull of a 48 x 12
        latitude-longitude grid on the ellipsoid), then the dense circumscribed one
        (64-edge pyramid of ``mu / cos(pi / 64)``; the grid hull scaled by
        ``1 / inradius``).

        Args:
            points: (k, 3) contact points, object frame, metres.
            normals: (k, 3) inward contact normals, object frame.
            mu: friction coefficient, >= 0.
            edges: the model's own pyramid edges, >= 3.
            torque_scale: torque length (metres); see :func:`force_closure_quality`.
            subgrasps: judge every (k-1)-contact subgrasp instead of the grasp.
            contact_model: ``"point"`` or ``"soft"``.
            torsion: soft-finger torsion coefficient (m); 0 for point contacts.

        Returns:
            ``"fc_linear"`` (force closure already for the ``edges`` linearization),
            ``"fc_dense"`` (force closure for the dense inscribed polytope),
            ``"undecided"`` (within the gap between the dense inner and outer
            polytopes: 0.12 % of ``mu`` for point contacts, 1.1 % of the set for soft
            ones) or ``"not_fc"`` (not force closure even for the outer polytope, or
            fewer contacts than :func:`~dexplan.model.grasp.cones.min_contacts`).

        Raises:
            InvalidInputError: as :func:`force_closure_quality`.
        """
        grasp = _Grasp(points, normals, mu, edges, torque_scale, contact_model, torsion)
        if grasp.too_few(subgrasps):
            return "not_fc"
        subsets = grasp.subsets(subgrasps)

        def sign(con: _Contacts) -> bool:
            return self._screen(_Subsets(con, subsets)) is not None

        if sign(grasp.contacts()):
            return "fc_linear"
        if grasp.mu == 0.0:  # both sets are exactly their linearizations
            return "not_fc"
        dense = MAX_FRICTION_EDGES_DENSE
        if grasp.tau is None:
            if sign(grasp.contacts(edges=dense)):
                return "fc_dense"
            outer = grasp.mu / math.cos(math.pi / dense)
            return "undecided" if sign(grasp.contacts(mu=outer, edges=dense)) else "not_fc"
        inner = _ellipsoid_facets(grasp.nrm, grasp.mu, grasp.tau, outer=False)
        if sign(grasp.contacts(rows=inner)):
            return "fc_dense"
        outer_rows = _ellipsoid_facets(grasp.nrm, grasp.mu, grasp.tau, outer=True)
        return "undecided" if sign(grasp.contacts(rows=outer_rows)) else "not_fc"

    # -- internals ----------------------------------------------------------

    def _quality(self, grasp: _Grasp, subgrasps: bool, margin: float | None, solve: bool) -> float:
        """The quality of the grasp (or the minimum over its subgrasps)."""
        thr = None if margin is None else as_positive(margin, "margin", allow_zero=True)
        if grasp.too_few(subgrasps):
            return 0.0
        return self._min_quality(grasp.contacts(), grasp.subsets(subgrasps), thr, solve)

    @staticmethod
    def _screen(sub: _Subsets) -> FloatArray | None:
        """Exact FC screen of every subset: interior points ``bh z0 <= -1``, or None.

        :func:`screen_groups` with all the subsets in one group: None as soon
        as one subset is not force closure.
        """
        z0, ok = screen_groups(sub, len(sub.ok))
        return z0 if ok.all() else None

    def _min_quality(
        self, con: _Contacts, subsets: np.ndarray, margin: float | None, solve: bool
    ) -> float:
        """Minimum quality over ``subsets``: screen, certified bounds, branch and bound.

        Args:
            con: the per-contact blocks.
            subsets: (S, m) contact indices of the subsets.
            margin: decision threshold (see :func:`force_closure_quality`), or None.
            solve: False stops at the certified lower bound (with ``margin``).

        Returns:
            The minimum quality, or a certified bound on the far side of ``margin``.
        """
        self._calls += 1
        self.stats["evaluations"] += 1
        sub = _Subsets(con, subsets)
        z0 = self._screen(sub)
        if z0 is None:
            return 0.0
        pairs = _PairBounds(sub, z0)
        if margin is not None:
            decided = pairs.first_decision(margin)
            if decided is not None:
                return decided
        pairs.refine()
        if margin is not None:
            worst_lo = float(pairs.q_lo.min())
            if worst_lo > margin or not solve:
                return worst_lo
        # Soft contacts: OSQP left every pair of 2-contact soft subgrasps unsolved
        # at max_iter (measured: 2.2 of 2.2 pairs, ~3 ms each, then the exact
        # fallback), so their pairs go to Lawson-Hanson directly.
        use_osqp = self.solver == "osqp" and con.r in (1, 3)
        return self._branch_and_bound(pairs, margin, use_osqp)

    def _branch_and_bound(self, pairs: _PairBounds, margin: float | None, use_osqp: bool) -> float:
        """Best-first branch and bound over the pairs.

        Pairs are solved in increasing lower bound until the lower bound reaches the
        best exact value (or, with ``margin``, until the decision is certain).
        """
        flat_lo = pairs.q_lo.ravel()
        order = np.argsort(flat_lo).tolist()
        bounds = flat_lo.tolist()
        exact_l = pairs.exact.ravel().tolist()
        best = math.inf
        for idx in order:
            bound = bounds[idx]
            if bound >= best:
                break
            if margin is not None and bound > margin:
                return min(best, bound)  # every remaining pair is above the margin
            if exact_l[idx]:
                val = bound
            else:
                s, j = divmod(idx, 12)
                val = self._solve_pair(pairs, s, j, use_osqp)
            best = min(best, val)
            if margin is not None and best <= margin:
                return best
        return best

    def _solve_pair(self, pairs: _PairBounds, s: int, j: int, use_osqp: bool) -> float:
        """The quality of pair ``(s, j)``, clamped to its certified bounds.

        Solved by OSQP when ``use_osqp`` (falling back to Lawson-Hanson), else exactly
        by Lawson-Hanson.
        """
        lo_sj = float(pairs.lo[s, j])
        hi_sj = math.sqrt(pairs.hi2[s, j])
        b = pairs.b[s, j]
        z = (
            self._solve_osqp(pairs.sub, s, b, pairs.feasible_point(s, j), lo_sj)
            if use_osqp
            else None
        )
        if z is None:
            z = _ldp_norm(pairs.sub, s, b)
        z = hi_sj if z is None else min(max(z, lo_sj), hi_sj)
        self.stats["pairs_solved"] += 1
        return 1.0 / math.sqrt(float(pairs.a2[s, j]) + z * z)

    def _solve_osqp(
        self, sub: _Subsets, s: int, b: FloatArray, zf: FloatArray, lo: float
    ) -> float | None:
        """``min |z| s.t. bh_s z <= b`` by OSQP; None if OSQP does not solve it."""
        bh = sub.bh[s]
        rows, n = bh.shape
        qp = self._qps.get((rows, n))
        if qp is None:
            qp = self._qps[(rows, n)] = _PairQP(rows, n, self.eps, self.max_iter)
        scale = lo if lo > 0.0 else 1.0
        y0 = np.zeros(rows)
        y0[int(np.argmin(b))] = 1.0
        x, solved = qp.solve((self._calls, s), bh, b / scale, zf / scale, y0)
        if solved:
            z = x * scale
            if np.max(bh @ z - b) <= 1e-7 * max(1.0, lo):
                return math.sqrt(float(z @ z))
        self.stats["osqp_fallbacks"] += 1
        return None


def _ldp_norm(sub: _Subsets, s: int, b: FloatArray) -> float | None:
    """``min |z| s.t. bh_s z <= b`` exactly (Lawson-Hanson), or None if infeasible.

    The NNLS matrix ``E = [-bh_s^T; -b^T]`` is kept per subset: only its last row
    changes between the 12 directions.
    """
    e = sub.ldp_buffers.get(s)
    if e is None:
        bh = sub.bh[s]
        e = sub.ldp_buffers[s] = np.empty((bh.shape[1] + 1, bh.shape[0]))
        e[:-1] = -bh.T
    e[-1] = -b
    u = _NNLS(e, _unit_last(e.shape[0]), 50 * e.shape[1])
    res = e @ u
    last = res[-1] - 1.0
    if not last < -1e-14:
        return None
    top = res[:-1]
    return math.sqrt(float(top @ top)) / -last


_UNIT_LAST: dict[int, FloatArray] = {}


def _unit_last(size: int) -> FloatArray:
    out = _UNIT_LAST.get(size)
    if out is None:
        out = _UNIT_LAST[size] = np.zeros(size)
        out[-1] = 1.0
    return out


_DROP_ONE: dict[int, np.ndarray] = {}


def _drop_one(k: int) -> np.ndarray:
    """(k, k-1) indices of the subsets that leave out one contact each."""
    out = _DROP_ONE.get(k)
    if out is None:
        idx = np.arange(k)
        out = _DROP_ONE[k] = np.array([np.delete(idx, s) for s in range(k)], dtype=np.intp)
    return out


def _scaled_torsion(contact_model: object, torsion: object, scale: float) -> float | None:
    """None for point contacts; ``torsion / L`` for soft ones (validated)."""
    if contact_model == "point" and torsion == 0.0 and not isinstance(torsion, bool):
        return None  # the point path: no further work
    t = check_contact_model(contact_model, torsion)
    return None if t is None else t / scale


#: Edges of the dense pyramids that judge point contacts against the round cone.
MAX_FRICTION_EDGES_DENSE = 64


#: The instance behind the module-level functions (e.g. ``DEFAULT.solver = "nnls"``).
DEFAULT = ForceClosure()


#: The module-level functions: :data:`DEFAULT`'s bound methods (one signature and
#: docstring each, on :class:`ForceClosure`).
force_closure_quality = DEFAULT.quality
min_subgrasp_quality = DEFAULT.min_subgrasp_quality
is_force_closure = DEFAULT.is_force_closure
exact_force_closure = DEFAULT.exact_set_verdict


#: Outcomes of :func:`exact_force_closure`.
VERDICTS: tuple[str, ...] = ("fc_linear", "fc_dense", "undecided", "not_fc")
