"""Friction cones, contact wrenches and a force-closure quality with provable bounds.

Everything here is expressed in the **object frame**: contact points ``p_c`` (metres)
and *inward* unit normals ``n_c`` (pointing into the object), one row per contact.

Friction model
--------------
Point contact with Coulomb friction ``mu``, the cone linearized by ``E = edges`` unit
edge directions ``u_ce = cos(a) n_c + sin(a) (cos(t_e) t1_c + sin(t_e) t2_c)`` with
``tan(a) = mu`` and ``t_e = 2 pi e / E``. The tangent basis ``(t1_c, t2_c)`` is a
deterministic function of ``n_c`` alone (Duff et al. 2017, "Building an orthonormal
basis, revisited"), never of the world frame, so a grasp expressed in the object
frame gives the same pyramid wherever the object is in the world (MEASURED.md: a
world-aligned basis flipped the verdict of 1% of rotated grasps).

The edge wrenches are ``w_ce = [u_ce, (p_c x u_ce) / L]`` with the torque scale ``L``
(the object's characteristic length; by default the largest ``|p_c|``, or 1 if all
points are at the origin). ``W`` is the ``(k E, 6)`` matrix of these rows.

Quality
-------
Let ``G = [G_1 ... G_k]`` with ``G_c = [I_3; [p_c]_x / L]`` (6 x 3) map the stacked
contact forces ``f = (f_1, ..., f_k)`` to the scaled wrench ``G f``, and ``K_c`` be the
pyramid spanned by the edges of contact ``c``. For a wrench ``d`` define the minimum
Euclidean force needed to produce it::

    phi(d) = min { |f|_2 : G f = d, f_c in K_c for every c }   (+inf if infeasible)

and, over the 12 signed unit axes ``d_j = +-e_i`` of the scaled wrench space::

    Q = min_j 1 / phi(d_j)          (0 when some phi(d_j) is infinite).

``Q > 0`` iff the grasp is force closure (FC) with the linearized cones.

Bounds relative to Ferrari-Canny. Let ``H = conv({0} U {w_ce})``,
``eps = max{r : B(0, r) in H}`` the (L1, ``sum lambda <= 1``) Ferrari-Canny epsilon
of the unit edge wrenches, ``gamma(d) = min{sum lambda : W^T lambda = d, lambda >= 0}``
the gauge of ``H``, and ``q = min_j 1 / gamma(d_j)`` the 12-direction LP quality of
DESIGN.md. With ``k`` contacts::

    eps <= q <= Q <= sqrt(k (1 + mu^2)) q <= sqrt(6 k (1 + mu^2)) eps.

Proof. (i) ``eps <= q <= sqrt(6) eps``: ``B(0, eps)`` in ``H`` gives ``eps d_j`` in ``H``,
so ``1/gamma(d_j) >= eps``; conversely ``H`` is convex and contains ``q d_j`` for all
12 ``j``, hence the cross-polytope of radius ``q``, hence the ball of radius
``q / sqrt(6)``. (ii) Every edge has ``n_c . u_ce = cos(a)``, so any representation
``f_c = sum_e lambda_ce u_ce`` has ``sum_e lambda_ce = n_c . f_c / cos(a)``: ``gamma(d) =
min{sum_c n_c . f_c / cos(a) : G f = d, f_c in K_c}``. The pyramid lies inside the
circular cone of half-angle ``a``, so ``cos(a) |f_c| <= n_c . f_c <= |f_c|`` on it. For
any feasible ``f``: ``|f|_2 <= sum_c |f_c| <= sum_c n_c . f_c / cos(a)``, so
``phi <= gamma``; and ``|f|_2 >= sum_c |f_c| / sqrt(k) >= sum_c n_c . f_c / sqrt(k)
>= cos(a) gamma / sqrt(k)``, so ``phi >= gamma / sqrt(k (1 + mu^2))``. Taking ``1/.``
and the minimum over ``j`` gives ``q <= Q <= sqrt(k (1 + mu^2)) q``. (iii) Adding a
contact adds variables (its force may be zero), so every ``phi(d_j)`` can only
decrease: ``Q`` is monotone under adding contacts (with ``L`` fixed).

Computation
-----------
If ``G`` has full rank 6, ``f = G^+ d + f_int`` with ``f_int`` in the null space of ``G``
(internal forces) and ``G^+ d`` orthogonal to it, so ``phi(d)^2 = |G^+ d|^2 + |z*|^2``
with ``z* = argmin{|z| : B z <= b(d)}``, ``B = A Pi`` (``A`` the block-diagonal outward
facet normals of the pyramids, ``Pi = I - G^+ G`` the projector onto the internal
forces, rows scaled to unit length) and ``b(d) = -A G^+ d``: a least-distance program,
strongly convex (``P = I``), one per (grasp, direction) "pair". The optimum lies in the
range of ``Pi``, so no null-space basis is needed. Per call:

1. Screens, exact sign. Fewer than 3 contacts (7 if ``mu = 0``) or ``rank G < 6``:
   0. Else FC iff some internal force is strictly inside every pyramid, i.e. iff
   ``B z < 0`` has a solution. The candidate ``Pi n`` (every finger pushing along its
   normal, made internal) settles most FC grasps; otherwise the least-distance
   program ``min |z| s.t. B z <= -1``, solved exactly by Lawson-Hanson NNLS, is
   feasible iff the grasp is FC. Either way ``z0`` with ``B z0 <= -1`` is kept.
2. Certified bounds for every pair, vectorized over the subgrasps and the 12
   directions: the relaxation to the most violated halfspace gives ``|z*| >= lo``
   (exact when one constraint is active); the points ``theta z1 + c z0``
   (``z1`` the relaxed optimum, ``theta`` on a 5-point grid, ``c`` the smallest
   feasible) are feasible and give ``|z*| <= hi``. With ``margin``, ``theta = 0``
   alone is tried first; most validity decisions end here.
3. Best-first branch and bound over the pairs: the pair with the smallest certified
   lower bound on its quality is solved, until that bound reaches the best solved
   value (typically 1-4 of the 48 pairs of a 4-contact ``min_subgrasp_quality``).
   ``solver="osqp"`` (default): one cached OSQP problem per ``(rows, n)`` shape, i.e.
   per (contact count, edges), ``P = I``, ``A = B`` with a dense pattern; per pair only
   ``Ax`` (skipped when the subgrasp has not changed) and ``u`` are updated, warm start
   from the feasible point, polish on, ``max_iter = 400``. A pair OSQP leaves
   unsolved (ADMM needs a median of ~170 iterations here and thousands near
   degenerate active sets) is solved exactly by Lawson-Hanson. ``solver="nnls"``
   solves every pair exactly by Lawson-Hanson (the least-distance dual is an NNLS),
   about 3x faster than the OSQP path here. Results are clamped to the certified bounds.

Accuracy: the sign never depends on OSQP or on a tolerance other than the screens'
(``RANK_TOL``, ``MAX_INTERIOR_NORM``); values are exact to ~1e-9 (NNLS, or OSQP with
successful polish) or to OSQP's ``eps`` (1e-7 relative) otherwise.

Measured speed and the comparison with a qhull reference: docs/force_closure.md and
``python scripts/bench_grasp.py``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Literal

import numpy as np
import osqp
import scipy.sparse as sp
from scipy.optimize import nnls

from dexplan.exceptions import InvalidInputError
from dexplan.typing import FloatArray, as_points, as_positive

__all__ = [
    "ForceClosure",
    "contact_wrenches",
    "force_closure_quality",
    "friction_cone_edges",
    "friction_cone_facets",
    "is_force_closure",
    "min_subgrasp_quality",
    "tangent_basis",
]

#: Allowed number of edges of a linearized friction cone (``friction_edges`` in
#: scenarios and plan files): fewer than 3 spans no cone, more than 64 only
#: costs time (the round cone is approximated within 0.12%).
MIN_FRICTION_EDGES = 3
MAX_FRICTION_EDGES = 64

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
# Validation
# ---------------------------------------------------------------------------


def _check_mu(mu: object) -> float:
    return as_positive(mu, "mu", allow_zero=True)


def _check_edges(edges: object) -> int:
    if isinstance(edges, bool) or not isinstance(edges, int | np.integer):
        raise InvalidInputError(f"edges must be an integer >= 3, got {edges!r}")
    if edges < 3:
        raise InvalidInputError(f"edges must be an integer >= 3, got {edges!r}")
    return int(edges)


def _check_normals(normals: object, name: str = "normals") -> FloatArray:
    arr = as_points(normals, name)
    n2 = np.einsum("ij,ij->i", arr, arr)
    if n2.size and not n2.min() >= 1e-24:
        row = int(np.argmin(n2))
        raise InvalidInputError(
            f"{name} must have non-zero length, got row {row} = {arr[row].tolist()}"
        )
    return arr / np.sqrt(n2)[:, None]


def _check_grasp(
    points: object, normals: object, mu: object, edges: object, torque_scale: object
) -> tuple[FloatArray, FloatArray, float, int, float]:
    pts = as_points(points, "points")
    if pts.shape[0] == 0:
        raise InvalidInputError("points must hold at least one contact, got shape (0, 3)")
    nrm = _check_normals(normals, "normals")
    if pts.shape != nrm.shape:
        raise InvalidInputError(
            f"points and normals must have the same shape, got {pts.shape} and {nrm.shape}"
        )
    mu_f = _check_mu(mu)
    e = _check_edges(edges)
    if torque_scale is None:
        scale = math.sqrt(float(np.einsum("ij,ij->i", pts, pts).max()))
        scale = scale if scale > 0.0 else 1.0
    else:
        scale = as_positive(torque_scale, "torque_scale")
    return pts, nrm, mu_f, e, scale


# ---------------------------------------------------------------------------
# Cones and wrenches
# ---------------------------------------------------------------------------


def tangent_basis(normals: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Orthonormal tangent vectors built from each unit normal alone.

    Duff et al. (2017) branchless basis: ``(t1, t2, n)`` is right-handed and depends
    only on ``n`` (never on a world axis), so the same object-frame normal always gets
    the same pyramid.

    Args:
        normals: (k, 3) unit normals, any frame.

    Returns:
        ``(t1, t2)``, each (k, 3), in the frame of ``normals``.
    """
    t = _tangents(np.asarray(normals, dtype=np.float64))
    return t[:, 0], t[:, 1]


