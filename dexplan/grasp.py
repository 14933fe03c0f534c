"""Force closure of point contacts with Coulomb friction, quality by OSQP.

Wrenches. Each contact i (point ``p_i`` and inward unit normal ``n_i`` in the
object frame) has a linearized friction cone of ``edges`` unit force
directions ``f_ik = (n_i + mu t_ik) / sqrt(1 + mu^2)``, with ``t_ik`` unit
tangents spaced evenly around ``n_i`` (the tangent basis is built from the
normal alone, so it turns with the grasp). Edge wrenches are
``w_ik = [f_ik, p_i x f_ik / L]`` with the torque scale ``L`` (the object's
characteristic length). ``W: (6, m)`` stacks them, ``m = k * edges``.

Metric. For the 12 signed axes ``d_j`` of wrench space let
``t_j = max{t : t d_j = W lam, lam >= 0, sum(lam) <= 1}`` and ``q = min_j t_j``;
then ``q / sqrt(6) <= eps <= q`` where ``eps`` is the Ferrari-Canny (L1)
epsilon, the radius of the largest origin-centred ball inside ``conv{w_ik}``
(the ball of radius eps contains the points eps d_j, so t_j >= eps; the
cross-polytope with vertices t_j d_j lies in the hull and contains the ball of
radius q / sqrt(6)).

LPs converge badly in OSQP, so the quality solved is the strongly convex QP

    s_j = min |lam|_2  s.t.  W lam = d_j,  lam >= 0,      Q = min_j 1 / s_j

(``Q = 0`` when some ``d_j`` is outside the cone of the edge wrenches, i.e. the
grasp is not force closure). Since ``|lam|_2 <= |lam|_1 <= sqrt(m) |lam|_2``
and ``1 / t_j = min{|lam|_1 : W lam = d_j, lam >= 0}``:

    q <= Q <= sqrt(m) q,   hence   Q / sqrt(6 m) <= eps <= Q.

Speed. Most calls come from validity checks asking "is every subgrasp's
quality above a margin?". Cheap screens decide most of them without OSQP:

1. rank: ``rank W < 6`` is never force closure;
2. a strictly positive null combination: force closure iff ``rank W = 6`` and
   some ``lam > 0`` has ``W lam = 0``; ``lam0 = 1 + mu``, ``mu`` from one
   non-negative least squares solve (exact sign);
3. a certified lower bound: for each ``d_j``, ``lam = W^+ d_j + a lam0`` with
   the smallest ``a`` making it non-negative is feasible, so
   ``1 / |lam|_2 <= 1 / s_j``; when the bound already clears the margin the
   answer is certain.

Only the remaining (near-margin) grasps are solved by OSQP, one problem set up
per wrench count and updated in place (``Ax``, ``l``, ``u``), warm-started
across the 12 directions.

Accuracy. The sign (force closure or not) comes from the exact screens (rank
and non-negative least squares), never from OSQP. The value is OSQP's, to its
tolerance (1e-6); ADMM can need thousands of iterations on grasps near the
boundary, and an axis still unsolved after 24000 keeps the best certified
lower bound instead (still > 0, still a lower bound of ``Q``). With
``margin``, the iteration cap is 400 and an unsolved axis gives a "no".
"""

from __future__ import annotations

import math

import numpy as np
import osqp
import scipy.sparse as sp
from scipy.optimize import nnls

from dexplan.exceptions import InvalidInputError
from dexplan.typing import FloatArray, as_points

#: Relative rank tolerance of the wrench matrix.
RANK_TOL = 1e-9
#: OSQP iteration cap when only a margin decision is asked for.
MARGIN_MAX_ITER = 400
#: OSQP iteration cap of an exact quality (raised five-fold once if needed).
EXACT_MAX_ITER = 4000
_AXES = np.concatenate([np.eye(6), -np.eye(6)], axis=1)  # (6, 12) signed axes


def _check(points: object, normals: object, mu: object, edges: object):
    p = as_points(points, "points")
    n = as_points(normals, "normals")
    if p.shape != n.shape:
        raise InvalidInputError(
            f"points and normals must have the same shape, got {p.shape} and {n.shape}"
        )
    try:
        mu_f = float(mu)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"mu must be a number, got {mu!r}") from exc
    if not math.isfinite(mu_f) or mu_f < 0:
        raise InvalidInputError(f"mu must be finite and >= 0, got {mu!r}")
    if isinstance(edges, bool) or not isinstance(edges, int | np.integer) or edges < 3:
        raise InvalidInputError(f"edges must be an integer >= 3, got {edges!r}")
    norms = np.linalg.norm(n, axis=1)
    if np.any(norms < 1e-12):
        raise InvalidInputError(f"normals must be non-zero, got {n.tolist()}")
    return p, n / norms[:, None], mu_f, int(edges)


