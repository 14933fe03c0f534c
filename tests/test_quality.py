"""Plan quality (dexplan.execution.quality): each figure against its definition, from the file."""

from __future__ import annotations

import copy
import itertools
import json
import math
from pathlib import Path

import numpy as np
import pytest

from dexplan.core.errors import InvalidInputError
from dexplan.execution.quality import PlanQuality, QualityLevel, format_quality, plan_quality
from dexplan.planfile.document import read_plan


@pytest.fixture(scope="module")
def plan_file(tmp_path_factory, paper_plan) -> Path:
    """The builtin scenario's plan of seed 3, as ``dexplan plan`` writes it."""
    return paper_plan(3, tmp_path_factory.mktemp("quality"))


@pytest.fixture(scope="module")
def doc(plan_file) -> dict:
    return read_plan(plan_file)


@pytest.fixture(scope="module")
def geometry(doc, plan_file) -> PlanQuality:
    """The figures of the segments alone (no verifier, no timing, no forces)."""
    return plan_quality(doc, plan_file.parent, holds=False, execution=False)


def _angle_deg(qa: list[float], qb: list[float]) -> float:
    """Angle (degrees) of the rotation between two XYZW quaternions, via rotation matrices."""

    def matrix(q: list[float]) -> np.ndarray:
        x, y, z, w = np.asarray(q) / np.linalg.norm(q)
        return np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
            ]
        )

    cos = (np.trace(matrix(qa).T @ matrix(qb)) - 1.0) / 2.0
    return math.degrees(math.acos(min(1.0, max(-1.0, cos))))


def test_counts_are_the_segments_of_the_file(doc, geometry) -> None:
    kinds = [s["kind"] for s in doc["segments"]]
    assert geometry.regrasps == kinds.count("regrasp") >= 1
    assert geometry.transfers == kinds.count("transfer") >= 1
    pairs = sum(a == b == "regrasp" for a, b in itertools.pairwise(kinds))
    assert geometry.regrasps_without_progress == pairs


def test_rotation_per_transfer_is_the_angle_between_its_end_poses(doc, geometry) -> None:
    angles = [
        _angle_deg(s["waypoints"][0]["object_pose_xyzquat"][3:],
                   s["waypoints"][-1]["object_pose_xyzquat"][3:])
        for s in doc["segments"]
        if s["kind"] == "transfer"
    ]  # fmt: skip
    assert geometry.rotation_per_transfer_deg_median == pytest.approx(
        float(np.median(angles)), abs=1e-6
    )
    assert geometry.rotation_per_transfer_deg_min == pytest.approx(min(angles), abs=1e-6)
    assert geometry.rotation_per_transfer_deg_max == pytest.approx(max(angles), abs=1e-6)
    assert 0.0 < geometry.rotation_per_transfer_deg_max <= 180.0


def test_joint_travel_is_the_sum_of_joint_steps(doc, geometry) -> None:
    total = 0.0
    for s in doc["segments"]:
        for a, b in itertools.pairwise(s["waypoints"]):
            total += sum(abs(qb - qa) for qa, qb in zip(a["q"], b["q"], strict=True))
    assert geometry.joint_travel_rad == pytest.approx(total, rel=1e-12)
    assert geometry.joint_travel_rad == pytest.approx(doc["stats"]["joint_travel_rad"], rel=1e-12)