def _tangents(n: FloatArray) -> FloatArray:
    """(k, 2, 3) rows ``t1, t2`` of :func:`tangent_basis` for unit normals (k, 3)."""
    x, y, z = n[:, 0], n[:, 1], n[:, 2]
    s = np.where(z >= 0.0, 1.0, -1.0)
    a = -1.0 / (s + z)
    b = x * y * a
    t = np.empty((n.shape[0], 2, 3))
    t[:, 0, 0] = 1.0 + s * x * x * a
    t[:, 0, 1] = s * b
    t[:, 0, 2] = -s * x
    t[:, 1, 0] = b
    t[:, 1, 1] = s + y * y * a
    t[:, 1, 2] = -y
    return t


_CIRCLES: dict[tuple[int, float], FloatArray] = {}


def _circle(edges: int, offset: float) -> FloatArray:
    """(edges, 2) rows ``(cos, sin)`` of the angles ``2 pi (e + offset) / edges``."""
    key = (edges, offset)
    out = _CIRCLES.get(key)
    if out is None:
        ang = 2.0 * np.pi * (np.arange(edges) + offset) / edges
        out = _CIRCLES[key] = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    return out


def friction_cone_edges(normals_in: object, mu: float, edges: int = 8) -> FloatArray:
    """Unit edge directions of the linearized friction cones.

    Edge ``e`` of contact ``c`` is ``cos(a) n_c + sin(a) (cos(t_e) t1_c + sin(t_e) t2_c)``
    with ``tan(a) = mu``, ``t_e = 2 pi e / edges`` and ``(t1_c, t2_c)`` from
    :func:`tangent_basis` (a function of ``n_c`` only). With ``mu = 0`` every edge is
    the normal.

    Args:
        normals_in: (k, 3) inward contact normals (into the object), object frame; they
            are normalized.
        mu: Coulomb friction coefficient, >= 0.
        edges: number of pyramid edges, >= 3.

    Returns:
        (k, edges, 3) unit edge directions, object frame.

    Raises:
        InvalidInputError: bad shape, non-finite or zero-length normal, ``mu < 0``,
            ``edges < 3``.
    """
    n = _check_normals(normals_in, "normals_in")
    mu_f = _check_mu(mu)
    e = _check_edges(edges)
    return _edges(n, mu_f, e)


