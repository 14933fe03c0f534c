"""The limits check of a trajectory document (``dexplan-trajectory/1``).

:func:`check_trajectory` re-checks a written trajectory against the limits it
states (joint and object speeds and accelerations, joint efforts, contact sets,
rest at segment ends), from the document alone. The limits are met by
construction: a violation is a bug or a tampered file.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from dexplan.core.typing import FloatArray

__all__ = [
    "CHECK_TOL",
    "REST_TOL",
    "check_trajectory",
]

#: Relative tolerance of the limits check (limits are met by construction).
CHECK_TOL = 1e-6
#: Speeds below this count as "at rest" (rad/s, m/s).
REST_TOL = 1e-9


def check_trajectory(doc: Mapping[str, Any], tol: float = CHECK_TOL) -> list[str]:
    """Violations of a trajectory document's own limits (empty when it passes).

    Checked at every point: joint velocities and accelerations, joint torques
    within the URDF's effort limits (``limits.joint_effort``), object speed,
    angular speed and accelerations within ``limits``; every grip force inside
    its exact contact set (round Coulomb cone ``|f_t| <= mu f_n``, or the
    elliptic soft-finger set ``|f_t|^2 / mu^2 + tau^2 / torsion^2 <= f_n^2``)
    with ``f_n >= 0``; time non-decreasing; every segment starts and ends at
    rest (joint and object velocities zero).

    Args:
        doc: a ``dexplan-trajectory/1`` document.
        tol: relative tolerance on every limit.
    """
    out: list[str] = []
    lim = doc["limits"]
    vj = np.asarray(lim["joint_velocity"], dtype=float)
    effort = lim.get("joint_effort")  # optional in the format: no effort check without it
    con = doc["contact"]
    mu, model, torsion = float(con["mu"]), con["contact_model"], float(con["torsion"])
    pts = doc["points"]
    prev_t = -math.inf
    for j, p in enumerate(pts):
        t = float(p["time_from_start"])
        msgs = ["time goes backwards"] if t < prev_t else []
        prev_t = t
        msgs += _joint_violations(p, lim, vj, doc["joint_names"], tol)
        msgs += _effort_violations(p, effort, doc["joint_names"], tol)
        msgs += _object_violations(p, lim, tol)
        msgs += _force_violations(p, mu, model, torsion, tol)
        for msg in msgs:
            if len(out) < 1000:
                out.append(f"point {j} (t = {t:.3f} s): {msg}")
    for si, s in enumerate(doc["segments"]):
        for j in (s["first_point"], s["last_point"]):
            p = pts[j]
            v = max(
                float(np.max(np.abs(p["velocities"]), initial=0.0)),
                float(np.max(np.abs(p["object_velocity"]), initial=0.0)),
            )
            if v > REST_TOL:
                out.append(f"segment {si}: not at rest at point {j} (speed {v:.3g})")
    return out


def _joint_violations(
    p: Mapping[str, Any],
    lim: Mapping[str, Any],
    vj: FloatArray,
    joint_names: list[str],
    tol: float,
) -> list[str]:
    """A point's joint velocities and accelerations beyond their limits.

    Args:
        p: the point.
        lim: the document's ``limits``.
        vj: (nq,) the joint velocity limits.
        joint_names: the joints, in the point's order.
        tol: relative tolerance.
    """
    msgs = []
    qd = np.asarray(p["velocities"], dtype=float)
    qdd = np.asarray(p["accelerations"], dtype=float)
    r = np.abs(qd) / vj
    if r.size and r.max() > 1 + tol:
        msgs.append(f"joint {joint_names[int(r.argmax())]} at {r.max():.4f} x its velocity limit")
    a = float(np.max(np.abs(qdd), initial=0.0)) / lim["joint_acceleration"]
    if a > 1 + tol:
        msgs.append(f"joint acceleration at {a:.4f} x the limit")
    return msgs


def _effort_violations(
    p: Mapping[str, Any], effort: list[float | None] | None, joint_names: list[str], tol: float
) -> list[str]:
    """A point's joint torques beyond the joints' effort limits (the grip needs more).

    Args:
        p: the point.
        effort: per joint its effort limit (N m) or None (no limit), or None.
        joint_names: the joints, in the point's order.
        tol: relative tolerance.
    """
    if effort is None:
        return []
    lim = np.array([np.inf if e is None else float(e) for e in effort])
    r = np.abs(np.asarray(p["joint_torques"], dtype=float)) / lim
    if r.size and r.max() > 1 + tol:
        j = int(r.argmax())
        return [
            f"joint {joint_names[j]} torque {abs(p['joint_torques'][j]):.4g} N m "
            f"above its effort limit {lim[j]:g} N m"
        ]
    return []


def _object_violations(p: Mapping[str, Any], lim: Mapping[str, Any], tol: float) -> list[str]:
    """A point's object speeds and accelerations (norms) beyond their limits.

    Args:
        p: the point.
        lim: the document's ``limits``.
        tol: relative tolerance.
    """
    msgs = []
    ov = np.asarray(p["object_velocity"], dtype=float)
    oa = np.asarray(p["object_acceleration"], dtype=float)
    for val, key, what in (
        (np.linalg.norm(ov[:3]), "object_speed", "object speed"),
        (np.linalg.norm(ov[3:]), "object_angular_speed", "object angular speed"),
        (np.linalg.norm(oa[:3]), "object_acceleration", "object acceleration"),
        (np.linalg.norm(oa[3:]), "object_angular_acceleration", "object angular acceleration"),
    ):
        if val > lim[key] * (1 + tol):
            msgs.append(f"{what} {val:.4g} above its limit {lim[key]:g}")
    return msgs


def _force_violations(
    p: Mapping[str, Any], mu: float, model: str, torsion: float, tol: float
) -> list[str]:
    """A point's grip forces that pull or lie outside their exact contact sets.

    Args:
        p: the point.
        mu: friction coefficient.
        model: ``"point"`` (round Coulomb cone) or ``"soft"`` (elliptic set).
        torsion: soft-finger torsion coefficient (m).
        tol: relative tolerance (of the force's norm, at least 1 N).
    """
    msgs = []
    for i, f in enumerate(p["grip_forces"]):
        if f is None:
            continue
        f = np.asarray(f, dtype=float)
        nrm = np.asarray(p["contact_normals"][i], dtype=float)
        fn = float(f @ nrm)
        ft = float(np.linalg.norm(f - fn * nrm))
        eps = tol * max(1.0, float(np.linalg.norm(f)))
        if fn < -eps:
            msgs.append(f"finger {i} pulls ({fn:.4g} N)")
            continue
        if model == "soft":
            tau = float(p["torsional_moments"][i] or 0.0)
            lhs = (ft / mu) ** 2 if mu > 0 else (0.0 if ft <= eps else math.inf)
            lhs += (tau / torsion) ** 2
            if math.sqrt(lhs) > fn + eps:
                msgs.append(f"finger {i}: force outside its soft-finger contact set")
        elif ft > mu * fn + eps:
            msgs.append(
                f"finger {i}: force outside its friction cone ({ft / max(fn, 1e-300):.4f} > mu)"
            )
    return msgs
