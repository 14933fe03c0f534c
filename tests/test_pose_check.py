"""Failures that say what to change: start and goal poses where no grasp can exist.

Each failure example of a new user (an object pushed into the palm, into an
obstacle, out of reach at the start or at the goal, a mesh in millimetres)
gets one line that names the cause and the field to change, before any
sampling, and ``--debug-rrd`` records the states behind the verdict.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from cli_contract import assert_bad_input, run_cli

from dexplan.model.objects import unit_scale_hint
from dexplan.model.scenario import builtin_scenarios, load_scenario
from dexplan.planning.context import build_context
from dexplan.planning.gsn.validity import REASONS, Rejection
from dexplan.planning.planner import plan
from dexplan.planning.pose_check import REACH_SLACK, check_pose, check_query, finger_reach
from dexplan.planning.progress import PlanStatus

ROOT = Path(__file__).resolve().parents[1]
PAPER = (ROOT / "scenarios" / "paper_sphere.toml").read_text()
START = "object_pose_xyzquat = [0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0]"
GOAL = "object_pose_xyzquat = [0.0, 0.0, 0.1, 0.0, 0.0, 1.0, 0.0]"


def _scenario(tmp_path: Path, text: str, name: str = "case") -> Path:
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


def _with_start(z: float, x: float = 0.0) -> str:
    return PAPER.replace(START, f"object_pose_xyzquat = [{x}, 0.0, {z}, 0.0, 0.0, 0.0, 1.0]")


def _context(tmp_path: Path, text: str):
    return build_context(load_scenario(_scenario(tmp_path, text)), 1)


def test_builtin_scenarios_pass_the_check() -> None:
    """No scenario that plans is refused: the check only refuses certain failures."""
    for s in builtin_scenarios():
        if s.name in ("three_finger_sphere_point", "allegro_mesh") or "suite/" in s.name:
            continue  # not plannable on purpose / costly models: checked on the others
        sc = load_scenario(s.path)
        ctx = build_context(sc, 1)
        assert check_query(ctx) is None, s.name
        start = check_pose(ctx, sc.start.object_pose_xyzquat, "start")
        assert all(f.gap == 0.0 for f in start.reach), s.name


def test_reach_gap_grows_with_distance(tmp_path) -> None:
    """The gap is how far the object is beyond each fingertip's reach, to a voxel."""
    ctx = _context(tmp_path, PAPER)
    near = np.array([0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0])
    gaps = []
    for dz in (0.10, 0.15, 0.20):
        pose = near + np.array([0.0, 0.0, dz, 0.0, 0.0, 0.0, 0.0])
        gaps.append([finger_reach(ctx, i, pose).gap for i in range(4)])
    gaps_a = np.array(gaps)
    assert np.all(gaps_a > REACH_SLACK)
    # 5 cm farther is 5 cm more gap (to two voxels: the reach is sampled)
    assert np.allclose(np.diff(gaps_a, axis=0), 0.05, atol=2 * 0.004)
    # and every fingertip centre the check calls nearest is really that far
    for i in range(4):
        f = finger_reach(ctx, i, near + np.array([0.0, 0.0, 0.2, 0.0, 0.0, 0.0, 0.0]))
        centre = near[:3] + np.array([0.0, 0.0, 0.2])
        d = np.linalg.norm(f.p_closest_world - centre) - 0.04 - ctx.hand.fingertip_radius
        assert d == pytest.approx(f.gap, abs=1e-9)


@pytest.mark.parametrize(
    ("z", "names"),
    [
        (0.01, ["inside the palm", "palm", "mm deep", "[start] object_pose_xyzquat"]),
        (0.3, ["out of reach of 4 of 4 fingertips", "f0_tip", "mm short", "[start]"]),
    ],
)
def test_start_failures_name_the_cause(tmp_path, capfd, z, names) -> None:
    path = _scenario(tmp_path, _with_start(z))
    out = tmp_path / "plan.json"
    code, _, err = run_cli(capfd, "plan", path, "-q", "-o", out)
    assert code == 1 and not out.exists()
    lines = err.strip().splitlines()
    assert len(lines) == 1, err  # no "0 sampler attempts ... rejections: none" line
    assert lines[0].startswith("dexplan: no plan: no_start_grasp: no grasp can exist")
    for name in names:
        assert name in lines[0], lines[0]


