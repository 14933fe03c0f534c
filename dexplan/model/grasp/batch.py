"""Force-closure questions of many grasps at once.

Planning asks the same question of many candidate grasps that differ in one
contact (a regrasp's landing candidates) or come from one object pose (the
sampler's per-finger combinations). :func:`min_subgrasp_quality_batch` answers
it for B grasps of k contacts in one pass of the vectorised stages of
:meth:`ForceClosure.min_subgrasp_quality` (per-subset analysis, the exact
screen, the certified pair bounds), so the Python overhead is paid once, not
B times. Grasps the bounds cannot decide go to the scalar method, so each
value is what :meth:`ForceClosure.min_subgrasp_quality` returns for that grasp
with the same arguments (tests compare them grasp by grasp).

The plan verifier judges every waypoint of a segment:
:func:`exact_force_closure_batch` runs the first test of
:meth:`ForceClosure.exact_set_verdict` (the model's own linearization, which
settles nearly every grasp of a plan) for all of them at once.
"""

from __future__ import annotations

from typing import cast

import numpy as np

from dexplan.core.typing import FloatArray, as_positive
from dexplan.model.grasp.cones import ContactModel, check_grasp, min_contacts
from dexplan.model.grasp.force_closure import DEFAULT, ForceClosure, Verdict
from dexplan.model.grasp.subgrasps import (
    Contacts,
    PairBounds,
    Subsets,
    batch_subsets,
    scaled_torsion,
    screen_groups,
    stacked_grasps,
)

__all__ = ["exact_force_closure_batch", "min_subgrasp_quality_batch"]


def min_subgrasp_quality_batch(
    points: object,
    normals: object,
    mu: float,
    *,
    edges: int = 8,
    torque_scale: float,
    margin: float,
    solve: bool = True,
    contact_model: ContactModel | str = ContactModel.POINT,
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
    pts_b, nrm_b = stacked_grasps(points, normals)
    B, k, _ = pts_b.shape
    if B == 0:
        return np.zeros(0)
    thr = as_positive(margin, "margin", allow_zero=True)
    pts, nrm, mu_f, e, scale = check_grasp(
        pts_b.reshape(-1, 3), nrm_b.reshape(-1, 3), mu, edges, torque_scale
    )
    tau = scaled_torsion(contact_model, torsion, scale)
    con = Contacts(pts, nrm, mu_f, e, scale, tau)
    out, open_ = _bounded(con, B, k, mu_f, thr, solve, contact_model)
    # grasps the bounds leave open are the scalar method's (it counts its own)
    solver.stats["evaluations"] += B - len(open_)
    for b in open_:
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
    return out


def _bounded(
    con: Contacts, B: int, k: int, mu: float, thr: float, solve: bool, model: ContactModel | str
) -> tuple[FloatArray, np.ndarray]:
    """What the vectorised stages decide for B grasps of k contacts ``con`` (grasp-major).

    Returns:
        ``(out, open)``: (B,) the values decided (0 where not force closure)
        and the indices of the grasps the certified bounds leave open when
        ``solve`` (their pairs must be solved; their ``out`` is unset).
    """
    out, none = np.zeros(B), np.zeros(0, dtype=np.intp)
    if k - 1 < min_contacts(mu, model):
        return out, none
    # subset s = k b + j of grasp b leaves out its contact j (the scalar order)
    subsets, _ = batch_subsets(B, k, subgrasps=True)
    sub = Subsets(con, subsets)
    z0, screened = screen_groups(sub, k)
    alive = np.flatnonzero(screened.reshape(B, k).all(axis=1))
    if not len(alive):
        return out, none
    rows = (k * alive[:, None] + np.arange(k)).ravel()
    pairs = PairBounds(sub.take(rows), z0[rows])
    # as first_decision: theta = 0 alone, then the relaxation's upper bounds
    lo = _per_grasp_min(pairs.first_lower(), k)
    hi = _per_grasp_min(pairs.q_hi, k)
    above, below = lo > thr, hi <= thr
    out[alive[above]] = lo[above]
    out[alive[below & ~above]] = hi[below & ~above]
    open_ = ~(above | below)
    if not open_.any():
        return out, none
    pairs.refine()
    refined = _per_grasp_min(pairs.q_lo, k)
    settled = open_ & ((refined > thr) | (not solve))
    out[alive[settled]] = refined[settled]
    return out, alive[open_ & ~settled]


def _per_grasp_min(values: FloatArray, k: int) -> FloatArray:
    """(G,) minimum over each grasp's k subsets and 12 directions of ``values: (G k, 12)``."""
    return values.reshape(-1, k * values.shape[1]).min(axis=1)


def exact_force_closure_batch(
    points: object,
    normals: object,
    mu: float,
    *,
    edges: int = 8,
    torque_scale: float,
    subgrasps: bool = False,
    contact_model: ContactModel | str = ContactModel.POINT,
    torsion: float = 0.0,
    solver: ForceClosure = DEFAULT,
) -> list[Verdict]:
    """:meth:`ForceClosure.exact_set_verdict` of B grasps of k contacts each.

    The linearization's screen runs for every grasp at once, in groups of
    one grasp's subsets (each group stops at its first failing subset, as
    the scalar screen does); a grasp it passes is ``"fc_linear"``, any other
    goes to the scalar method (the dense polytopes).

    Args:
        points: (B, k, 3) contact points, object frame, metres.
        normals: (B, k, 3) inward contact normals, object frame.
        mu: friction coefficient, >= 0.
        edges: the model's own pyramid edges, >= 3.
        torque_scale: torque length (metres), the same for every grasp.
        subgrasps: judge every (k-1)-contact subgrasp instead of the grasp.
        contact_model: ``"point"`` or ``"soft"``.
        torsion: soft-finger torsion coefficient (m); 0 for point contacts.
        solver: the :class:`ForceClosure` that judges the grasps the screen leaves.

    Returns:
        The verdict of each grasp, in order.

    Raises:
        InvalidInputError: shapes other than (B, k, 3), or as the scalar method.
    """
    pts_b, nrm_b = stacked_grasps(points, normals)
    B, k, _ = pts_b.shape
    if B == 0:
        return []
    pts, nrm, mu_f, e, scale = check_grasp(
        pts_b.reshape(-1, 3), nrm_b.reshape(-1, 3), mu, edges, torque_scale
    )
    if (k - 1 if subgrasps else k) < min_contacts(mu_f, contact_model):
        return [Verdict.NOT_FC] * B
    subsets, per_grasp = batch_subsets(B, k, subgrasps)
    con = Contacts(pts, nrm, mu_f, e, scale, scaled_torsion(contact_model, torsion, scale))
    _, ok = screen_groups(Subsets(con, subsets), per_grasp)
    passed = cast(np.ndarray, ok.reshape(B, per_grasp).all(axis=1))
    return [
        Verdict.FC_LINEAR
        if bool(passed[b])
        else solver.exact_set_verdict(
            pts_b[b],
            nrm_b[b],
            mu_f,
            edges=e,
            torque_scale=scale,
            subgrasps=subgrasps,
            contact_model=contact_model,
            torsion=torsion,
        )
        for b in range(B)
    ]
