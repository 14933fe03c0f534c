"""Plan files (format ``dexplan-plan/2``; ``/1`` is read too): build, write and read documents.

A plan file is one self-contained JSON document: the hand (URDF text, joint
names, fingertip frames and radius), the object, friction, obstacles, start,
goal, the transfer/regrasp segments and statistics. It is written atomically
(temporary file in the same folder, then rename), so a reader never sees half a
plan.

The models a document describes are rebuilt by :mod:`dexplan.planfile.models`;
the rules a plan must keep are checked by :mod:`dexplan.planfile.verify`.

Every document is first checked for structure by
:func:`dexplan.planfile.schema.validate_plan` (:func:`read_plan` and
:func:`~dexplan.planfile.verify.verify_plan` both call it): a malformed plan is a
:class:`~dexplan.core.errors.PlanFileError` naming the field, never a violation,
a crash or a silent pass.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from dexplan.core.errors import InvalidInputError, PlanFileError, one_line
from dexplan.core.files import atomic_output, file_sha256
from dexplan.core.segments import Segment, Waypoint
from dexplan.core.typing import FloatArray
from dexplan.model.grasp.rolling import ContactMotion, tip_side_contacts
from dexplan.model.hand.hand import Hand
from dexplan.model.scenario import Scenario
from dexplan.planfile import schema as plan_schema
from dexplan.planfile.models import hand_table
from dexplan.planfile.schema import FORMAT, validate_plan

__all__ = [
    "FORMAT",
    "PlannedPath",
    "build_plan_document",
    "read_plan",
    "segment_to_dict",
    "segments_from_dicts",
    "waypoint_to_dict",
    "write_plan",
]


# ------------------------------------------------------------------ writing
def waypoint_to_dict(w: Waypoint) -> dict[str, Any]:
    """JSON form of a waypoint."""
    return {
        "object_pose_xyzquat": [float(v) for v in w.object_pose_xyzquat],
        "q": [float(v) for v in w.q],
        "contacts": [None if c is None else [float(v) for v in c] for c in w.contacts],
    }


def segment_to_dict(s: Segment) -> dict[str, Any]:
    """JSON form of a segment."""
    return {
        "kind": s.kind,
        "finger": s.finger,
        "waypoints": [waypoint_to_dict(w) for w in s.waypoints],
    }


def segments_from_dicts(items: Sequence[Mapping[str, Any]]) -> tuple[Segment, ...]:
    """Segments from their JSON form (of a document :func:`validate_plan` accepted)."""
    out = []
    for s in items:
        wps = tuple(
            Waypoint(
                np.asarray(w["object_pose_xyzquat"], dtype=float),
                np.asarray(w["q"], dtype=float),
                tuple(None if c is None else np.asarray(c, dtype=float) for c in w["contacts"]),
            )
            for w in s["waypoints"]
        )
        out.append(Segment(s["kind"], s["finger"], wps))
    return tuple(out)


def write_plan(path: str | Path, doc: Mapping[str, Any]) -> None:
    """Write a plan document as JSON, atomically.

    Raises:
        PlanFileError: the folder does not exist or is not writable.
    """
    text = json.dumps(doc, indent=1, allow_nan=False)
    try:
        with atomic_output(path, "plan") as tmp, open(tmp, "w") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
    except InvalidInputError as exc:
        raise PlanFileError(str(exc)) from exc
    except OSError as exc:
        raise PlanFileError(f"cannot write plan to {str(path)!r}: {exc}") from exc


def read_plan(path: str | Path, base_dir: str | Path | None = None) -> dict[str, Any]:
    """Read a plan file and check its structure (:func:`validate_plan`).

    Args:
        path: the plan file.
        base_dir: folder relative mesh paths resolve against (default: the
            plan file's folder).

    Raises:
        PlanFileError: missing or oversized file
            (:data:`~dexplan.planfile.schema.MAX_PLAN_BYTES`),
            invalid or too deeply nested JSON, or a malformed plan (the message
            names the field).
    """
    path = Path(path)
    if not path.is_file():
        raise PlanFileError(f"plan file not found: {str(path)!r}")
    size = path.stat().st_size
    if size > plan_schema.MAX_PLAN_BYTES:
        limit = plan_schema.MAX_PLAN_BYTES
        raise PlanFileError(f"{path}: {size} bytes, more than a plan may have ({limit})")
    try:
        doc = json.loads(path.read_bytes())
    except RecursionError as exc:
        raise PlanFileError(f"{path}: not valid JSON: nested too deeply") from exc
    except (ValueError, UnicodeDecodeError) as exc:  # JSONDecodeError, a 5000-digit int
        raise PlanFileError(f"{path}: not valid JSON: {one_line(str(exc), 200)}") from exc
    try:
        validate_plan(doc, path.resolve().parent if base_dir is None else base_dir)
    except PlanFileError as exc:
        raise PlanFileError(f"{path}: {exc}") from exc
    return doc


def _portable_shape(shape: Mapping[str, Any], base_dir: Path, out_dir: Path) -> dict[str, Any]:
    """Shape dict with a mesh path relative to the plan's folder and its sha256."""
    d = dict(shape)
    if d.get("shape") == "mesh":
        src = (base_dir / str(d["path"])).resolve()
        try:
            d["path"] = os.path.relpath(src, out_dir.resolve())
        except ValueError:  # another drive
            d["path"] = str(src)
        d["sha256"] = file_sha256(src)
    return d


class PlannedPath(Protocol):
    """What a plan document is built from (a planner result has these).

    The plan file sits below planning and does not import it: any object with
    these attributes will do (:class:`~dexplan.planning.planner.PlanResult` is one).
    """

    @property
    def segments(self) -> Sequence[Segment]:
        """The transfer and regrasp segments, in order."""
        ...

    @property
    def start_pose(self) -> FloatArray:
        """``start_pose: (7,)`` the object's start pose, world frame, XYZW."""
        ...

    @property
    def start_q(self) -> FloatArray | None:
        """``start_q: (n_joints,)`` the hand's start configuration, or None."""
        ...

    @property
    def stats(self) -> _StatsLike:
        """The planner's statistics (their ``as_dict()`` goes to the document)."""
        ...


class _StatsLike(Protocol):
    def as_dict(self) -> Mapping[str, Any]: ...


def _object_table(scenario: Any, base: Path, out_dir: Path) -> dict[str, Any]:
    """The plan's ``object`` table: the shape, and ``mass`` when the scenario gives one."""
    d = _portable_shape(scenario.object, base, out_dir)
    mass = getattr(scenario, "object_mass", None)
    if mass is not None:
        d["mass"] = float(mass)
    return d


def build_plan_document(
    scenario: Scenario, hand: Hand, result: PlannedPath, out_dir: str | Path = "."
) -> dict[str, Any]:
    """The ``dexplan-plan/2`` document of a planner's result.

    Args:
        scenario: the scenario planned.
        hand: the hand used.
        result: the planner's result (segments, start pose and joints, statistics).
        out_dir: folder the plan will be written to (mesh paths are relative to it).
    """
    out_dir = Path(out_dir)
    base = scenario.base_dir
    g = scenario.goal
    doc = {
        "format": FORMAT,
        "scenario": scenario.name,
        "hand": hand_table(hand),
        "object": _object_table(scenario, base, out_dir),
        "mu": scenario.mu,
        "friction_edges": scenario.friction_edges,
        "contact_model": scenario.contact_model,
        "torsion": scenario.torsion,
        "hold_shift": scenario.hold_shift,
        "obstacles": [_portable_shape(o, base, out_dir) for o in scenario.obstacles],
        "start": {
            "object_pose_xyzquat": [float(v) for v in result.start_pose],
            "q": None if result.start_q is None else [float(v) for v in result.start_q],
        },
        "goal": {
            "object_pose_xyzquat": [float(v) for v in g.object_pose_xyzquat],
            "position_tol": g.position_tol,
            "angle_tol": g.angle_tol,
        },
        "contact_motion": str(getattr(scenario, "contact_motion", ContactMotion.FIXED)),
        "segments": [_with_tip_contacts(hand, segment_to_dict(s)) for s in result.segments],
        "stats": _jsonable(result.stats.as_dict()),
    }
    gravity = getattr(scenario, "gravity", None)
    if gravity is not None:  # [world] gravity, for executing the plan
        doc["world"] = {"gravity": [float(v) for v in gravity]}
    return doc


def _with_tip_contacts(hand: Hand, seg: dict[str, Any]) -> dict[str, Any]:
    """``seg`` (JSON form) with each waypoint's ``tip_contacts`` (contacts in tip frames)."""
    for w in seg["waypoints"]:
        tips = tip_side_contacts(hand, w["q"], np.asarray(w["object_pose_xyzquat"]), w["contacts"])
        w["tip_contacts"] = [None if t is None else [float(v) for v in t] for t in tips]
    return seg


def _jsonable(value: Any) -> Any:
    """Statistics as plain JSON values (NumPy scalars and arrays converted)."""
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
