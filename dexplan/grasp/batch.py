"""The (k-1)-subgrasp force-closure quality of many grasps at once.

Planning asks the same question of many candidate grasps that differ in one
contact (a regrasp's landing candidates) or come from one object pose (the
sampler's per-finger combinations). :func:`min_subgrasp_quality_batch` answers
it for B grasps of k contacts in one pass of the vectorised stages of
:meth:`ForceClosure.min_subgrasp_quality` (per-subset analysis, the exact
screen, the certified pair bounds), so the Python overhead is paid once, not
B times. Grasps the bounds cannot decide go to the scalar method, so each
value is what :meth:`ForceClosure.min_subgrasp_quality` returns for that grasp
with the same arguments (tests compare them grasp by grasp).
"""

from __future__ import annotations

import numpy as np

from dexplan.exceptions import InvalidInputError
from dexplan.grasp.cones import ContactModel, _check_grasp, min_contacts
from dexplan.grasp.quality import (
    DEFAULT,
    MAX_INTERIOR_NORM,
    ForceClosure,
    _Contacts,
    _drop_one,
    _ldp,
    _PairBounds,
    _scaled_torsion,
    _Subsets,
)
from dexplan.typing import FloatArray, as_positive

__all__ = ["min_subgrasp_quality_batch"]


def min_subgrasp_quality_batch(
    points: object,
    normals: object,
    mu: float,
    *,
    edges: int = 8,
    torque_scale: float,
    margin: float,
    solve: bool = True,
    contact_model: ContactModel = "point",
    torsion: float = 0.0,
    solver: ForceClosure = DEFAULT,
) -> FloatArray:
    """:meth:`ForceClosure.min_subgrasp_quality` of B grasps of k contacts each.

    Args:
        points: (B, k, 3) contact points, object frame, metres.
        normals: (B, k, 3) inward contact normals, object frame.
        mu: friction coefficient, >= 0.
        edges: pyramid edges per contact, >= 3.
        torque_scale: torque length (metres), the same for every grasp (the
            scalar method's default, the largest ``|points|``, is per grasp).
        margin: decision threshold, >= 0 (see ``force_closure_quality``).
        solve: False never runs the pair solver (undecided grasps return their
            certified lower bound), as in the scalar method.
        contact_model: ``"point"`` or ``"soft"``.
        torsion: soft-finger torsion coefficient (m); 0 for point contacts.
        solver: the :class:`ForceClosure` whose pair solver and counters are used.

    Returns:
        (B,) the value the scalar method returns for each grasp.

    Raises:
        InvalidInputError: shapes other than (B, k, 3), or as the scalar method.
    """
    pts_b = np.asarray(points, dtype=float)
    nrm_b = np.asarray(normals, dtype=float)
    if pts_b.ndim != 3 or pts_b.shape[2] != 3 or pts_b.shape != nrm_b.shape:
        raise InvalidInputError(
            "points and normals must both have shape (B, k, 3), got "
            f"{pts_b.shape} and {nrm_b.shape}"
        )
    B, k, _ = pts_b.shape
    out = np.zeros(B)
    if B == 0:
        return out
    thr = as_positive(margin, "margin", allow_zero=True)
    pts, nrm, mu_f, e, scale = _check_grasp(
        pts_b.reshape(-1, 3), nrm_b.reshape(-1, 3), mu, edges, torque_scale
    )
    tau = _scaled_torsion(contact_model, torsion, scale)
    solver.stats["evaluations"] += B
    if k - 1 < min_contacts(mu_f, contact_model):
        return out
    con = _Contacts(pts, nrm, mu_f, e, scale, tau)
    # subset s = k b + j of grasp b leaves out its contact j (the scalar order)
    subsets = (_drop_one(k)[None] + k * np.arange(B)[:, None, None]).reshape(B * k, k - 1)
    sub = _Subsets(con, subsets)
    z0, screened = _screen_each(sub, k)
    alive = np.flatnonzero(screened.reshape(B, k).all(axis=1))
    if not len(alive):
        return out
    rows = (k * alive[:, None] + np.arange(k)).ravel()
    pairs = _PairBounds(_take(sub, rows), z0[rows])
    # first_decision: theta = 0 alone, then the relaxation's upper bounds
    c0 = np.maximum(-pairs.beta.min(axis=2), 0.0)
    lo = _per_grasp_min(1.0 / np.sqrt(pairs.a2 + c0 * c0 * pairs.z0z0), k)
    hi = _per_grasp_min(pairs.q_hi, k)
    above, below = lo > thr, hi <= thr
    out[alive[above]] = lo[above]
    out[alive[below & ~above]] = hi[below & ~above]
    open_ = ~(above | below)
    if not open_.any():
        return out
    pairs.refine()
    refined = _per_grasp_min(pairs.q_lo, k)
    settled = open_ & ((refined > thr) | (not solve))
    out[alive[settled]] = refined[settled]
    for b in alive[open_ & ~settled]:
        # the certified bounds leave it open: the scalar method solves pairs
        out[b] = solver.min_subgrasp_quality(
            pts_b[b],
            nrm_b[b],
            mu_f,
            edges=e,
            torque_scale=scale,
            margin=thr,
            solve=True,
            contact_model=contact_model,
            torsion=torsion,
        )
        solver.stats["evaluations"] -= 1  # counted above
    return out


def _per_grasp_min(values: FloatArray, k: int) -> FloatArray:
    """(G,) minimum over each grasp's k subsets and 12 directions of ``values: (G k, 12)``."""
    return values.reshape(-1, k * values.shape[1]).min(axis=1)


def _screen_each(sub: _Subsets, k: int) -> tuple[FloatArray, np.ndarray]:
    """The scalar screen of each grasp's k consecutive subsets.

    Returns interior points ``z0: (S, n)`` and ``ok: (S,)``, False where the
    scalar screen would reject the subset (rank deficient, or the
    least-distance program finds no interior point). As in the scalar screen,
    a grasp's remaining subsets are not examined once one fails (their
    ``ok`` is then meaningless: the grasp is rejected).
    """
    bh, guess = sub.bh, sub.guess
    ok = sub.ok.copy()
    margin = -(bh @ guess[:, :, None]).max(axis=1)  # (S, 1)
    good = margin[:, 0] > 1e-6 * np.sqrt(np.einsum("sn,sn->s", guess, guess))
    z0 = guess / np.where(good[:, None], margin, 1.0)
    h = -np.ones(bh.shape[1])
    failed = ~ok.reshape(-1, k).all(axis=1)
    for s in np.flatnonzero(ok & ~good):
        if failed[s // k]:
            continue
        z = _ldp(bh[s], h)
        worst = -float(np.max(bh[s] @ z)) if z is not None else 0.0
        if z is None or not z @ z < MAX_INTERIOR_NORM**2 or not worst > 0.5:
            ok[s] = False
            failed[s // k] = True
            continue
        z0[s] = z / worst
    return z0, ok


def _take(sub: _Subsets, rows: np.ndarray) -> _Subsets:
    """The subsets ``rows`` of ``sub`` (a new object sharing nothing mutable)."""
    out = _Subsets.__new__(_Subsets)
    out.ok = sub.ok[rows]
    out.bh = sub.bh[rows]
    out.ch = sub.ch[rows]
    out.a = sub.a[rows]
    out.guess = sub.guess[rows]
    out.ldp_buffers = {}
    return out
