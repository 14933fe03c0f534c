"""Plan quality: the figures users compare plans by, from a plan document.

:func:`plan_quality` computes a :class:`PlanQuality` from a ``dexplan-plan/2``
document in three parts, cheapest first:

- **geometry** (microseconds, from the segments alone): regrasps and
  transfers; the object's rotation over each transfer (the angle between its
  first and last orientation, degrees: median, min and max); regrasps with no
  progress (a regrasp whose next segment is another regrasp: the object did
  not move between them); the joint travel (sum over segments and waypoint
  steps of ``|q_{k+1} - q_k|_1``, rad);
- **holds** (the verifier's :class:`~dexplan.planfile.verify.VerifyReport`,
  free when the caller has one, else :func:`~dexplan.planfile.verify.verify_plan`
  runs): the weakest hold's force-closure quality and the worst torque ratio;
- **execution** (seconds): the execution time of the time parameterisation
  ``dexplan export`` uses (:func:`~dexplan.execution.timing.time_plan`, the
  default :class:`~dexplan.execution.segment_timing.TimingLimits`: the export's
  ``duration_s``), and the largest grip force at the plan's waypoints
  (:mod:`dexplan.execution.forces`, the plan's mass and gravity). The export
  samples between the waypoints too (100 Hz by default, ten times the cost);
  the waypoints are where the contacts and the object pose are the plan's own.
  A regrasp's holding fingers and the object stay still (the verifier's
  ``regrasp_object_still`` and ``regrasp_one_finger``), so its grip forces
  are those of its first waypoint, solved once.

A figure that cannot be computed (a segment toppra cannot time, a waypoint
where no forces balance the weight) is None, with the reason in
:attr:`PlanQuality.notes`; the others are still reported.
"""

from __future__ import annotations

import itertools
import math
import statistics
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields, replace
from enum import StrEnum
from pathlib import Path
from typing import Any

import numpy as np

from dexplan.core.errors import one_line
from dexplan.core.pose import quat_angle
from dexplan.core.segments import SegmentKind, joint_travel
from dexplan.execution.forces import force_settings_from_plan, solver_from_plan
from dexplan.execution.segment_timing import TimingError
from dexplan.execution.timing import DEFAULT_LIMITS, time_plan
from dexplan.model.grasp.grip_forces import GripForceError, loaded_fingers
from dexplan.model.hand.hand import Hand
from dexplan.planfile import VerifyReport, hand_from_plan, segments_from_dicts, verify_plan

__all__ = [
    "PlanQuality",
    "QualityLevel",
    "format_quality",
    "plan_quality",
    "rotation_per_transfer_deg",
]


class QualityLevel(StrEnum):
    """Which quality figures a planning call computes after a solved query."""

    #: Every figure: the geometry, the holds and the execution (seconds).
    FULL = "full"
    #: The geometry and the holds of the verifier's report (milliseconds):
    #: no execution time, no grip force.
    FAST = "fast"
    #: None: no quality table.
    NONE = "none"