def _edges(n: FloatArray, mu: float, edges: int) -> FloatArray:
    ca = 1.0 / math.sqrt(1.0 + mu * mu)
    radial = _circle(edges, 0.0) @ _tangents(n)  # (k, edges, 3)
    return ca * n[:, None, :] + (mu * ca) * radial


def friction_cone_facets(normals_in: object, mu: float, edges: int = 8) -> FloatArray:
    """Outward unit normals of the pyramid facets (H-representation of the cones).

    Facet ``e`` joins edges ``e`` and ``e + 1``; a force ``f`` is in the pyramid of
    contact ``c`` iff ``a_ce . f <= 0`` for every ``e``. For ``mu > 0`` this is
    ``a_ce = (m_ce - beta n_c) / sqrt(1 + beta^2)`` with ``m_ce`` the unit tangent at
    angle ``t_e + pi / edges`` and ``beta = mu cos(pi / edges)``. (With ``mu = 0`` these
    rows only force the tangential part to zero; the quality code then uses the
    normal force itself as the variable.)

    Args:
        normals_in: (k, 3) inward contact normals, object frame.
        mu: friction coefficient, >= 0.
        edges: number of pyramid edges, >= 3.

    Returns:
        (k, edges, 3) outward facet normals, object frame.
    """
    n = _check_normals(normals_in, "normals_in")
    mu_f = _check_mu(mu)
    e = _check_edges(edges)
    return _facets(n, mu_f, e)


