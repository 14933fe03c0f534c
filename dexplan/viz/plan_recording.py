"""Recordings of plans: a ``dexplan-plan/2`` document animated on ``plan_step`` and ``time``."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dexplan.core.segments import Segment, count_kinds
from dexplan.execution.quality import PlanQuality, plan_quality
from dexplan.planfile import segments_from_dicts
from dexplan.planning.roadmap.graph import Roadmap
from dexplan.viz.blueprints import plan_blueprint
from dexplan.viz.contacts import log_contacts_and_fc
from dexplan.viz.roadmap_recording import log_roadmap
from dexplan.viz.scene import (
    HandLayout,
    Scene,
    log_scene_static,
    scene_from_doc,
    send_configurations,
)
from dexplan.viz.session import (
    GREY,
    STEP_SECONDS,
    finger_color,
    plan_index,
    recording,
    rerun_module,
    rgba,
    set_step,
)

if TYPE_CHECKING:  # rerun's types for annotations; at run time rerun loads on first use
    import rerun

_TRANSFER_COLOR = [70, 130, 220, 255]
_REGRASP_COLOR = [240, 150, 40, 255]


def record_plan(
    doc: Mapping[str, Any],
    path: str | Path,
    *,
    roadmap: Roadmap | None = None,
    base_dir: Path = Path("."),
) -> None:
    """Write a Rerun recording (``.rrd``) of a ``dexplan-plan/2`` document.

    The recording holds the static scene (hand link geometry, object, goal,
    obstacles, palm frame, in a right-handed z-up world), the roadmap when
    given, and the plan animated on two timelines: ``plan_step`` (one step
    per waypoint of every segment; a waypoint shared by two consecutive
    segments is counted twice, once as the last step of a segment and once
    as the first of the next, so the number of steps is
    ``sum(len(segment.waypoints))``, the plan's ``stats.waypoints``) and
    ``time`` (:data:`~dexplan.viz.STEP_SECONDS` per step). Per step: object
    pose, every moving hand link's pose, contacts with friction cones, the
    segment kind and free finger, and the force-closure quality of the
    holding grasp and the minimum over its subgrasps. ``plan/quality`` holds
    the plan's quality figures (:mod:`dexplan.execution.quality`): those of
    the file's ``stats.quality``, or, for a file without them, the ones its
    segments give (counts, rotation per transfer, joint travel). A blueprint
    lays out a 3D view, the FC plot, mode lanes, the segment log and the summaries.

    Args:
        doc: the plan document (as from :func:`dexplan.planfile.document.read_plan` or
            :func:`dexplan.planfile.document.build_plan_document`).
        path: output ``.rrd`` file.
        roadmap: the GSn roadmap the plan came from, drawn statically.
        base_dir: folder relative mesh paths resolve against (the plan's).

    Raises:
        DependencyError: rerun-sdk missing.
        PlanFileError: the document is malformed (the message names the
            field) or its hand does not build.
        InvalidInputError: the output folder does not exist.

    """
    rr = rerun_module()
    scene = scene_from_doc(doc, Path(base_dir))  # validates the document
    segments = segments_from_dicts(doc["segments"])
    assert scene.hand is not None and scene.obj is not None
    waypoints = [w for s in segments for w in s.waypoints]

    name = f"dexplan plan {doc.get('scenario', '')}".strip()
    with recording(path, name, plan_blueprint(roadmap is not None)) as rec:
        layout = log_scene_static(rec, scene)
        if roadmap is not None:
            log_roadmap(rec, roadmap, 0.25 * scene.obj.bounding_radius)
        S = len(waypoints)
        indexes = plan_index(np.arange(S))
        rec.log(
            "plan/summary",
            rr.TextDocument(
                _plan_summary_markdown(doc, S, segments), media_type=rr.MediaType.MARKDOWN
            ),
            static=True,
        )
        rec.log(
            "plan/quality",
            rr.TextDocument(
                _quality_markdown(doc, Path(base_dir)), media_type=rr.MediaType.MARKDOWN
            ),
            static=True,
        )
        if S:
            poses = np.array([w.object_pose_xyzquat for w in waypoints])
            qs = np.array([w.q for w in waypoints])
            send_configurations(rec, scene, layout, indexes, poses, qs)
            _log_plan_states(rec, scene, layout, segments)
            log_contacts_and_fc(rec, scene, segments, indexes)


def _plan_summary_markdown(
    doc: Mapping[str, Any], n_steps: int, segments: Sequence[Segment]
) -> str:
    """The plan's summary: segments, waypoints, friction and its stats, in Markdown."""
    stats = doc.get("stats") or {}
    kinds = count_kinds(segments)
    n_tr, n_rg = kinds["transfers"], kinds["regrasps"]
    lines = [
        f"## Plan {doc.get('scenario', '')}".rstrip(),
        "",
        f"- segments: **{len(segments)}** ({n_tr} transfers, {n_rg} regrasps)",
        f"- waypoints (`plan_step` steps): **{n_steps}**, "
        f"{STEP_SECONDS:g} s each on the `time` timeline",
        f"- friction: mu = {doc.get('mu')}, {doc.get('friction_edges', 8)} cone edges, "
        f"{doc.get('contact_model', 'point')} contacts"
        + (f" (torsion {doc.get('torsion')} m)" if doc.get("contact_model") == "soft" else ""),
    ]
    if stats:
        lines += ["", "| stat | value |", "|---|---|"]
        lines += [f"| {k} | {v} |" for k, v in stats.items() if not isinstance(v, dict | list)]
    return "\n".join(lines) + "\n"


def _quality_markdown(doc: Mapping[str, Any], base_dir: Path) -> str:
    """The plan's quality figures in Markdown: the file's, or those its segments give."""
    table = (doc.get("stats") or {}).get("quality")
    if isinstance(table, Mapping):
        q, from_file = PlanQuality.from_mapping(table), True
    else:  # milliseconds: no verifier, no timing, no grip forces
        q, from_file = plan_quality(doc, base_dir, holds=False, execution=False), False
    rows = [
        ("regrasps", q.regrasps),
        ("transfers", q.transfers),
        ("regrasps without progress", q.regrasps_without_progress),
        ("rotation per transfer, median (deg)", q.rotation_per_transfer_deg_median),
        ("rotation per transfer, min (deg)", q.rotation_per_transfer_deg_min),
        ("rotation per transfer, max (deg)", q.rotation_per_transfer_deg_max),
        ("joint travel (rad)", q.joint_travel_rad),
        ("execution time (s)", q.execution_time_s),
        ("weakest hold (force-closure quality)", q.weakest_hold),
        ("worst torque ratio (share of the effort limits)", q.worst_torque_ratio),
        ("largest grip force (N)", q.max_grip_force_n),
    ]
    lines = ["## Plan quality", "", "| figure | value |", "|---|---|"]
    lines += [f"| {name} | {'-' if v is None else format(v, '.4g')} |" for name, v in rows]
    lines += [f"- {note}" for note in q.notes]
    if not from_file:
        lines += [
            "",
            "The plan file has no `stats.quality`: the hold, execution time and grip "
            "force figures are those `dexplan plan` writes (or "
            "`dexplan.execution.quality.plan_quality` computes).",
        ]
    return "\n".join(lines) + "\n"


def _log_state_lanes(rec: rerun.RecordingStream, n: int) -> None:
    """The static values and colours of the mode and free-finger lanes."""
    rr = rerun_module()
    rec.log(
        "plan/state/mode",
        rr.StateConfiguration(
            values=["transfer", "regrasp"], colors=[_TRANSFER_COLOR, _REGRASP_COLOR]
        ),
        static=True,
    )
    rec.log(
        "plan/state/free_finger",
        rr.StateConfiguration(
            values=["none"] + [f"finger {i}" for i in range(n)],
            colors=[[120, 120, 120, 255]] + [rgba(finger_color(i)) for i in range(n)],
        ),
        static=True,
    )


def _segment_text(si: int, seg: Segment, first: int, last: int) -> str:
    """The segment log's line for segment ``si`` (steps ``first``..``last``)."""
    what = f"regrasp of finger {seg.finger}" if seg.kind == "regrasp" else "transfer"
    return f"segment {si}: {what} ({len(seg.waypoints)} waypoints, steps {first}-{last})"


def _log_plan_states(
    rec: rerun.RecordingStream,
    scene: Scene,
    layout: HandLayout | None,
    segments: Sequence[Segment],
) -> None:
    """Segment log, mode and free-finger lanes, and the free finger's colour."""
    rr = rerun_module()
    _log_state_lanes(rec, scene.hand.n_fingers if scene.hand is not None else 0)
    step = 0
    for si, seg in enumerate(segments):
        set_step(rec, step)
        last = step + len(seg.waypoints) - 1
        color = _REGRASP_COLOR if seg.kind == "regrasp" else _TRANSFER_COLOR
        text = _segment_text(si, seg, step, last)
        rec.log("plan/segment", rr.TextLog(text, level=rr.TextLogLevel.INFO, color=color))
        rec.log("plan/state/mode", rr.StateChange(state=seg.kind))
        free = seg.finger if seg.kind == "regrasp" else None
        rec.log(
            "plan/state/free_finger",
            rr.StateChange(state="none" if free is None else f"finger {free}"),
        )
        if layout is not None:
            _recolor_fingers(rec, layout, free)
        step = last + 1


def _recolor_fingers(rec: rerun.RecordingStream, layout: HandLayout, free: int | None) -> None:
    """Colour the free finger's links in its colour and the others grey (at the current step)."""
    for gpath, kind, finger in layout.geoms:
        if finger is None:
            continue
        color = finger_color(finger) if finger == free else GREY
        # every archetype class has from_fields; their common base does not declare it
        rec.log(gpath, kind.from_fields(**_color_fields(kind, color)))  # type: ignore[attr-defined]


def _color_fields(kind: type[rerun.AsComponents], color: Sequence[int]) -> dict[str, Any]:
    """The colour field of an archetype type (a mesh's albedo, else its colours)."""
    rr = rerun_module()
    if kind is rr.Mesh3D:
        return {"albedo_factor": rgba(color)}
    return {"colors": [rgba(color)]}
