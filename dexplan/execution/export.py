"""Trajectory documents (``dexplan-trajectory/1``): their JSON form, written and read.

:func:`trajectory_document` is the JSON form of a
:class:`~dexplan.execution.trajectory.Trajectory` (docs/trajectory_format.md),
which :func:`write_trajectory` writes atomically as JSON or CSV (one row per
sample) and :func:`read_trajectory` reads back.
:func:`~dexplan.execution.check.check_trajectory` checks a document against its
own limits.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import os
from collections.abc import Mapping
from enum import StrEnum
from pathlib import Path
from typing import Any

import numpy as np

from dexplan.core.errors import InvalidInputError, PlanFileError
from dexplan.core.files import atomic_output
from dexplan.core.typing import FloatArray
from dexplan.execution.trajectory import Trajectory

__all__ = [
    "TRAJECTORY_FORMAT",
    "TrajectoryFormat",
    "plan_sha256",
    "read_trajectory",
    "trajectory_document",
    "write_trajectory",
]

TRAJECTORY_FORMAT = "dexplan-trajectory/1"


class TrajectoryFormat(StrEnum):
    """The trajectory file formats, named by the file's suffix (``.json``, ``.csv``)."""

    JSON = "json"
    CSV = "csv"

    @classmethod
    def of_path(cls, path: Path) -> TrajectoryFormat | None:
        """The format of a file by its suffix, any case (None: not a trajectory format)."""
        suffix = path.suffix.lower()
        return next((f for f in cls if suffix == f".{f.value}"), None)


def plan_sha256(doc: Mapping[str, Any]) -> str:
    """SHA-256 of a plan document's canonical JSON (sorted keys, no spaces)."""
    text = json.dumps(doc, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()


def _vec(a: FloatArray) -> list[float] | None:
    return None if np.any(np.isnan(a)) else [float(v) for v in a]


def trajectory_document(
    traj: Trajectory, plan: Mapping[str, Any], sha256: str | None = None
) -> dict[str, Any]:
    """The ``dexplan-trajectory/1`` JSON document of a trajectory.

    Args:
        traj: from :func:`~dexplan.execution.trajectory.build_trajectory`.
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
    fmt = TrajectoryFormat.of_path(path)
    if fmt is None:
        raise InvalidInputError(
            f"-o: the trajectory file must end in .json or .csv, got {str(path)!r}"
        )
    text = json.dumps(doc, allow_nan=False) if fmt == TrajectoryFormat.JSON else _csv_text(doc)
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
    if TrajectoryFormat.of_path(path) == TrajectoryFormat.CSV:
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
