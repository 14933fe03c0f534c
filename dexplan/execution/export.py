"""Executable trajectories (``dexplan-trajectory/1``): build, write, read and check.

:func:`build_trajectory` times a plan (:mod:`dexplan.execution.timing`), samples it at a
rate plus every segment boundary, and adds at each sample the contacts, the
grip forces and the joint torques (:mod:`dexplan.execution.forces`).
:func:`trajectory_document` is its JSON form (docs/trajectory_format.md), which
:func:`write_trajectory` writes atomically as JSON or CSV (one row per sample)
and :func:`read_trajectory` reads back. :func:`check_trajectory` checks a
document against its own limits.

Samples: at ``k / rate`` from each segment's start, plus the segment's end;
consecutive segments share their boundary sample (at rest). At a sample inside
a waypoint step the contacts are those of the step's first waypoint, except a
finger that is free at the step's last waypoint (it is lifting off, or not yet
landed): free. A regrasp's free finger carries no load at any of its samples
(it lifts off unloaded), except the last one when another segment follows
(it has landed and takes its share there); at a boundary sample the next
regrasp's finger carries none.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from dexplan.core.errors import InvalidInputError, PlanFileError
from dexplan.core.files import atomic_output
from dexplan.core.typing import FloatArray
from dexplan.execution.forces import (
    ForceSettings,
    GripForceError,
    GripForces,
    GripForceSolver,
    force_settings_from_plan,
    joint_effort_limits,
    solver_from_plan,
)
from dexplan.execution.timing import (
    PlanTiming,
    SegmentTiming,
    TimingLimits,
    TrajectorySample,
    time_plan,
)

__all__ = [
    "DEFAULT_RATE",
    "MAX_RATE",
    "TRAJECTORY_FORMAT",
    "Trajectory",
    "build_trajectory",
    "check_trajectory",
    "read_trajectory",
    "trajectory_document",
    "write_trajectory",
]

TRAJECTORY_FORMAT = "dexplan-trajectory/1"
#: Samples per second (Hz) when none is given, and the largest accepted.
DEFAULT_RATE = 100.0
MAX_RATE = 10000.0
#: Relative tolerance of the limits check (limits are met by construction).
CHECK_TOL = 1e-6
#: Speeds below this count as "at rest" (rad/s, m/s).
REST_TOL = 1e-9


@dataclass(frozen=True)
class Trajectory:
    """A timed plan, sampled (``m`` samples, ``n`` fingers, ``nq`` joints).

    Attributes:
        t: (m,) time from start (s), non-decreasing (strictly increasing
            except where a segment does not move).
        q, qd, qdd: (m, nq) joint positions, velocities, accelerations.
        object_pose: (m, 7) ``[x, y, z, qx, qy, qz, qw]``, world frame.
        object_velocity: (m, 6) ``[v, w]``, world frame (m/s, rad/s).
        object_acceleration: (m, 6) ``[dv/dt, d2c/dt2]``
            (:class:`dexplan.execution.timing.TrajectorySample`).
        contacts: (m, n, 3) contact points, object frame (m); NaN for free fingers.
        normals: (m, n, 3) inward unit normals at the contacts, object frame; NaN when free.
        forces: (m, n, 3) grip forces on the object, object frame (N); NaN when free.
        torsion: (m, n) soft-finger torsional moments (N m); NaN when free.
        joint_torques: (m, nq) ``J^T f`` (N m).
        margins: (m,) cone margin each sample's forces keep (fraction of ``mu``).
        segments: per segment ``(kind, finger, first_sample, last_sample)``.
        timing: the :class:`~dexplan.execution.timing.PlanTiming`.
        settings: the :class:`~dexplan.execution.forces.ForceSettings`.
        joint_effort: (nq,) the URDF's joint effort (torque) limits (N m), NaN
            where a joint has none; None when unknown.
    """

    t: FloatArray
    q: FloatArray
    qd: FloatArray
    qdd: FloatArray
    object_pose: FloatArray
    object_velocity: FloatArray
    object_acceleration: FloatArray
    contacts: FloatArray
    normals: FloatArray
    forces: FloatArray
    torsion: FloatArray
    joint_torques: FloatArray
    margins: FloatArray
    segments: tuple[tuple[str, int | None, int, int], ...]
    timing: PlanTiming
    settings: ForceSettings
    joint_effort: FloatArray | None = None

    @property
    def duration(self) -> float:
        """Total execution time (s)."""
        return float(self.t[-1]) if self.t.size else 0.0


def plan_sha256(doc: Mapping[str, Any]) -> str:
    """SHA-256 of a plan document's canonical JSON (sorted keys, no spaces)."""
    text = json.dumps(doc, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()


def build_trajectory(
    doc: Mapping[str, Any],
    *,
    rate: float = DEFAULT_RATE,
    limits: TimingLimits | None = None,
    settings: ForceSettings | None = None,
    base_dir: str | Path = ".",
    hand: Any = None,
    unbalanced: str = "raise",
) -> Trajectory:
    """Time, sample and add forces to a validated plan.

    Args:
        doc: the plan (:func:`dexplan.planfile.document.read_plan`).
        rate: samples per second (Hz), in (0, :data:`MAX_RATE`].
        limits: timing limits (default :class:`~dexplan.execution.timing.TimingLimits`).
        settings: force settings (default: the plan's mass and gravity).
        base_dir: the plan's folder (mesh paths).
        hand: the plan's hand (rebuilt from the file when None).
        unbalanced: where no forces balance the wrench: ``"raise"`` a
            GripForceError, or ``"zero"``: no grip forces there (NaN margin;
            the physics replay of a tampered plan).

    Raises:
        InvalidInputError: a bad rate.
        TimingError: a segment cannot be timed.
        GripForceError: at some sample no forces balance the wrench.
    """
    if isinstance(rate, bool) or not (
        isinstance(rate, int | float) and math.isfinite(rate) and 0 < rate <= MAX_RATE
    ):
        raise InvalidInputError(f"rate must be in (0, {MAX_RATE:g}] Hz, got {rate!r}")
    if hand is None:
        from dexplan.planfile import hand_from_plan

        hand = hand_from_plan(doc["hand"])
    settings = force_settings_from_plan(doc) if settings is None else settings
    timing = time_plan(doc, TimingLimits() if limits is None else limits, hand)
    solver = solver_from_plan(doc, settings, hand, base_dir)
    segs = doc["segments"]
    n = hand.n_fingers
    samples = _Samples()
    ranges = []
    for si, (seg, st) in enumerate(zip(segs, timing.segments, strict=True)):
        ts = _sample_times(st.duration, rate, shared_start=si > 0)
        first = len(samples.t) - (1 if si > 0 else 0)
        smp = st.sample(ts)
        nxt = segs[si + 1] if si + 1 < len(segs) else None
        for j in range(ts.size):
            contacts, loaded = _sample_contacts(seg, st, nxt, ts, j, int(smp.step[j]), n)
            samples.add_forces(
                _grip_forces(solver, smp, j, contacts, loaded, unbalanced, si, st), contacts
            )
        samples.add_states(float(timing.start_times[si]) + ts, smp)
        ranges.append((seg["kind"], seg["finger"], first, len(samples.t) - 1))
    traj = samples.trajectory(n, hand.nq, tuple(ranges), timing, settings)
    return replace(traj, joint_effort=joint_effort_limits(hand.model))


def _sample_times(duration: float, rate: float, *, shared_start: bool) -> FloatArray:
    """A segment's sample times (s from its start): every ``1 / rate`` plus its end.

    Args:
        duration: the segment's duration (s); 0: one sample at 0.
        rate: samples per second (Hz).
        shared_start: the first sample is the previous segment's last: dropped
            (the boundary sample is the earlier segment's, with its contacts
            and forces).
    """
    ts = np.arange(0.0, duration, 1.0 / rate) if duration > 0 else np.zeros(1)
    if duration > 0:
        ts = ts[ts < duration - 1e-9]
        ts = np.append(ts, duration)
    if shared_start:
        ts = ts[1:] if ts.size > 1 else ts[:0]  # the shared boundary sample
    return ts


def _sample_contacts(
    seg: Mapping[str, Any],
    st: SegmentTiming,
    nxt: Mapping[str, Any] | None,
    ts: FloatArray,
    j: int,
    k: int,
    n: int,
) -> tuple[list[FloatArray | None], tuple[bool, ...]]:
    """The contacts of sample ``j`` of a segment and the fingers loaded there.

    Inside a waypoint step the contacts are those of the step's first waypoint,
    except a finger free at the step's last one (lifting off, or not yet
    landed). A regrasp's free finger is unloaded until it has landed (its last
    sample, shared with the next segment); the next regrasp's finger is
    unloaded from that shared sample on.

    Args:
        seg: the plan segment.
        st: its timing.
        nxt: the next plan segment, or None.
        ts: the segment's sample times (s from its start).
        j: the sample.
        k: the waypoint that starts the step sample ``j`` lies in.
        n: number of fingers.

    Returns:
        ``(contacts, loaded)``: per finger the contact point (object frame) or
        None, and whether it carries load.
    """
    wps = seg["waypoints"]
    if k + 1 < len(wps) and abs(ts[j] - st.waypoint_times[k + 1]) <= 1e-9:
        # at the next waypoint: the path parameter there can fall a rounding
        # error short of it (a regrasp's last sample then read the free
        # finger as not yet landed, and the next one's finger unloaded too)
        k += 1
    wp = wps[k]
    at_wp = abs(ts[j] - st.waypoint_times[k]) <= 1e-12 or k == len(wps) - 1
    contacts = []
    for i in range(n):
        c = wp["contacts"][i]
        lifting = not at_wp and k + 1 < len(wps) and wps[k + 1]["contacts"][i] is None
        if lifting:
            c = None
        contacts.append(None if c is None else np.asarray(c, dtype=float))
    free_here = seg["finger"] if seg["kind"] == "regrasp" else None
    free_next = nxt["finger"] if nxt is not None and nxt["kind"] == "regrasp" else None
    end = j == ts.size - 1
    loaded = tuple(
        c is not None
        and not (i == free_here and not (end and nxt is not None))
        and not (end and i == free_next)
        for i, c in enumerate(contacts)
    )
    return contacts, loaded


def _grip_forces(
    solver: GripForceSolver,
    smp: TrajectorySample,
    j: int,
    contacts: list[FloatArray | None],
    loaded: tuple[bool, ...],
    unbalanced: str,
    si: int,
    st: SegmentTiming,
) -> GripForces:
    """Grip forces at sample ``j``; with ``unbalanced="zero"`` none (NaN margin) where none balance.

    Args:
        solver: the plan's grip-force solver.
        smp: the segment's samples.
        j: the sample.
        contacts: per finger, the contact point or None.
        loaded: the fingers that carry load.
        unbalanced: ``"raise"`` or ``"zero"`` (:func:`build_trajectory`).
        si: the segment's index (error messages).
        st: the segment's timing (error messages).

    Raises:
        GripForceError: no forces balance the wrench and ``unbalanced`` is not ``"zero"``.
    """
    k = int(smp.step[j])
    try:
        return solver.solve(
            smp.q[j],
            smp.object_pose[j],
            contacts,
            loaded,
            where=f"segment {si}, waypoint {k} (t = {st.waypoint_times[k]:.3f} s)",
        )
    except GripForceError:
        if unbalanced != "zero":
            raise
        g = solver.solve(smp.q[j], smp.object_pose[j], contacts, (False,) * len(contacts))
        return replace(g, margin=math.nan)


class _Samples:
    """The columns of a trajectory, filled segment by segment."""

    _STATES = ("q", "qd", "qdd", "object_pose", "object_velocity", "object_acceleration")

    def __init__(self) -> None:
        self.t: list[float] = []
        self.states: dict[str, list[Any]] = {key: [] for key in self._STATES}
        self.contacts: list[FloatArray] = []
        self.normals: list[FloatArray] = []
        self.forces: list[FloatArray] = []
        self.torsion: list[FloatArray] = []
        self.joint_torques: list[FloatArray] = []
        self.margins: list[float] = []

    def add_forces(self, g: GripForces, contacts: list[FloatArray | None]) -> None:
        """Append one sample's grip forces (NaN forces and torsion for free fingers)."""
        free = np.array([c is None for c in contacts])
        f = g.forces.copy()
        tor = g.torsion.copy()
        f[free] = np.nan
        tor[free] = np.nan
        self.contacts.append(g.contacts)
        self.normals.append(g.normals)
        self.forces.append(f)
        self.torsion.append(tor)
        self.joint_torques.append(g.joint_torques)
        self.margins.append(g.margin)

    def add_states(self, t: FloatArray, smp: TrajectorySample) -> None:
        """Append a segment's times (from the plan's start) and states."""
        self.t.extend(t.tolist())
        for key in self._STATES:
            self.states[key].extend(list(getattr(smp, key)))

    def trajectory(
        self,
        n: int,
        nq: int,
        ranges: tuple[tuple[str, int | None, int, int], ...],
        timing: PlanTiming,
        settings: ForceSettings,
    ) -> Trajectory:
        """The :class:`Trajectory` of the columns (``n`` fingers, ``nq`` joints)."""
        s = self.states
        return Trajectory(
            np.asarray(self.t),
            np.asarray(s["q"]).reshape(-1, nq),
            np.asarray(s["qd"]).reshape(-1, nq),
            np.asarray(s["qdd"]).reshape(-1, nq),
            np.asarray(s["object_pose"]).reshape(-1, 7),
            np.asarray(s["object_velocity"]).reshape(-1, 6),
            np.asarray(s["object_acceleration"]).reshape(-1, 6),
            np.asarray(self.contacts).reshape(-1, n, 3),
            np.asarray(self.normals).reshape(-1, n, 3),
            np.asarray(self.forces).reshape(-1, n, 3),
            np.asarray(self.torsion).reshape(-1, n),
            np.asarray(self.joint_torques).reshape(-1, nq),
            np.asarray(self.margins),
            ranges,
            timing,
            settings,
        )


def _vec(a: FloatArray) -> list[float] | None:
    return None if np.any(np.isnan(a)) else [float(v) for v in a]


def trajectory_document(
    traj: Trajectory, plan: Mapping[str, Any], sha256: str | None = None
) -> dict[str, Any]:
    """The ``dexplan-trajectory/1`` JSON document of a trajectory.

    Args:
        traj: from :func:`build_trajectory`.
        plan: the plan it was built from (joint names, friction).
        sha256: the plan file's SHA-256 (default: :func:`plan_sha256` of ``plan``).
    """
    st = traj.settings
    points = [_point(traj, j) for j in range(traj.t.size)]
    return {
        "format": TRAJECTORY_FORMAT,
        "plan_sha256": sha256 if sha256 is not None else plan_sha256(plan),
        "joint_names": list(plan["hand"]["joint_names"]),
        "fingertip_frames": list(plan["hand"]["fingertip_frames"]),
        "duration": traj.duration,
        "limits": _limits_table(traj),
        "contact": {
            "mu": float(plan["mu"]),
            "friction_edges": int(plan.get("friction_edges", 8)),
            "contact_model": str(plan.get("contact_model", "point")),
            "torsion": float(plan.get("torsion", 0.0)),
            "cone_margin": st.cone_margin,
            "min_normal_force": st.min_normal_force,
        },
        "object_mass": st.mass,
        "gravity": [float(v) for v in st.gravity],
        "points": points,
        "segments": [
            {"kind": k, "finger": f, "first_point": a, "last_point": b}
            for k, f, a, b in traj.segments
        ],
    }


def _point(traj: Trajectory, j: int) -> dict[str, Any]:
    """Sample ``j`` of the trajectory as a ``points`` entry of the document."""
    return {
        "time_from_start": float(traj.t[j]),
        "positions": [float(v) for v in traj.q[j]],
        "velocities": [float(v) for v in traj.qd[j]],
        "accelerations": [float(v) for v in traj.qdd[j]],
        "object_pose_xyzquat": [float(v) for v in traj.object_pose[j]],
        "object_velocity": [float(v) for v in traj.object_velocity[j]],
        "object_acceleration": [float(v) for v in traj.object_acceleration[j]],
        "contacts": [_vec(c) for c in traj.contacts[j]],
        "contact_normals": [_vec(c) for c in traj.normals[j]],
        "grip_forces": [_vec(f) for f in traj.forces[j]],
        "torsional_moments": [None if math.isnan(v) else float(v) for v in traj.torsion[j]],
        "joint_torques": [float(v) for v in traj.joint_torques[j]],
        "cone_margin": float(traj.margins[j]),
    }


def _limits_table(traj: Trajectory) -> dict[str, Any]:
    """The document's ``limits``: the joint and object limits the timing used."""
    lim = traj.timing.limits
    return {
        "joint_velocity": [float(v) for v in traj.timing.joint_velocity],
        "joint_effort": (
            None
            if traj.joint_effort is None
            else [None if math.isnan(v) else float(v) for v in traj.joint_effort]
        ),
        "joint_acceleration": lim.max_acceleration,
        "object_speed": lim.object_speed,
        "object_angular_speed": lim.object_angular_speed,
        "object_acceleration": lim.object_acceleration,
        "object_angular_acceleration": lim.object_angular_acceleration,
        "approach_scale": lim.approach_scale,
        "approach_steps": lim.approach_steps,
    }


# ------------------------------------------------------------------ files
def _csv_header(doc: Mapping[str, Any]) -> list[str]:
    joints = doc["joint_names"]
    n = len(doc["fingertip_frames"])
    h = ["time_from_start", "segment", "kind", "finger"]
    h += [f"position_{j}" for j in joints]
    h += [f"velocity_{j}" for j in joints]
    h += [f"acceleration_{j}" for j in joints]
    h += [f"object_{a}" for a in ("x", "y", "z", "qx", "qy", "qz", "qw")]
    h += [f"object_{a}" for a in ("vx", "vy", "vz", "wx", "wy", "wz")]
    h += [f"object_{a}" for a in ("ax", "ay", "az", "alphax", "alphay", "alphaz")]
    for i in range(n):
        h += [f"contact{i}_{a}" for a in "xyz"]
        h += [f"normal{i}_{a}" for a in "xyz"]
        h += [f"force{i}_{a}" for a in "xyz"]
        h += [f"torsion{i}"]
    h += [f"torque_{j}" for j in joints]
    h += ["cone_margin"]
    return h


def _csv_text(doc: Mapping[str, Any]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(_csv_header(doc))
    seg_of = {}
    for si, s in enumerate(doc["segments"]):
        for j in range(s["first_point"], s["last_point"] + 1):
            seg_of[j] = (si, s)  # the later segment wins at a shared boundary
    n = len(doc["fingertip_frames"])
    for j, p in enumerate(doc["points"]):
        si, s = seg_of[j]
        row: list[Any] = [
            repr(p["time_from_start"]),
            si,
            s["kind"],
            "" if s["finger"] is None else s["finger"],
        ]
        for key in ("positions", "velocities", "accelerations", "object_pose_xyzquat",
                    "object_velocity", "object_acceleration"):  # fmt: skip
            row += [repr(v) for v in p[key]]
        for i in range(n):
            for key in ("contacts", "contact_normals", "grip_forces"):
                v = p[key][i]
                row += ["", "", ""] if v is None else [repr(x) for x in v]
            tm = p["torsional_moments"][i]
            row.append("" if tm is None else repr(tm))
        row += [repr(v) for v in p["joint_torques"]]
        row.append(repr(p["cone_margin"]))
        w.writerow(row)
    return buf.getvalue()


def write_trajectory(path: str | Path, doc: Mapping[str, Any]) -> None:
    """Write a trajectory document atomically: ``.json`` as JSON, ``.csv`` one row per sample.

    A CSV file keeps the samples only (its header names the columns); the
    document's other fields (limits, segments as ``segment`` and ``kind``
    columns) are in the JSON form.

    Raises:
        InvalidInputError: an extension other than ``.json`` or ``.csv``, or a
            missing folder.
        OSError: the file cannot be written.
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in (".json", ".csv"):
        raise InvalidInputError(
            f"-o: the trajectory file must end in .json or .csv, got {str(path)!r}"
        )
    text = json.dumps(doc, allow_nan=False) if ext == ".json" else _csv_text(doc)
    with atomic_output(path, "trajectory") as tmp, open(tmp, "w", newline="") as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())


def read_trajectory(path: str | Path) -> dict[str, Any]:
    """Read a trajectory file (JSON: the document; CSV: ``{"header", "rows"}`` as floats).

    Raises:
        PlanFileError: missing, unreadable or not a ``dexplan-trajectory/1`` file.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise PlanFileError(f"cannot read trajectory {str(path)!r}: {exc}") from exc
    if path.suffix.lower() == ".csv":
        rows = list(csv.reader(io.StringIO(text)))
        if not rows or rows[0][:1] != ["time_from_start"]:
            raise PlanFileError(f"{path}: not a dexplan trajectory CSV (no header)")
        header = rows[0]
        out = []
        for r in rows[1:]:
            out.append(
                [
                    v if header[k] == "kind" else (math.nan if v == "" else float(v))
                    for k, v in enumerate(r)
                ]
            )
        return {"header": header, "rows": out}
    try:
        doc = json.loads(text)
    except ValueError as exc:
        raise PlanFileError(f"{path}: not valid JSON: {str(exc)[:200]}") from exc
    if not isinstance(doc, dict) or doc.get("format") != TRAJECTORY_FORMAT:
        raise PlanFileError(f"{path}: format must be {TRAJECTORY_FORMAT!r}")
    return doc


# ------------------------------------------------------------------ check
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
    effort = lim.get("joint_effort")  # absent in files written before it was checked
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
