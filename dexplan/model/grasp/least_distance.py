"""Least-distance programs ``min |z| s.t. B z <= b``: exact (Lawson-Hanson) and OSQP.

The force-closure quality (:mod:`dexplan.model.grasp`) solves one such program
per (subgrasp, direction) pair; :func:`ldp` and :func:`ldp_norm` solve it
exactly through its NNLS dual, :class:`PairQP` with a cached OSQP problem.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import osqp
import scipy.sparse as sp
from scipy.optimize import nnls

from dexplan.core.typing import FloatArray

__all__ = ["NNLS", "PairQP", "ldp", "ldp_norm"]


def _public_nnls(e: FloatArray, f: FloatArray, maxiter: int) -> FloatArray:
    return nnls(e, f, maxiter=maxiter)[0]


def _fast_nnls_or_public() -> Callable[[FloatArray, FloatArray, int], FloatArray]:
    """Return the compiled Lawson-Hanson kernel of scipy (no input checks) if usable.

    The kernel skips ``scipy.optimize.nnls``'s input checks, which cost more than
    the solve on these small problems. It is a private scipy module, so it is
    imported here under a guard (it may be absent or differ in another scipy
    release) and checked on a known problem; any failure uses the public function.
    """
    try:
        from scipy.optimize._slsqplib import nnls as kernel

        x = kernel(np.eye(2), np.array([1.0, -1.0]), 6)[0]
        if np.allclose(x, [1.0, 0.0]):
            return lambda e, f, maxiter: kernel(e, f, maxiter)[0]
    except Exception:  # any failure: use the public function
        pass
    return _public_nnls


NNLS = _fast_nnls_or_public()


def ldp(bh: FloatArray, h: FloatArray) -> FloatArray | None:
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
    u = NNLS(e, f, 50 * rows)
    res = e @ u
    res[n] -= 1.0
    if not res[n] < -1e-14:
        return None
    return res[:n] / -res[n]


def ldp_norm(e: FloatArray, b: FloatArray) -> float | None:
    """``|z*|`` of ``min |z| s.t. bh z <= b`` exactly (Lawson-Hanson), or None if infeasible.

    Args:
        e: (n + 1, R) NNLS matrix ``[-bh^T; -b^T]`` whose first n rows are set;
            its last row is overwritten with ``-b`` (the caller keeps ``e`` per
            ``bh``: only that row changes between directions).
        b: (R,) right-hand sides.
    """
    e[-1] = -b
    u = NNLS(e, _unit_last(e.shape[0]), 50 * e.shape[1])
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


class PairQP:
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