def _facets(n: FloatArray, mu: float, edges: int) -> FloatArray:
    beta = mu * math.cos(math.pi / edges)
    inv = 1.0 / math.sqrt(1.0 + beta * beta)
    radial = _circle(edges, 0.5) @ _tangents(n)  # (k, edges, 3)
    return inv * radial - (beta * inv) * n[:, None, :]


def contact_wrenches(
    points: object,
    normals_in: object,
    mu: float,
    edges: int = 8,
    torque_scale: float | None = None,
) -> FloatArray:
    """Wrenches of the unit edge forces, torques divided by ``torque_scale``.

    Row ``c * edges + e`` is ``[u_ce, (p_c x u_ce) / torque_scale]``.

    Args:
        points: (k, 3) contact points, object frame, metres.
        normals_in: (k, 3) inward contact normals, object frame.
        mu: friction coefficient, >= 0.
        edges: pyramid edges per contact, >= 3.
        torque_scale: length ``L`` dividing the torques (metres); callers pass the
            object's characteristic length. Default: the largest distance of the
            points from the object-frame origin, or 1 if all points are at the origin.

    Returns:
        (k * edges, 6) wrenches ``[force, torque / L]`` in the object frame.

    Raises:
        InvalidInputError: bad shapes, non-finite values, zero-length normal,
            ``mu < 0``, ``edges < 3`` or ``torque_scale <= 0``.
    """
    pts, nrm, mu_f, e, scale = _check_grasp(points, normals_in, mu, edges, torque_scale)
    u = _edges(nrm, mu_f, e)
    torque = np.cross(pts[:, None, :], u) / scale
    return np.concatenate([u, torque], axis=2).reshape(-1, 6)


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

    ``r = 3`` (force vector) when ``mu > 0``; ``r = 1`` (normal force, one row
    ``-a <= 0``) when ``mu = 0``.
    """

    __slots__ = ("g", "push", "r", "rows")

    def __init__(self, pts: FloatArray, nrm: FloatArray, mu: float, edges: int, scale: float):
        k = pts.shape[0]
        if mu > 0.0:
            self.r = 3
            g = np.zeros((k, 6, 3))
            g[:, _EYE_R, _EYE_C] = 1.0
            g[:, _SKEW_R, _SKEW_C] = pts[:, _SKEW_P] * (_SKEW_SIGN / scale)
            self.rows = _facets(nrm, mu, edges)
            self.push = nrm
        else:
            self.r = 1
            g = np.empty((k, 6, 1))
            g[:, :3, 0] = nrm
            g[:, 3:, 0] = np.cross(pts, nrm) / scale
            self.rows = -np.ones((k, 1, 1))
            self.push = np.ones((k, 1))
        self.g = g


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


class ForceClosure:
    """Force-closure quality with cached OSQP problems (see the module docstring).

    Not thread-safe: the OSQP problems are mutated by every call. Use one instance per
    thread; the module-level functions share a default instance.

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

    # -- public API ---------------------------------------------------------

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
    ) -> float:
        """Quality ``Q`` of the grasp (see :func:`force_closure_quality`)."""
        pts, nrm, mu_f, e, scale = _check_grasp(points, normals, mu, edges, torque_scale)
        thr = None if margin is None else as_positive(margin, "margin", allow_zero=True)
        k = pts.shape[0]
        if k < _min_contacts(mu_f):
            return 0.0
        con = _Contacts(pts, nrm, mu_f, e, scale)
        return self._min_quality(con, np.arange(k)[None, :], thr, solve)

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
    ) -> float:
        """Minimum quality over the grasp and its (k-1)-contact subgrasps.

        See :func:`min_subgrasp_quality`.
        """
        pts, nrm, mu_f, e, scale = _check_grasp(points, normals, mu, edges, torque_scale)
        thr = None if margin is None else as_positive(margin, "margin", allow_zero=True)
        k = pts.shape[0]
        if k - 1 < _min_contacts(mu_f):
            return 0.0
        con = _Contacts(pts, nrm, mu_f, e, scale)
        return self._min_quality(con, _drop_one(k), thr, solve)

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
    ) -> bool:
        """Whether ``Q > margin`` (of the grasp, or of every (k-1) subgrasp).

        See :func:`is_force_closure`.
        """
        pts, nrm, mu_f, e, scale = _check_grasp(points, normals, mu, edges, torque_scale)
        thr = as_positive(margin, "margin", allow_zero=True)
        k = pts.shape[0]
        m = k - 1 if subgrasps else k
        if m < _min_contacts(mu_f):
            return False
        con = _Contacts(pts, nrm, mu_f, e, scale)
        subsets = _drop_one(k) if subgrasps else np.arange(k)[None, :]
        if thr == 0.0:
            return self._screen(_Subsets(con, subsets)) is not None
        return self._min_quality(con, subsets, thr, True) > thr

    # -- internals ----------------------------------------------------------

    @staticmethod
    def _screen(sub: _Subsets) -> FloatArray | None:
        """Exact FC screen of every subset: interior points ``bh z0 <= -1``, or None.

        The cheap candidate ``Pi n`` (every finger pushing along its normal, made
        internal) settles most force-closure subsets; the others get the exact
        least-distance program ``min |z| s.t. bh z <= -1`` (Lawson-Hanson), which is
        infeasible iff the subset is not force closure.
        """
        if not sub.ok.all():
            return None
        bh = sub.bh
        guess = sub.guess
        margin = -(bh @ guess[:, :, None]).max(axis=1)  # (S, 1)
        good = margin[:, 0] > 1e-6 * np.sqrt(np.einsum("sn,sn->s", guess, guess))
        z0 = guess / np.where(good[:, None], margin, 1.0)
        if good.all():
            return z0
        h = -np.ones(bh.shape[1])
        for s in np.flatnonzero(~good):
            z = _ldp(bh[s], h)
            if z is None or not z @ z < MAX_INTERIOR_NORM**2:  # also catches NaN
                return None
            # certificate: bh z < 0 strictly (rescaled so that bh z0 <= -1)
            worst = -float(np.max(bh[s] @ z))
            if not worst > 0.5:
                return None
            z0[s] = z / worst
        return z0

    def _min_quality(
        self, con: _Contacts, subsets: np.ndarray, margin: float | None, solve: bool
    ) -> float:
        self._calls += 1
        self.stats["evaluations"] += 1
        sub = _Subsets(con, subsets)
        z0 = self._screen(sub)
        if z0 is None:
            return 0.0
        bh = sub.bh
        # b(d_j) = -A G^+ d_j with unit rows: (S, 12, R)
        b = np.concatenate([-sub.ch, sub.ch], axis=2).transpose(0, 2, 1)
        a2h = sub.a * sub.a
        a2 = np.concatenate([a2h, a2h], axis=1)  # |G^+ d_j|^2, (S, 12)
        # Relaxation to the most violated halfspace: exact lower bound lo <= |z*|.
        lo = np.maximum(-b.min(axis=2), 0.0)  # (S, 12)
        lo2 = lo * lo
        q_hi = 1.0 / np.sqrt(a2 + lo2)  # each pair's quality is in [q_lo, q_hi]
        # Feasible points theta z1 + c z0 (bh z0 <= -1, z1 the relaxed optimum): the
        # smallest c for each theta of a small grid, then the best theta: hi >= |z*|.
        inv_slack = 1.0 / -(bh @ z0[:, :, None])[:, None, :, 0]  # (S, 1, R)
        beta = b * inv_slack
        z0z0 = np.einsum("sn,sn->s", z0, z0)[:, None]
        if margin is not None:
            # validity fast path: theta = 0 alone (c z0) often settles the decision
            c0 = np.maximum(-beta.min(axis=2), 0.0)
            worst_lo = float((1.0 / np.sqrt(a2 + c0 * c0 * z0z0)).min())
            if worst_lo > margin:
                return worst_lo
            worst_hi = float(q_hi.min())
            if worst_hi <= margin:
                return worst_hi
        s_count = b.shape[0]
        i1 = np.argmin(b, axis=2)
        z1 = bh[np.arange(s_count)[:, None], i1] * -lo[:, :, None]  # (S, 12, n)
        alpha = (z1 @ bh.transpose(0, 2, 1)) * inv_slack  # (S, 12, R)
        c = np.maximum((_THETAS * alpha - beta).max(axis=3), 0.0)  # (T, S, 12)
        z1z0 = np.einsum("sjn,sn->sj", z1, z0)
        t = _THETAS[..., 0]
        norm2 = t * t * lo2 + c * (2.0 * t * z1z0 + c * z0z0)
        best_t = np.argmin(norm2, axis=0)
        exact = c[-1] <= 0.0  # z1 itself is feasible
        hi2 = np.where(exact, lo2, np.maximum(norm2.min(axis=0), lo2))
        q_lo = 1.0 / np.sqrt(a2 + hi2)
        if margin is not None:
            worst_lo = float(q_lo.min())
            if worst_lo > margin or not solve:
                return worst_lo
        # Best-first branch and bound: solve pairs in increasing lower bound until
        # the lower bound reaches the best exact value.
        flat_lo = q_lo.ravel()
        order = np.argsort(flat_lo).tolist()
        bounds = flat_lo.tolist()
        exact_l = exact.ravel().tolist()
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
                lo_sj = float(lo[s, j])
                hi_sj = math.sqrt(hi2[s, j])
                if self.solver == "osqp":
                    tj = float(_THETAS[best_t[s, j], 0, 0, 0])
                    zf = tj * z1[s, j] + float(c[best_t[s, j], s, j]) * z0[s]
                    z = self._solve_osqp(sub, s, b[s, j], zf, lo_sj)
                else:
                    z = None
                if z is None:
                    z = _ldp_norm(sub, s, b[s, j])
                z = hi_sj if z is None else min(max(z, lo_sj), hi_sj)
                self.stats["pairs_solved"] += 1
                val = 1.0 / math.sqrt(float(a2[s, j]) + z * z)
            best = min(best, val)
            if margin is not None and best <= margin:
                return best
        return best

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