def test_start_inside_an_obstacle_is_named(tmp_path) -> None:
    text = PAPER + (
        '\n[[obstacles]]\nname = "post"\nshape = "box"\nsize = [0.02, 0.02, 0.2]\n'
        "pose_xyzquat = [0.03, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0]\n"
    )
    # the [[obstacles]] table must come before [start]: rebuild the file in order
    head, tail = PAPER.split("[start]")
    text = head + text[len(PAPER) :] + "\n[start]" + tail
    res = plan(load_scenario(_scenario(tmp_path, text)))
    assert res.status == PlanStatus.NO_START_GRASP
    assert "inside an obstacle (post 20 mm deep)" in res.message and "mm deep" in res.message
    assert res.rejections is not None and res.rejections.attempts == 0


def test_unreachable_goal_is_found_before_any_sampling(tmp_path) -> None:
    """A goal out of reach ends the query at once, not after the time limit."""
    text = PAPER.replace(GOAL, "object_pose_xyzquat = [0.0, 0.0, 0.3, 0.0, 0.0, 1.0, 0.0]")
    res = plan(load_scenario(_scenario(tmp_path, text)), time_limit=600.0)
    assert res.status == PlanStatus.NO_GOAL_GRASP
    assert "goal pose" in res.message and "out of reach" in res.message
    assert "[goal] object_pose_xyzquat" in res.message
    assert res.rejections is not None
    assert res.rejections.attempts == 0 and not res.stats.goal_samples
    # the verdict's states, for --debug-rrd: one per finger out of reach
    kept = res.rejections.samples
    assert [s.reason for s in kept] == [Rejection.REACH] * 4
    assert Rejection.REACH not in REASONS  # the checker's counters are unchanged
    assert all(np.allclose(s.x[2], 0.3) for s in kept)


def test_goal_within_tolerance_of_a_free_pose_is_left_to_the_planner(tmp_path) -> None:
    """A goal pose touching an obstacle by less than its tolerance may still be reached."""
    sc = load_scenario(ROOT / "tests" / "data" / "unsolvable_lid_box.toml")
    assert check_query(build_context(sc, 1)) is None


def test_debug_rrd_records_the_verdict(tmp_path, capfd) -> None:
    pytest.importorskip("rerun")
    from test_viz import column, read_rrd

    path = _scenario(tmp_path, _with_start(0.3))
    rrd = tmp_path / "why.rrd"
    code, _, err = run_cli(capfd, "plan", path, "-q", "-o", tmp_path / "p.json", "--debug-rrd", rrd)
    assert code == 1 and "4 rejected samples recorded" in err
    texts = column(read_rrd(rrd)["/rejected"], "TextLog:text")
    assert len(texts) == 4 and all(t.startswith("reach: finger ") for t in texts)
    assert all("mm short at the start pose" in t for t in texts)


def test_mesh_in_millimetres_gets_a_scale_hint(tmp_path, capfd) -> None:
    egg = trimesh.load(ROOT / "dexplan" / "data" / "meshes" / "egg.obj")
    egg.apply_scale(1000.0)
    egg.export(tmp_path / "egg_mm.obj")
    text = PAPER.replace(
        'shape = "sphere"\nradius = 0.04', 'shape = "mesh"\npath = "egg_mm.obj"', 1
    )
    path = _scenario(tmp_path, text)
    code, _, err = run_cli(capfd, "plan", path, "-q", "-o", tmp_path / "p.json")
    line = assert_bad_input(code, err, names=["object", "m across", "scale = 0.001"])
    assert "in millimetres?" in line and "0.0838 m across" in line


def test_unit_scale_hint() -> None:
    assert unit_scale_hint(104.0, 1.0, 2.0).startswith("; in millimetres? scale = 0.001")
    assert "centimetres? scale = 0.01 " in unit_scale_hint(9.0, 1.0, 2.0)
    assert "scale = 2e-05" in unit_scale_hint(104.0, 0.02, 2.0)  # relative to the given scale
    assert unit_scale_hint(1e6, 1.0, 2.0) == ""  # no unit makes it hand-sized


def test_edge_of_reach_is_named_when_sampling_finds_no_grasp(tmp_path) -> None:
    """4 mm short by the reach estimate: not refused (within its error), but named."""
    res = plan(load_scenario(_scenario(tmp_path, _with_start(0.18))))
    assert res.status == PlanStatus.NO_START_GRASP
    assert res.rejections is not None and res.rejections.attempts > 0  # it was sampled
    assert res.message.startswith("no valid grasp found at the start pose; at the start pose")
    assert "4 of 4 fingertips are at the edge of their reach" in res.message
    assert "f0_tip 4 mm short" in res.message and "[start] object_pose_xyzquat" in res.message
    ctx = _context(tmp_path, PAPER)
    fine = check_pose(ctx, np.array([0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0]), "start")
    assert fine.edge_hint() == ""  # the paper's pose: 50 mm of margin
