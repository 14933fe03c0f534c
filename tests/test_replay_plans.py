"""Replay of whole multi-segment plans with obstacles: paper hand, box, Allegro with a mesh (slow).

Plans may still drop the object in physics; what is asserted is that the
replay says what happened, consistently with the plan: both loops reported,
the actuators never beyond the effort limits, errors finite and bounded by the
drop, a drop placed in a segment of the right kind with the right finger.
"""

from pathlib import Path

import numpy as np
import pytest

from dexplan.cli import main as cli
from dexplan.execution.trajectory import build_trajectory
from dexplan.planfile import read_plan

mujoco = pytest.importorskip("mujoco")

from dexplan.execution.replay.result import DROP_TOL, Loop, ReplayReport  # noqa: E402
from dexplan.execution.replay.simulation import replay_loops  # noqa: E402

pytestmark = pytest.mark.slow

SCENARIOS = Path(__file__).resolve().parents[1] / "dexplan" / "data" / "scenarios"
#: A table under the Allegro's palm (its palm reaches 3 cm below the base frame).
ALLEGRO_TABLE = """
[[obstacles]]
name = "table"
shape = "box"
size = [0.3, 0.3, 0.01]
pose_xyzquat = [0.0, 0.0, -0.04, 0.0, 0.0, 0.0, 1.0]
"""
#: A replay is tried on the first seed that plans a multi-segment plan of at most
#: this execution time (s): replays run in about real time.
MAX_DURATION = 120.0


def _plan(scenario: Path, folder: Path, seeds=range(1, 7)) -> Path:
    """The first seed's plan with a regrasp and an execution time within MAX_DURATION."""
    for seed in seeds:
        path = folder / f"plan_{seed}.json"
        argv = ["plan", str(scenario), "--seed", str(seed), "--time-limit", "120", "-q"]
        if cli.run([*argv, "-o", str(path)]) != 0:
            continue
        doc = read_plan(path)
        regrasps = any(s["kind"] == "regrasp" for s in doc["segments"])
        if regrasps and build_trajectory(doc, base_dir=folder).duration <= MAX_DURATION:
            return path
    pytest.fail(f"{scenario.name}: no seed in {list(seeds)} gives a plan to replay")


def _check(doc, report: ReplayReport) -> None:
    """What every replay report must say, whatever the physics did."""
    assert [r.loop for r in report.results] == [Loop.CLOSED, Loop.OPEN]
    assert report.summary().splitlines()[-1].startswith("verdict: closed loop ")
    for r in report.results:
        assert r.n_segments == len(doc["segments"]) > 1
        assert r.max_effort_ratio <= 1.0 + 1e-9
        assert np.all(np.isfinite(r.position_error)) and np.all(np.isfinite(r.angle_error))
        if r.drop is None:
            assert r.waypoints_reached == r.waypoints
            assert r.goal_position_error is not None and np.isfinite(r.goal_position_error)
            continue
        d = r.drop
        seg = doc["segments"][d.segment]
        assert d.kind == seg["kind"]
        assert d.finger == (seg["finger"] if seg["kind"] == "regrasp" else None)
        assert d.finger not in d.holding_fingers
        assert 0.0 <= d.lost_track_time <= d.time <= r.duration
        assert r.max_position_error <= DROP_TOL and r.waypoints_reached < r.waypoints
        assert d.planned_hold_quality >= 0.0 and d.measured_hold_quality >= 0.0


@pytest.mark.parametrize(
    "scenario",
    [SCENARIOS / "paper_sphere.toml", SCENARIOS / "cube_obstacle.toml"],
    ids=["paper_sphere_table", "box_table_post"],
)
def test_paper_hand_plans_replay_whole(scenario: Path, tmp_path: Path) -> None:
    path = _plan(scenario, tmp_path)
    doc = read_plan(path)
    assert doc["obstacles"]
    _check(doc, replay_loops(doc, base_dir=tmp_path))


def test_allegro_mesh_with_a_table_replays_whole(tmp_path: Path) -> None:
    text = (SCENARIOS / "allegro_mesh.toml").read_text()
    mesh = (SCENARIOS / "../meshes/pebble.obj").resolve()
    text = text.replace('path = "../meshes/pebble.obj"', f'path = "{mesh}"') + ALLEGRO_TABLE
    scenario = tmp_path / "allegro_mesh_table.toml"
    scenario.write_text(text)
    path = _plan(scenario, tmp_path)
    doc = read_plan(path)
    assert doc["object"]["shape"] == "mesh" and doc["obstacles"]
    _check(doc, replay_loops(doc, base_dir=tmp_path))