@dataclass(frozen=True)
class PlanQuality:
    """The quality figures of one plan (None: not computed, or not computable).

    Attributes:
        regrasps: regrasp segments.
        transfers: transfer segments.
        regrasps_without_progress: regrasps whose next segment is another
            regrasp (no object motion between them).
        rotation_per_transfer_deg_median: median over the transfers of the
            rotation angle between a transfer's first and last object
            orientation (world frame, degrees, in [0, 180]); None without transfers.
        rotation_per_transfer_deg_min: the least of those angles (degrees).
        rotation_per_transfer_deg_max: the largest of those angles (degrees).
        joint_travel_rad: the hand joints' total travel, the sum over segments,
            waypoint steps and joints of ``|delta q|`` (rad; m for a prismatic joint).
        execution_time_s: the time-optimal execution time (s) under the
            default timing limits, the ``duration_s`` of ``dexplan export``.
        max_grip_force_n: the largest grip force of a finger at a waypoint (N,
            the norm of its contact force), under the plan's mass and gravity.
        weakest_hold: the least force-closure quality of a hold of the plan
            (:attr:`~dexplan.planfile.verify.VerifyReport.weakest_hold`).
        worst_torque_ratio: the largest share of the joints' effort limits a
            hold needs (> 1: the hand cannot hold;
            :attr:`~dexplan.planfile.verify.VerifyReport.worst_torque_ratio`).
        notes: why a figure is None, one line each.
    """

    regrasps: int
    transfers: int
    regrasps_without_progress: int
    rotation_per_transfer_deg_median: float | None
    rotation_per_transfer_deg_min: float | None
    rotation_per_transfer_deg_max: float | None
    joint_travel_rad: float
    execution_time_s: float | None = None
    max_grip_force_n: float | None = None
    weakest_hold: float | None = None
    worst_torque_ratio: float | None = None
    notes: tuple[str, ...] = ()

    def as_dict(self) -> dict[str, Any]:
        """The JSON form (a plan file's ``stats.quality``): every field.

        None, NaN and infinite figures are None (JSON null): a torque ratio of
        ``inf`` (a hold that cannot balance the weight) is never in a verified plan.
        """
        out: dict[str, Any] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            finite = not isinstance(v, float) or math.isfinite(v)
            out[f.name] = v if finite else None
        out["notes"] = list(self.notes)
        return out

    @classmethod
    def from_mapping(cls, table: Mapping[str, Any]) -> PlanQuality:
        """Read back :meth:`as_dict` (a plan file's ``stats.quality``).

        Missing figures are None (counts 0), unknown keys are left out: a file
        written by another version still reads.
        """
        names = {f.name for f in fields(cls)}
        known = {k: v for k, v in table.items() if k in names}
        for count in ("regrasps", "transfers", "regrasps_without_progress"):
            known[count] = int(known.get(count) or 0)
        known["joint_travel_rad"] = float(known.get("joint_travel_rad") or 0.0)
        known["notes"] = tuple(str(n) for n in known.get("notes") or ())
        return cls(
            **{
                "rotation_per_transfer_deg_median": None,
                "rotation_per_transfer_deg_min": None,
                "rotation_per_transfer_deg_max": None,
                **known,
            }
        )


def rotation_per_transfer_deg(segments: Sequence[Mapping[str, Any]]) -> list[float]:
    """The object's rotation over each transfer, in plan order.

    Args:
        segments: the plan's ``segments`` (plan-file dicts).

    Returns:
        Per transfer, the angle (degrees, in [0, 180]) between the object
        orientation (world frame) at its first and its last waypoint.
    """
    out = []
    for s in segments:
        if s["kind"] != SegmentKind.TRANSFER or not s["waypoints"]:
            continue
        first = np.asarray(s["waypoints"][0]["object_pose_xyzquat"][3:], dtype=float)
        last = np.asarray(s["waypoints"][-1]["object_pose_xyzquat"][3:], dtype=float)
        out.append(math.degrees(quat_angle(first, last)))
    return out


def _geometry(segments: Sequence[Mapping[str, Any]]) -> PlanQuality:
    """The figures of the segments alone (no models): counts, rotations, travel."""
    kinds = [s["kind"] for s in segments]
    rotations = rotation_per_transfer_deg(segments)
    stalled = sum(
        a == SegmentKind.REGRASP and b == SegmentKind.REGRASP for a, b in itertools.pairwise(kinds)
    )
    return PlanQuality(
        regrasps=kinds.count(SegmentKind.REGRASP),
        transfers=kinds.count(SegmentKind.TRANSFER),
        regrasps_without_progress=int(stalled),
        rotation_per_transfer_deg_median=statistics.median(rotations) if rotations else None,
        rotation_per_transfer_deg_min=min(rotations) if rotations else None,
        rotation_per_transfer_deg_max=max(rotations) if rotations else None,
        joint_travel_rad=joint_travel(segments_from_dicts(segments)),
    )


def _max_grip_force(doc: Mapping[str, Any], hand: Hand, base_dir: Path) -> float:
    """The largest grip force (N) of a finger at a waypoint of the plan.

    Every transfer waypoint, and each regrasp's first waypoint (its holding
    fingers and the object stay still; the free finger carries no load).

    Raises:
        GripForceError: at some waypoint no forces balance the wrench.
    """
    solver = solver_from_plan(doc, force_settings_from_plan(doc), hand, base_dir)
    largest = 0.0
    for si, seg in enumerate(doc["segments"]):
        free = seg["finger"] if seg["kind"] == SegmentKind.REGRASP else None
        wps = seg["waypoints"][:1] if free is not None else seg["waypoints"]
        for wi, w in enumerate(wps):
            contacts = [None if c is None else np.asarray(c, dtype=float) for c in w["contacts"]]
            g = solver.solve(
                np.asarray(w["q"], dtype=float),
                np.asarray(w["object_pose_xyzquat"], dtype=float),
                contacts,
                loaded_fingers(contacts, free),
                where=f"segment {si}, waypoint {wi}",
            )
            largest = max(largest, float(np.linalg.norm(g.forces, axis=1).max(initial=0.0)))
    return largest