def _min_contacts(mu: float) -> int:
    """Fewest contacts that can be FC: 3 with friction, 7 frictionless (6D span)."""
    return 3 if mu > 0.0 else 7


#: The instance behind the module-level functions (e.g. ``DEFAULT.solver = "nnls"``).
DEFAULT = ForceClosure()


def force_closure_quality(
    points: object,
    normals: object,
    mu: float,
    *,
    edges: int = 8,
    torque_scale: float | None = None,
    margin: float | None = None,
    solve: bool = True,
) -> float:
    """Force-closure quality ``Q`` of a grasp; ``> 0`` iff force closure.

    ``Q = min_j 1 / phi(d_j)`` over the 12 signed unit axes of the scaled wrench
    space, ``phi(d)`` the least Euclidean norm of contact forces in the linearized
    cones producing the wrench ``d``; ``0.0`` if not force closure (never negative).
    Bounds (module docstring): ``eps <= Q <= sqrt(6 k (1 + mu^2)) eps`` for the
    Ferrari-Canny epsilon ``eps`` of the unit edge wrenches (L1 hull), and
    ``q <= Q <= sqrt(k (1 + mu^2)) q`` for the 12-direction LP quality ``q``.

    Args:
        points: (k, 3) contact points, object frame, metres.
        normals: (k, 3) inward contact normals (into the object), object frame.
        mu: friction coefficient, >= 0 (0: frictionless, the cone is the normal).
        edges: pyramid edges per contact, >= 3.
        torque_scale: length dividing torques (metres), e.g. the object's
            characteristic length; default: the largest ``|points|`` (1 if 0).
        margin: decision threshold (validity checks). When given, the result ``r``
            satisfies ``r > margin`` iff ``Q > margin``; ``r`` is exact only when that
            needs it: otherwise a certified lower bound ``margin < r <= Q`` or a
            certified upper bound ``Q <= r <= margin``.
        solve: with ``margin``, False never runs the pair solver: undecided grasps
            return their certified lower bound (a "no" may then be a false negative;
            for cheap conservative filtering of many candidates).

    Returns:
        The quality, in (scaled wrench) per (unit contact force).

    Raises:
        InvalidInputError: bad shapes, non-finite values, zero-length normal,
            ``mu < 0``, ``edges < 3``, ``torque_scale <= 0``, ``margin < 0``.
    """
    return DEFAULT.quality(
        points, normals, mu, edges=edges, torque_scale=torque_scale, margin=margin, solve=solve
    )


