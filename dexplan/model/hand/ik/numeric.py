"""Damped least squares IK: batched over targets, and for one finger of any kind.

Steps ``dq = J^T (J J^T + lambda I)^-1 e`` with ``lambda = |e|^2 + 1e-9``:
the damping vanishes near a solution, so the convergence is quadratic there,
and stays bounded at singularities. Steps are clipped to the joint limits.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from dexplan.core.typing import FloatArray
from dexplan.model.hand.ik.chain import FingerChain


def batch_dls(
    chain: FingerChain,
    targets: FloatArray,
    q0: FloatArray,
    lo: FloatArray,
    hi: FloatArray,
    *,
    tol: float = 1e-7,
    max_iter: int = 40,
) -> tuple[FloatArray, np.ndarray]:
    """Damped least squares IK for many targets at once, within joint limits.

    Steps ``dq = J^T (J J^T + lambda I)^-1 e`` with ``lambda = |e|^2 + 1e-9``
    (as :func:`finger_dls`), clipped to the limits, for all
    targets together; converged targets stop moving.

    Args:
        chain: the finger.
        targets: (N, 3) fingertip-centre targets, world frame.
        q0: (N, m) or (m,) start configurations (the solution stays near them).
        lo: (m,) lower joint limits.
        hi: (m,) upper joint limits.
        tol: success threshold on the position error (m).
        max_iter: iterations.

    Returns:
        ``q: (N, m)`` within limits and ``ok: (N,)`` (error below ``tol``).
    """
    targets = np.asarray(targets, dtype=float).reshape(-1, 3)
    q = np.clip(np.broadcast_to(q0, (len(targets), chain.m)).astype(float), lo, hi)
    active = np.arange(len(targets))
    ok = np.zeros(len(targets), dtype=bool)
    eye = np.eye(3)
    for _ in range(max_iter):
        if not len(active):
            break
        qa = q[active]
        p, J = chain.jacobian(qa)
        e = targets[active] - p
        err2 = np.einsum("ij,ij->i", e, e)
        done = err2 < tol * tol
        ok[active[done]] = True
        keep = ~done
        active, qa, J, e, err2 = active[keep], qa[keep], J[keep], e[keep], err2[keep]
        if not len(active):
            break
        A = J @ J.transpose(0, 2, 1) + (err2 + 1e-9)[:, None, None] * eye
        dq = np.einsum("nji,nj->ni", J, np.linalg.solve(A, e[:, :, None])[:, :, 0])
        q[active] = np.clip(qa + dq, lo, hi)
    if len(active):
        e = targets[active] - chain.tips(q[active])
        ok[active] = np.einsum("ij,ij->i", e, e) < tol * tol
    return q, ok


@dataclass(frozen=True)
class IKResult:
    """Outcome of a per-finger inverse kinematics solve.

    Attributes:
        q_finger: (m,) joint values of the finger, always within limits.
        success: True when the tip reached the target within tolerance.
        residual: |p_tip - p_target| in metres at ``q_finger``.
        iterations: solver iterations used (over all restarts).
    """

    q_finger: FloatArray
    success: bool
    residual: float
    iterations: int


def halton(n: int, dims: int) -> FloatArray:
    """First ``n`` points of the Halton sequence in ``[0, 1)^dims`` (IK restarts)."""
    primes = (2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37)[:dims]
    out = np.empty((n, dims))
    for j, b in enumerate(primes):
        for i in range(n):
            f, r, k = 1.0, 0.0, i + 1
            while k:
                f /= b
                r += f * (k % b)
                k //= b
            out[i, j] = r
    return out


#: Restart points of :func:`finger_dls` (deterministic: the same call gives the same answer).
RESTARTS = halton(16, 12)


def finger_dls(
    tip_jacobian: Callable[[FloatArray], tuple[FloatArray, FloatArray]],
    target: FloatArray,
    q_start: FloatArray,
    lo: FloatArray,
    hi: FloatArray,
    *,
    tol: float,
    max_iter: int,
    restarts: int,
) -> IKResult:
    """Damped least squares IK of one fingertip centre, with restarts.

    When a run stalls it restarts from the limits' midpoint and then from
    the points of :data:`RESTARTS`, so the same call always gives the same
    answer.

    Args:
        tip_jacobian: ``q_finger: (m,)`` to the tip centre ``(3,)`` and its
            position Jacobian ``(3, m)``, world frame.
        target: (3,) fingertip-centre target, world frame.
        q_start: (m,) first start (clipped to the limits).
        lo: (m,) lower joint limits.
        hi: (m,) upper joint limits.
        tol: success threshold on the position error (m).
        max_iter: iterations per start.
        restarts: extra starts after the first.

    Returns:
        The best configuration found and whether it is within ``tol``.
    """
    eye = np.eye(3)
    best_q, best_err, iters = np.clip(q_start, lo, hi), math.inf, 0
    q_f = best_q
    for attempt in range(restarts + 1):
        if attempt == 0:
            q_f = best_q
        elif attempt == 1:
            q_f = 0.5 * (lo + hi)
        else:
            q_f = lo + (hi - lo) * RESTARTS[(attempt - 2) % len(RESTARTS), : len(lo)]
        for _ in range(max_iter):
            iters += 1
            p, J = tip_jacobian(q_f)
            e = target - p
            err = math.sqrt(e @ e)
            if err < best_err:
                best_err, best_q = err, q_f.copy()
            if err < tol:
                return IKResult(best_q, True, best_err, iters)
            dq = J.T @ np.linalg.solve(J @ J.T + (err * err + 1e-9) * eye, e)
            q_new = np.clip(q_f + dq, lo, hi)
            if np.max(np.abs(q_new - q_f)) < 1e-12:
                break  # stalled against a limit or in a local minimum
            q_f = q_new
    return IKResult(best_q, best_err < tol, best_err, iters)