def _execution(
    doc: Mapping[str, Any], hand: Hand, base_dir: Path
) -> tuple[float | None, float | None, list[str]]:
    """``(execution time s, largest grip force N, notes)``; a figure that fails is None."""
    notes = []
    duration: float | None = None
    force: float | None = None
    try:
        duration = time_plan(doc, DEFAULT_LIMITS, hand).duration
    except TimingError as exc:
        notes.append(f"execution_time_s: {one_line(str(exc), 200)}")
    try:
        force = _max_grip_force(doc, hand, base_dir)
    except GripForceError as exc:
        notes.append(f"max_grip_force_n: {one_line(str(exc), 200)}")
    return duration, force, notes


def plan_quality(
    doc: Mapping[str, Any],
    base_dir: str | Path = ".",
    *,
    hand: Hand | None = None,
    report: VerifyReport | None = None,
    holds: bool = True,
    execution: bool = True,
) -> PlanQuality:
    """The quality figures of a plan (module docstring).

    Args:
        doc: a validated ``dexplan-plan/2`` document
            (:func:`~dexplan.planfile.document.read_plan`,
            :func:`~dexplan.planfile.document.build_plan_document`).
        base_dir: folder relative mesh paths resolve against (the plan's).
        hand: the plan's hand, if already built (rebuilt from the file when None).
        report: the verifier's report on this plan (its weakest hold and worst
            torque ratio); None: :func:`~dexplan.planfile.verify.verify_plan`
            runs, if ``holds``.
        holds: with no ``report``, run the verifier for the hold figures
            (False: they are None).
        execution: compute the execution time and the largest grip force
            (False: they are None).

    Returns:
        The :class:`PlanQuality`; a figure that cannot be computed is None,
        with its reason in ``notes``.

    Raises:
        PlanFileError: the hand or the object cannot be rebuilt from the file.
    """
    base = Path(base_dir)
    quality = _geometry(doc["segments"])
    figures: dict[str, Any] = {}
    notes: list[str] = []
    if report is None and holds:
        report = verify_plan(doc, base)
    if report is not None:
        figures["weakest_hold"] = report.weakest_hold
        figures["worst_torque_ratio"] = report.worst_torque_ratio
    if execution:
        hand = hand_from_plan(doc["hand"]) if hand is None else hand
        duration, force, notes = _execution(doc, hand, base)
        figures["execution_time_s"] = duration
        figures["max_grip_force_n"] = force
    return replace(quality, **figures, notes=tuple(notes))


def _num(value: float | None, spec: str, unit: str = "") -> str:
    """A figure for the summary lines; ``-`` when missing."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    return f"{value:{spec}}{unit}"


def format_quality(q: PlanQuality) -> list[str]:
    """The two summary lines of a plan's quality (``dexplan plan`` prints them)."""
    rot = _num(q.rotation_per_transfer_deg_median, ".1f", " deg")
    if q.rotation_per_transfer_deg_min is not None:
        lo = _num(q.rotation_per_transfer_deg_min, ".1f")
        hi = _num(q.rotation_per_transfer_deg_max, ".1f")
        rot += f" (median; {lo}-{hi})"
    return [
        f"quality: regrasps {q.regrasps}  transfers {q.transfers}  rotation/transfer {rot}  "
        f"no-progress regrasps {q.regrasps_without_progress}",
        f"execution {_num(q.execution_time_s, '.1f', ' s')}  "
        f"joint travel {_num(q.joint_travel_rad, '.1f', ' rad')}  "
        f"weakest hold {_num(q.weakest_hold, '.4g')}  "
        f"torque ratio {_num(q.worst_torque_ratio, '.2f')}  "
        f"max grip {_num(q.max_grip_force_n, '.2f', ' N')}",
    ]
