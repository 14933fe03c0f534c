"""Inspecting things: ``dexplan info --hand HAND_OR_SCENARIO_OR_URDF`` and ``dexplan scenarios``."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from cli_contract import assert_bad_input, run_cli

from dexplan.bench.tasks import resolve_scenario, scenario_files
from dexplan.core.errors import ScenarioError
from dexplan.model.hand.hand import Hand
from dexplan.model.scenario import builtin_scenarios, resolve_scenario_path

ROOT = Path(__file__).resolve().parents[1]
HANDS = ROOT / "dexplan" / "data" / "hands"
JOINT_ROW = re.compile(
    r"^\s+(\d+)\s+(\S+)\s+(\S+)\s+([+-]\d\.\d{3})\s+([+-]\d\.\d{3})\s+(\S+)\s+(\S+)$"
)


def _joint_rows(out: str) -> list[tuple[str, ...]]:
    return [m.groups() for ln in out.splitlines() if (m := JOINT_ROW.match(ln))]


def test_info_builtin_hand_lists_joints_in_planning_order(capfd) -> None:
    code, out, _ = run_cli(capfd, "info", "--hand", "paper")
    assert code == 0
    hand = Hand.builtin("paper")
    rows = _joint_rows(out)
    assert [r[1] for r in rows] == list(hand.joint_names)
    for j, r in enumerate(rows):
        assert float(r[3]) == pytest.approx(hand.lower[j], abs=5e-4)
        assert float(r[4]) == pytest.approx(hand.upper[j], abs=5e-4)
        assert float(r[6]) == pytest.approx(1.0)  # the URDF's effort
        assert int(r[2]) == next(i for i, ix in enumerate(hand.finger_q_index) if j in ix)
    assert "fingertip radius 0.012 m" in out
    for i, tip in enumerate(hand.fingertip_frames):
        assert f"finger {i}: {tip}: x [" in out


def test_info_reach_contains_the_fingertips(capfd) -> None:
    """The printed reach box holds the fingertip at random joint values."""
    code, out, _ = run_cli(capfd, "info", "--hand", "paper")
    assert code == 0
    hand = Hand.builtin("paper")
    rng = np.random.default_rng(3)
    for i in range(hand.n_fingers):
        line = next(ln for ln in out.splitlines() if ln.startswith(f"  finger {i}: "))
        box = np.array([[float(v) for v in m] for m in re.findall(r"\[([^,]+), ([^\]]+)\]", line)])
        for _ in range(20):
            tip = hand.fingertip_positions(rng.uniform(hand.lower, hand.upper))[i]
            assert np.all(tip >= box[:, 0] - 0.004) and np.all(tip <= box[:, 1] + 0.004)


def test_info_scenario_with_a_user_urdf(tmp_path, capfd) -> None:
    shutil.copy(HANDS / "three_finger.urdf", tmp_path / "my_hand.urdf")
    scen = tmp_path / "mine.toml"
    scen.write_text(
        (ROOT / "scenarios" / "three_finger_sphere.toml")
        .read_text()
        .replace('builtin = "three_finger"', 'urdf = "my_hand.urdf"\n'
                 'fingertip_frames = ["f0_tip", "f1_tip", "f2_tip"]\nfingertip_radius = 0.012')
    )  # fmt: skip
    code, out, _ = run_cli(capfd, "info", "--hand", scen)
    assert code == 0, out
    assert "hand: my_hand: 3 fingers, 9 joints, fingertip radius 0.012 m" in out
    assert len(_joint_rows(out)) == 9
    assert "finger 2: f2_tip: x [" in out
    assert "start pose: fingertip reach past the surface (mm): f0_tip +" in out
    assert "goal pose:" in out and "every fingertip reaches the object" in out


def test_info_bare_urdf_lists_joints_and_tip_candidates(capfd) -> None:
    code, out, _ = run_cli(capfd, "info", "--hand", HANDS / "three_finger.urdf")
    assert code == 0
    assert [r[1] for r in _joint_rows(out)][:3] == ["f0_abd", "f0_mcp", "f0_pip"]
    assert "fingertip frame candidates" in out and "f0_tip" in out


def test_info_unknown_hand_is_one_line_with_a_hint(capfd) -> None:
    code, out, err = run_cli(capfd, "info", "--hand", "paper_spere")
    assert out == ""
    assert_bad_input(code, err, names=["--hand", "'paper_spere'", "did you mean 'paper_sphere'"])


def test_scenarios_lists_every_builtin(capfd) -> None:
    code, out, _ = run_cli(capfd, "scenarios")
    assert code == 0
    names = [s.name for s in builtin_scenarios()]
    assert "paper_sphere" in names and "suite/box_roll90" in names
    listed = [ln.split()[0] for ln in out.splitlines() if ln and not ln.startswith("every")]
    assert listed == names
    assert "paper_sphere" in out and "180 degrees" in out


def test_builtin_names_resolve_everywhere(tmp_path, capfd) -> None:
    for s in builtin_scenarios():
        assert resolve_scenario_path(s.name) == s.path
        assert resolve_scenario_path(f"{s.name}.toml") == s.path
    assert resolve_scenario("suite/box_yaw90").name == "box_yaw90"
    assert len(scenario_files("suite")) == len([s for s in builtin_scenarios() if "/" in s.name])
    with pytest.raises(ScenarioError, match="did you mean 'paper_sphere'"):
        resolve_scenario_path("paper_spher")
    # a file of that name wins over the builtin one
    own = tmp_path / "paper_sphere"
    own.write_text("")
    assert resolve_scenario_path(own) == own
    code, _, err = run_cli(capfd, "plan", "paper_spher", "-o", tmp_path / "p.json")
    assert_bad_input(code, err, names=["'paper_spher'", "dexplan scenarios"])
    code, _, err = run_cli(
        capfd, "roadmap", "build", "nosuch", "--nodes", "5", "-o", tmp_path / "r.npz"
    )
    assert_bad_input(code, err, names=["'nosuch'"])


def test_info_scenario_says_when_a_pose_is_out_of_reach(tmp_path, capfd) -> None:
    text = (ROOT / "scenarios" / "paper_sphere.toml").read_text()
    far = text.replace(
        "object_pose_xyzquat = [0.0, 0.0, 0.1, 0.0, 0.0, 1.0, 0.0]",
        "object_pose_xyzquat = [0.0, 0.0, 0.3, 0.0, 0.0, 1.0, 0.0]",
    )
    (tmp_path / "far.toml").write_text(far)
    code, out, _ = run_cli(capfd, "info", "--hand", tmp_path / "far.toml")
    assert code == 0
    goal = next(ln for ln in out.splitlines() if ln.startswith("goal pose:"))
    assert "f0_tip -11" in goal and "no grasp can exist" in goal and "out of reach" in goal
