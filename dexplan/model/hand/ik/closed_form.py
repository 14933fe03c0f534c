"""What the closed-form finger solvers share: their check against forward kinematics.

A closed form is derived for one geometry; a finger that only looks like it
(an axis a little off, a joint offset the derivation ignores) would get
wrong answers. So before a hand uses a solver, :func:`matches_fk` solves the
tips of random configurations (fixed seed: the same hand always gets the same
answer) and accepts the solver only if every target has a branch and every
branch lands on its target. :func:`nearest_branch_of` picks, per target, the
valid branch nearest given joints; :func:`planar_2r` is the planar two-link
problem both the offset and the 2-joint solvers end in.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from dexplan.core.typing import FloatArray
from dexplan.model.hand.ik.chain import FingerChain

__all__ = ["CHECK_TOL", "Branches", "matches_fk", "nearest_branch_of", "planar_2r"]

#: Largest tip error (m) of a branch a closed-form solver may make.
CHECK_TOL = 1e-9
#: Configurations whose tips :func:`matches_fk` solves.
_CHECKS = 32

#: A solver's every branch: targets ``(N, 3)`` -> ``q: (N, B, m)``, ``ok: (N, B)``.
Branches = Callable[[FloatArray], tuple[FloatArray, np.ndarray]]


def matches_fk(chain: FingerChain, lo: FloatArray, hi: FloatArray, branches: Branches) -> bool:
    """Whether ``branches`` solves the tips of random configurations within limits exactly.

    Args:
        chain: the finger's forward kinematics.
        lo: (m,) lower joint limits.
        hi: (m,) upper joint limits.
        branches: the solver's every-branch function.
    """
    rng = np.random.default_rng(0)
    targets = chain.tips(rng.uniform(lo, hi, (_CHECKS, len(lo))))
    sol, ok = branches(targets)
    if not ok.any(axis=1).all():
        return False
    per_target = np.repeat(targets, sol.shape[1], axis=0)[ok.ravel()]
    return float(np.linalg.norm(chain.tips(sol[ok]) - per_target, axis=1).max()) < CHECK_TOL


def nearest_branch_of(
    branches: Branches, targets: FloatArray, q_near: FloatArray
) -> tuple[FloatArray, np.ndarray]:
    """Per target the valid branch nearest ``q_near: (m,)`` or ``(N, m)``.

    Returns:
        ``q: (N, m)`` and ``ok: (N,)`` (some branch valid).
    """
    q, ok = branches(targets)
    m = q.shape[2]
    d = np.sum((q - np.asarray(q_near, dtype=float).reshape(-1, 1, m)) ** 2, axis=2)
    best = np.argmin(np.where(ok, d, np.inf), axis=1)
    return q[np.arange(len(q)), best], np.asarray(ok.any(axis=1))


def planar_2r(
    d: FloatArray, l1: FloatArray, l2: FloatArray
) -> tuple[np.ndarray, list[tuple[FloatArray, FloatArray]]]:
    """Both elbows of a planar two-link chain reaching in-plane points.

    The chain reaches ``Rot(a) (l1 + Rot(phi) l2)`` for first-joint angle
    ``a`` and elbow angle ``phi`` (plane coordinates).

    Args:
        d: (N, 2) points from the first joint, plane coordinates.
        l1: (2,) the first link at zero angles.
        l2: (2,) the second link at zero angles.

    Returns:
        ``inside: (N,)`` the point lies within the chain's annulus, and per
        elbow (one way, then the other) ``(a, phi)``, (N,) each (meaningless
        where not inside).
    """
    n1, n2 = np.linalg.norm(l1), np.linalg.norm(l2)
    beta = np.arctan2(l2[1], l2[0]) - np.arctan2(l1[1], l1[0])
    cos = (np.einsum("ij,ij->i", d, d) - n1 * n1 - n2 * n2) / (2.0 * n1 * n2)
    acos = np.arccos(np.clip(cos, -1.0, 1.0))
    elbows = []
    for phi in (acos - beta, -acos - beta):
        cp, sp = np.cos(phi), np.sin(phi)
        v = l1 + np.stack([cp * l2[0] - sp * l2[1], sp * l2[0] + cp * l2[1]], axis=1)
        elbows.append((np.arctan2(d[:, 1], d[:, 0]) - np.arctan2(v[:, 1], v[:, 0]), phi))
    return np.abs(cos) <= 1.0, elbows