def min_subgrasp_quality(
    points: object,
    normals: object,
    mu: float,
    *,
    edges: int = 8,
    torque_scale: float | None = None,
    margin: float | None = None,
    solve: bool = True,
) -> float:
    """Minimum quality over the full grasp and each of its (k-1)-contact subgrasps.

    Monotonicity makes the full grasp redundant: a subgrasp's feasible contact forces
    extended by a zero force at the missing contact are feasible for the full grasp
    (same ``torque_scale``), so every ``phi(d_j)`` of the full grasp is at most the
    subgrasp's, i.e. ``Q(full) >= Q(subgrasp)``; the minimum is over the k subgrasps
    only. A subgrasp that fails the exact screens returns 0.0 at once.

    The torque scale of every subgrasp is the full grasp's (default: the largest
    ``|points|`` over all k contacts), so this equals
    ``min(force_closure_quality(subgrasp, torque_scale=L) for each subgrasp)``.

    Args:
        points: (k, 3) contact points, object frame, metres.
        normals: (k, 3) inward contact normals, object frame.
        mu: friction coefficient, >= 0.
        edges: pyramid edges per contact, >= 3.
        torque_scale: torque length (metres); see :func:`force_closure_quality`.
        margin: decision threshold (validity checks). When given, the result ``r``
            satisfies ``r > margin`` iff ``Q > margin``; ``r`` is exact only when that
            needs it: otherwise a certified lower bound ``margin < r <= Q`` or a
            certified upper bound ``Q <= r <= margin``.
        solve: with ``margin``, False never runs the pair solver: undecided grasps
            return their certified lower bound (a "no" may then be a false negative;
            for cheap conservative filtering of many candidates).

    Returns:
        The minimum quality (0.0 if some subgrasp is not force closure, or k < 4 with
        friction, k < 8 without).

    Raises:
        InvalidInputError: as :func:`force_closure_quality`, or ``margin < 0``.
    """
    return DEFAULT.min_subgrasp_quality(
        points, normals, mu, edges=edges, torque_scale=torque_scale, margin=margin, solve=solve
    )


def is_force_closure(
    points: object,
    normals: object,
    mu: float,
    *,
    edges: int = 8,
    torque_scale: float | None = None,
    margin: float = 0.0,
    subgrasps: bool = False,
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

    Returns:
        ``Q > margin`` (``min_subgrasp_quality > margin`` with ``subgrasps``).
    """
    return DEFAULT.is_force_closure(
        points,
        normals,
        mu,
        edges=edges,
        torque_scale=torque_scale,
        margin=margin,
        subgrasps=subgrasps,
    )
