"""Every IK branch of a finger without a closed form: damped least squares from several seeds.

A 3-joint finger reaches most fingertip positions in up to four postures
(knee in or out, the first joint on one side or the other); a damped least
squares solve from one start finds the posture nearest that start, and
the others are never tried. :func:`branch_solutions` starts the batched solve
(:func:`~dexplan.model.hand.ik.numeric.batch_dls`) from :data:`BRANCH_SEEDS`
deterministic points spread over the joint ranges (the middle of the ranges
and Halton points), all targets and seeds in one vectorised call, and keeps
the distinct solutions per target. A branch is found when some seed lies in
its basin of attraction; with 8 seeds spread over the joint box each branch
of the fingers measured (the TriFinger's finger_edu, whose offset axes rule
out the closed forms of :mod:`.planar` and :mod:`.split`) has several.
"""

from __future__ import annotations

import numpy as np

from dexplan.core.typing import FloatArray
from dexplan.model.hand.ik.chain import FingerChain
from dexplan.model.hand.ik.numeric import batch_dls, halton

__all__ = ["BRANCH_SEEDS", "SAME_SOLUTION", "branch_seeds", "branch_solutions"]

#: Seeds per target (the middle of the joint ranges, then Halton points).
BRANCH_SEEDS = 8
#: Two solutions closer than this in every joint (rad or m) are the same branch.
SAME_SOLUTION = 1e-3
# Seeds keep off the limits: a start on a limit is clipped back onto it.
_SEED_INSET = 0.05


def branch_seeds(lo: FloatArray, hi: FloatArray, count: int = BRANCH_SEEDS) -> FloatArray:
    """``(count, m)`` deterministic start points inside the joint box ``[lo, hi]``."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    m = len(lo)
    unit = np.vstack([np.full((1, m), 0.5), halton(count - 1, m)])
    unit = _SEED_INSET + (1.0 - 2.0 * _SEED_INSET) * unit
    return lo + unit * (hi - lo)


def branch_solutions(
    chain: FingerChain,
    targets: FloatArray,
    lo: FloatArray,
    hi: FloatArray,
    *,
    seeds: int = BRANCH_SEEDS,
    tol: float = 1e-7,
) -> tuple[FloatArray, np.ndarray]:
    """The distinct IK solutions of each target, one per branch found.

    Args:
        chain: the finger.
        targets: (N, 3) fingertip-centre targets, world frame.
        lo: (m,) lower joint limits.
        hi: (m,) upper joint limits.
        seeds: starts per target (:func:`branch_seeds`).
        tol: success threshold on the position error (m).

    Returns:
        ``q: (N, seeds, m)`` within limits and ``ok: (N, seeds)``: True for
        a converged solution that no earlier seed's solution of the same
        target repeats (within :data:`SAME_SOLUTION` in every joint).
    """
    targets = np.asarray(targets, dtype=float).reshape(-1, 3)
    n, m = len(targets), chain.m
    starts = branch_seeds(lo, hi, seeds)  # (S, m)
    q0 = np.broadcast_to(starts[None], (n, seeds, m)).reshape(-1, m)
    q, ok = batch_dls(chain, np.repeat(targets, seeds, axis=0), q0, lo, hi, tol=tol)
    q, ok = q.reshape(n, seeds, m), ok.reshape(n, seeds)
    for k in range(1, seeds):
        # (N, k): does seed k's solution repeat an earlier converged one?
        same = np.all(np.abs(q[:, :k] - q[:, k : k + 1]) < SAME_SOLUTION, axis=2) & ok[:, :k]
        ok[:, k] &= ~same.any(axis=1)
    return q, ok
