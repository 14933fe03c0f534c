"""The scenario suite (dexplan/data/scenarios/suite/): what it covers, and sweeps over it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from dexplan.bench.tasks import (
    make_tasks,
    parse_planners,
    scenario_files,
    scenario_planners,
    validate_sweep,
)
from dexplan.core.errors import ScenarioError
from dexplan.core.pose import quat_angle
from dexplan.model.objects import Mesh, shape_from_dict
from dexplan.model.scenario import load_scenario
from dexplan.planning.ompl import available_planners

SUITE = Path(__file__).resolve().parents[1] / "dexplan" / "data" / "scenarios" / "suite"


@pytest.fixture(scope="module")
def suite():
    return [load_scenario(p) for p in scenario_files(SUITE)]


def test_every_suite_scenario_says_what_it_tests(suite):
    assert len(suite) >= 12
    for path in scenario_files(SUITE):
        first = Path(path).read_text(encoding="utf-8").splitlines()[0]
        assert first.startswith("# ") and len(first) > 20, path


def test_suite_covers_shapes_axes_obstacles_and_friction(suite):
    shapes = {s.object["shape"] for s in suite}
    assert {"sphere", "box", "capsule", "cylinder", "mesh"} <= shapes
    meshes = [
        shape_from_dict(s.object, Path(s.base_dir)) for s in suite if s.object["shape"] == "mesh"
    ]
    assert len(meshes) >= 2 and all(isinstance(m, Mesh) and len(m.faces) >= 5000 for m in meshes)
    assert any(not trimesh.Trimesh(m.vertices, m.faces).is_convex for m in meshes)  # non-convex
    turns, axes = set(), set()
    for s in suite:
        q0 = np.asarray(s.start.object_pose_xyzquat)
        q1 = np.asarray(s.goal.object_pose_xyzquat)
        turns.add(round(np.degrees(quat_angle(q0[3:], q1[3:]))))
        axis = np.asarray(q1[3:6]) / np.linalg.norm(q1[3:6])
        axes.add(
            "vertical"
            if abs(axis[2]) > 0.999
            else "horizontal"
            if abs(axis[2]) < 1e-9
            else "tilted"
        )
        if np.linalg.norm(q1[:3] - q0[:3]) > 0.005:
            turns.add("translation")
    assert {90, 180, "translation"} <= turns and axes == {"vertical", "horizontal", "tilted"}
    assert any(s.mu <= 0.4 for s in suite)
    names = {o.get("name") for s in suite for o in s.obstacles}
    assert {"plate", "post"} <= names


def test_planners_all_and_default(suite):
    assert parse_planners("all") == available_planners()
    assert parse_planners("PRM,all")[0] == "PRM" and len(parse_planners("PRM,all")) == len(
        available_planners()
    )
    validate_sweep(["default", "PRM"], 1, None)
    box = next(s for s in suite if s.name == "box_yaw90")
    assert box.planner.name == "KPIECE1"
    assert scenario_planners(box, ["default", "KPIECE1", "PRM"]) == ["KPIECE1", "PRM"]
    tasks = make_tasks(suite, ["default"], [1])
    assert [t.planner for t in tasks] == [s.planner.name for s in suite]


def test_scenario_folder_without_scenarios_is_refused(tmp_path):
    with pytest.raises(ScenarioError, match=r"holds no \.toml file"):
        scenario_files(tmp_path)
    assert scenario_files(tmp_path / "x.toml") == [tmp_path / "x.toml"]