def friction_cone_edges(normals_in: FloatArray, mu: float, edges: int = 8) -> FloatArray:
    """Unit edge directions of the linearized friction cones.

    Args:
        normals_in: (k, 3) inward unit contact normals, object frame.
        mu: friction coefficient (>= 0).
        edges: edges per cone (>= 3).

    Returns:
        (k, edges, 3) unit force directions, object frame. The tangent basis is
        a function of the normal only.
    """
    _, n, mu, edges = _check(
        np.zeros_like(np.asarray(normals_in, dtype=float)), normals_in, mu, edges
    )
    return _cone_edges(n, mu, edges)


_UNIT_CIRCLE: dict[int, tuple[FloatArray, FloatArray]] = {}


def _cone_edges(n: FloatArray, mu: float, edges: int) -> FloatArray:
    """:func:`friction_cone_edges` for checked unit normals ``n: (k, 3)``."""
    if edges not in _UNIT_CIRCLE:
        ang = 2.0 * np.pi * np.arange(edges) / edges
        _UNIT_CIRCLE[edges] = (np.cos(ang)[None, :, None], np.sin(ang)[None, :, None])
    cos, sin = _UNIT_CIRCLE[edges]
    # tangent basis from the normal alone (Duff et al.'s branchless basis)
    sign = np.where(n[:, 2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    t1 = np.stack([1.0 + sign * n[:, 0] ** 2 * a, sign * b, -sign * n[:, 0]], axis=1)
    t2 = np.stack([b, sign + n[:, 1] ** 2 * a, -n[:, 1]], axis=1)
    tang = cos * t1[:, None, :] + sin * t2[:, None, :]
    return (n[:, None, :] + mu * tang) / math.sqrt(1.0 + mu * mu)


def contact_wrenches(
    points: FloatArray,
    normals_in: FloatArray,
    mu: float,
    edges: int = 8,
    torque_scale: float | None = None,
) -> FloatArray:
    """Edge wrenches ``(k * edges, 6)``: ``[f, p x f / torque_scale]``.

    ``torque_scale`` defaults to the largest distance of a contact from the
    object-frame origin (1 if all contacts are at the origin).
    """
    p, n, mu, edges = _check(points, normals_in, mu, edges)
    return _wrenches(p, n, mu, edges, _torque_scale(p, torque_scale))


def _wrenches(p: FloatArray, n: FloatArray, mu: float, edges: int, ts: float) -> FloatArray:
    """:func:`contact_wrenches` for checked inputs (no validation: inner loops)."""
    f = _cone_edges(n, mu, edges)  # (k, e, 3)
    w = np.empty((*f.shape[:2], 6))
    w[..., :3] = f
    px, py, pz = (p[:, i, None] for i in range(3))
    w[..., 3] = (py * f[..., 2] - pz * f[..., 1]) / ts
    w[..., 4] = (pz * f[..., 0] - px * f[..., 2]) / ts
    w[..., 5] = (px * f[..., 1] - py * f[..., 0]) / ts
    return w.reshape(-1, 6)


def _torque_scale(p: FloatArray, torque_scale: float | None) -> float:
    if torque_scale is None:
        r = float(np.max(np.linalg.norm(p, axis=1))) if len(p) else 0.0
        return r if r > 0 else 1.0
    ts = float(torque_scale)
    if not math.isfinite(ts) or ts <= 0:
        raise InvalidInputError(f"torque_scale must be finite and > 0, got {torque_scale!r}")
    return ts


class _QpCache:
    """One OSQP problem per wrench count ``m``, updated in place."""

    def __init__(self) -> None:
        self._by_m: dict[int, osqp.OSQP] = {}

    def solve_min_norms(self, W: FloatArray, max_iter: int = 4000) -> FloatArray:
        """``s_j = min |lam|_2 s.t. W lam = d_j, lam >= 0`` for the 12 axes.

        Returns ``inf`` for an infeasible axis and ``nan`` for one not solved
        within ``max_iter`` iterations.
        """
        m = W.shape[1]
        prob = self._by_m.get(m)
        # A = [W; I] with a fixed sparsity pattern (every W entry stored, even a
        # zero), so later grasps only update the values
        data = np.concatenate([W, np.ones((1, m))], axis=0).T.ravel()  # column-major
        lo = np.zeros(6 + m)
        u = np.concatenate([np.zeros(6), np.full(m, np.inf)])
        if prob is None:
            rows = np.concatenate(
                [np.tile(np.arange(6), (m, 1)), 6 + np.arange(m)[:, None]], axis=1
            ).ravel()
            A = sp.csc_matrix((data, rows, np.arange(0, 7 * m + 1, 7)), shape=(6 + m, m))
            prob = osqp.OSQP()
            prob.setup(
                sp.eye(m, format="csc"),  # P = I: strongly convex
                np.zeros(m),
                A,
                lo,
                u,
                verbose=False,
                eps_abs=1e-6,
                eps_rel=1e-6,
                max_iter=4000,
                polishing=True,
                warm_starting=True,
                adaptive_rho=True,
            )
            self._by_m[m] = prob
        else:
            prob.update(Ax=data)
        prob.update_settings(max_iter=max_iter)
        out = np.empty(12)
        for j in range(12):
            d = _AXES[:, j]
            lo[:6] = d
            u[:6] = d
            prob.update(l=lo, u=u)
            res = prob.solve(raise_error=False)
            status = res.info.status
            if "infeasible" in status:
                out[j] = np.inf
            elif status not in ("solved", "solved inaccurate"):
                out[j] = np.nan
            else:
                out[j] = float(np.linalg.norm(np.maximum(res.x, 0.0)))
        return out


_CACHE = _QpCache()


def _positive_null(W: FloatArray) -> FloatArray | None:
    """``lam > 0`` with ``W lam = 0`` (``lam >= 1``), or None when there is none."""
    ones = np.ones(W.shape[1])
    mu_, res = nnls(W, -W @ ones)
    if res > 1e-9 * max(1.0, float(np.linalg.norm(W @ ones))):
        return None
    return ones + mu_


def _lower_bound(pinv: FloatArray, lam0: FloatArray) -> float:
    """Certified lower bound of ``Q`` from feasible points (see the module notes).

    Args:
        pinv: (m, 6) pseudo-inverse of ``W``.
        lam0: (m,) strictly positive null combination of the wrenches.
    """
    lp = pinv @ _AXES  # (m, 12) minimum-norm solutions of W lam = d_j, maybe negative
    alpha = np.max(np.maximum(-lp / lam0[:, None], 0.0), axis=0)  # (12,)
    lam = lp + alpha[None, :] * lam0[:, None]
    return float(1.0 / np.sqrt(np.max(np.einsum("ij,ij->j", lam, lam))))


def _quality(W: FloatArray, margin: float | None, solve: bool = True) -> float:
    U, S, Vt = np.linalg.svd(W, full_matrices=False)
    if S[-1] <= RANK_TOL * max(1.0, S[0]):
        return 0.0
    lam0 = _positive_null(W)
    if lam0 is None:
        return 0.0
    lb = _lower_bound((Vt.T / S) @ U.T, lam0)
    if margin is None:
        # exact: ADMM needs thousands of iterations near the boundary, so a
        # direction left unsolved gets a second, five times longer run
        s = _CACHE.solve_min_norms(W, max_iter=EXACT_MAX_ITER)
        if np.any(np.isnan(s)):
            s = _CACHE.solve_min_norms(W, max_iter=5 * EXACT_MAX_ITER)
        if not np.all(np.isfinite(s)):
            # the screens proved force closure (every axis is in the cone), so
            # an axis OSQP left unsolved keeps its certified bound
            return max(lb, _nnls_lower_bound(W))
        return float(1.0 / np.max(s))
    if lb > margin:
        return lb
    # a second certificate: per axis, the better of two feasible points
    lb = max(lb, _nnls_lower_bound(W))
    if lb > margin or not solve:
        return lb
    # near the margin: solve, with an iteration cap; an axis the cap leaves
    # unsolved keeps the certified bound (<= margin): the decision is "no"
    s = _CACHE.solve_min_norms(W, max_iter=MARGIN_MAX_ITER)
    if not np.all(np.isfinite(s)):
        return lb
    return float(1.0 / np.max(s))


def _nnls_lower_bound(W: FloatArray) -> float:
    """``min_j 1 / |lam_j|`` over non-negative least-squares solutions of ``W lam = d_j``."""
    worst = 0.0
    for j in range(12):
        lam, res = nnls(W, _AXES[:, j])
        if res > 1e-9:
            return 0.0
        worst = max(worst, float(np.linalg.norm(lam)))
    return 1.0 / worst


def force_closure_quality(
    points: object,
    normals: object,
    mu: object,
    *,
    edges: int = 8,
    torque_scale: float | None = None,
    margin: float | None = None,
) -> float:
    """Force-closure quality ``Q`` of a grasp (> 0 iff force closure).

    Args:
        points: (k, 3) contact points, object frame.
        normals: (k, 3) inward contact normals, object frame (normalised here).
        mu: Coulomb friction coefficient (>= 0).
        edges: edges of each linearized friction cone (>= 3).
        torque_scale: torque normalisation length (see :func:`contact_wrenches`).
        margin: when given and the certified lower bound of ``Q`` exceeds it,
            that bound is returned without solving the QP (exact below the
            margin, a certified lower bound above it).

    Returns:
        ``Q = min_j 1 / s_j`` (module notes): ``Q / sqrt(6 m) <= eps <= Q``
        for the Ferrari-Canny epsilon of the linearized grasp; 0 when the grasp
        is not force closure.

    Raises:
        InvalidInputError: wrong shapes, non-finite values, mu < 0, edges < 3,
            zero normals, non-positive torque scale.
    """
    W = contact_wrenches(points, normals, mu, edges, torque_scale).T  # type: ignore[arg-type]
    return _quality(W, margin)


def min_subgrasp_quality(
    points: object,
    normals: object,
    mu: object,
    *,
    edges: int = 8,
    torque_scale: float | None = None,
    margin: float | None = None,
    solve: bool = True,
) -> float:
    """Minimum quality over a grasp and all its (k-1)-contact subgrasps.

    Adding contacts adds wrenches, which only enlarges the hull and the cone:
    every ``t_j`` and every ``1 / s_j`` can only grow. So the full grasp is
    never worse than any of its subgrasps and the minimum is over the k
    subgrasps of k-1 contacts.

    Args:
        points: (k, 3) contact points, object frame (k >= 2).
        normals: (k, 3) inward contact normals.
        mu: friction coefficient.
        edges: cone edges.
        torque_scale: torque normalisation length; defaults to that of the full
            grasp, so all subgrasps share it.
        margin: when given, a subgrasp whose certified lower bound exceeds it
            is not solved exactly: the bound is used (so the result is exact
            when it is <= margin, and a certified lower bound > margin
            otherwise). Validity checks only need that decision.
        solve: with a margin, False never calls OSQP: only the certified
            bounds decide, so a "no" may be a false negative (for choosing
            among many candidates, where a cheap conservative filter is best).

    Returns:
        The minimum quality (0 when some subgrasp is not force closure).
    """
    p, n, mu_f, e = _check(points, normals, mu, edges)
    if len(p) < 2:
        raise InvalidInputError(f"min_subgrasp_quality needs >= 2 contacts, got {len(p)}")
    ts = _torque_scale(p, torque_scale)
    W_all = _wrenches(p, n, mu_f, e, ts).T  # (6, k * e)
    k = len(p)
    subs = [np.delete(W_all, np.s_[i * e : (i + 1) * e], axis=1) for i in range(k)]
    if margin is not None and k >= 3:
        # the common case in validity checks, batched: one stacked SVD for all
        # subgrasps, and the first certificate for each
        certified = _batched_screen(np.stack(subs), margin)
        if certified is not None:
            return certified
    best = math.inf
    for W in subs:
        best = min(best, _quality(W, margin, solve))
        if best == 0.0:
            break
    return float(best)


def _batched_screen(Ws: FloatArray, margin: float) -> float | None:
    """Minimum certified bound over stacked subgrasps ``Ws: (k, 6, m)`` if all clear ``margin``.

    Returns None when some subgrasp is rank deficient, has no positive null
    combination, or is not certified above the margin: the caller then runs
    the per-subgrasp path, which settles those cases.
    """
    U, S, Vt = np.linalg.svd(Ws, full_matrices=False)
    if np.any(S[:, -1] <= RANK_TOL * np.maximum(1.0, S[:, 0])):
        return None
    pinv = np.swapaxes(Vt, 1, 2) / S[:, None, :] @ np.swapaxes(U, 1, 2)  # (k, m, 6)
    best = math.inf
    for W, P in zip(Ws, pinv, strict=True):
        lam0 = _positive_null(W)
        if lam0 is None:
            return None
        lb = _lower_bound(P, lam0)
        if lb <= margin:
            return None
        best = min(best, lb)
    return best