def test_a_back_and_forth_regrasp_counts_one_more_without_progress(doc, plan_file, geometry):
    """After a regrasp a transfer follows: the same finger back to its old contact, and again."""
    segs = doc["segments"]
    k = next(
        i
        for i, s in enumerate(segs[:-1])
        if s["kind"] == "regrasp" and segs[i + 1]["kind"] == "transfer"
    )
    wps = segs[k]["waypoints"]
    again = {"kind": "regrasp", "finger": segs[k]["finger"], "waypoints": wps[::-1] + wps[1:]}
    tampered = copy.deepcopy(doc)
    tampered["segments"].insert(k + 1, again)
    q = plan_quality(tampered, plan_file.parent, holds=False, execution=False)
    assert q.regrasps_without_progress == geometry.regrasps_without_progress + 1
    assert (q.regrasps, q.transfers) == (geometry.regrasps + 1, geometry.transfers)
    one_way = sum(
        float(np.abs(np.subtract(b["q"], a["q"])).sum()) for a, b in itertools.pairwise(wps)
    )
    assert q.joint_travel_rad == pytest.approx(geometry.joint_travel_rad + 2 * one_way)
    assert q.rotation_per_transfer_deg_median == geometry.rotation_per_transfer_deg_median


def test_the_plan_file_carries_its_quality(doc, plan_file) -> None:
    """``dexplan plan`` wrote stats.quality; recomputed from the file alone, it is the same."""
    table = doc["stats"]["quality"]
    assert table["time_s"] > 0
    written = PlanQuality.from_mapping(table)
    again = plan_quality(doc, plan_file.parent)
    assert again.notes == written.notes == ()
    for name, value in vars(again).items():
        if isinstance(value, float):
            assert getattr(written, name) == pytest.approx(value, rel=1e-9), name
        else:
            assert getattr(written, name) == value, name
    assert written.execution_time_s > 0 and written.max_grip_force_n > 0
    assert written.weakest_hold > 0 and 0 < written.worst_torque_ratio <= 1.0


def test_execution_time_is_the_exports_duration(doc, plan_file) -> None:
    from dexplan.cli import main as cli

    out = plan_file.with_name("traj.json")
    assert cli.run(["export", str(plan_file), "-o", str(out), "--rate", "5"]) == 0
    duration = json.loads(out.read_text())["duration"]
    assert doc["stats"]["quality"]["execution_time_s"] == pytest.approx(duration, rel=1e-12)


def test_grip_forces_beyond_the_effort_limits_leave_the_rest(doc, plan_file, geometry) -> None:
    heavy = copy.deepcopy(doc)
    heavy["object"]["mass"] = 100.0  # kg: no hold within the paper hand's 1 N m limits
    q = plan_quality(heavy, plan_file.parent, holds=False)
    assert q.max_grip_force_n is None
    assert len(q.notes) == 1 and q.notes[0].startswith("max_grip_force_n: segment 0")
    assert q.execution_time_s == pytest.approx(doc["stats"]["quality"]["execution_time_s"])
    assert q.joint_travel_rad == geometry.joint_travel_rad
    assert "max grip -" in format_quality(q)[1]


def test_json_form_round_trips_and_drops_non_finite_figures(geometry) -> None:
    import dataclasses

    q = dataclasses.replace(geometry, worst_torque_ratio=math.inf, notes=("why",))
    table = q.as_dict()
    assert table["worst_torque_ratio"] is None and table["notes"] == ["why"]
    json.dumps(table, allow_nan=False)
    back = PlanQuality.from_mapping({**table, "unknown_figure": 1})
    assert back == dataclasses.replace(q, worst_torque_ratio=None)
    assert PlanQuality.from_mapping({}).regrasps == 0


def test_api_quality_levels() -> None:
    import dataclasses

    import dexplan

    with pytest.raises(InvalidInputError, match="quality must be one of full, fast, none"):
        dexplan.plan(quality="most")
    fast = dexplan.plan(seed=3, quality=QualityLevel.FAST, time_limit=300.0)
    assert fast.solved and fast.quality is not None
    assert fast.quality.execution_time_s is None and fast.quality.max_grip_force_n is None
    assert fast.quality.weakest_hold is not None  # the verifier's report, reused
    assert fast.quality.regrasps == sum(s.kind == "regrasp" for s in fast.segments)
    assert fast.to_document()["stats"]["quality"]["regrasps"] == fast.quality.regrasps
    bare = dataclasses.replace(fast, quality=None)  # what quality="none" returns
    assert "quality" not in bare.to_document()["stats"]
