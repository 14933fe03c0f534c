"""Failure diagnostics: rejection reasons with counts, and a plan that fails its
final verification kept for inspection."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from cli_contract import run_cli

from dexplan import api
from dexplan import planfile as plan_module
from dexplan.planning.diagnostics import Rejections
from dexplan.planning.gsn.sampler_stats import SamplerStats
from dexplan.planning.gsn.validity import KEPT_PER_REASON, REASONS, ValidityStats

ROOT = Path(__file__).resolve().parents[1]
UNSOLVABLE = ROOT / "tests" / "data" / "unsolvable_lid.toml"
#: The same with a box: the sampler's grasps of it are often rejected.
UNSOLVABLE_BOX = ROOT / "tests" / "data" / "unsolvable_lid_box.toml"


def test_rejections_name_the_dominant_reasons_largest_first():
    v = ValidityStats(checked=100, valid=3)
    v.rejected.update({"collision": 60, "force_closure": 30, "joint_limits": 7})
    v.collision_pairs[("link_13.0", "palm_link")] += 40
    v.collision_pairs[("link_3.0", "object")] += 20
    s = SamplerStats(attempts=500, ik_failures=80)
    r = Rejections.from_stats(s, v)
    assert [k for k, _ in r.dominant()] == [
        "inverse kinematics",
        "collision",
        "force closure",
        "joint limits",
    ]
    line = r.describe()
    assert "500 sampler attempts" in line and "3 of 100" in line
    assert "60 collision (most often link_13.0 / palm_link: 40)" in line
    assert line.index("inverse kinematics") < line.index("collision") < line.index("force")


def test_failed_query_reports_its_rejections(capfd, tmp_path):
    out = tmp_path / "plan.json"
    code, _, err = run_cli(capfd, "plan", UNSOLVABLE, "--time-limit", "1", "-o", out, "-q")
    assert code == 1
    lines = err.strip().splitlines()
    assert lines[0].startswith("dexplan: no plan: no_goal_grasp")
    assert "sampler attempts" in lines[1] and "rejections:" in lines[1]
    assert not out.exists()


def test_plan_failing_final_verification_is_written_for_inspection(monkeypatch, capfd, tmp_path):
    """Such a plan was discarded; now it is kept as PLAN.invalid.json, exit code 1."""
    real = plan_module.verify_plan

    def failing(doc, base_dir=".", package_dirs=()):
        rep = real(doc, base_dir, package_dirs)
        bad = plan_module.Violation(0, 1, "collision", "link_1 touches object (injected)")
        return plan_module.VerifyReport((bad,), rep.waypoints, rep.segments)

    monkeypatch.setattr(api, "verify_plan", failing)
    out = tmp_path / "plan.json"
    code, _, err = run_cli(capfd, "plan", "--time-limit", "300", "-o", out, "-q")
    assert code == 1
    assert "invalid_plan" in err and "plan.invalid.json" in err
    assert not out.exists()
    doc = json.loads((tmp_path / "plan.invalid.json").read_text())
    assert doc["segments"] and "injected" in doc["stats"]["violations"][0]
    # the file itself is a well-formed plan that `dexplan verify` can re-check
    code, stdout, _ = run_cli(capfd, "verify", tmp_path / "plan.invalid.json")
    assert code == 0 and stdout.startswith("OK")


def test_debug_rrd_records_the_rejected_samples_with_their_reasons(capfd, tmp_path):
    from test_viz import column, read_rrd

    rrd = tmp_path / "rejected.rrd"
    args = ("plan", UNSOLVABLE_BOX, "--time-limit", "1", "-o", tmp_path / "p.json", "-q")
    code, _, err = run_cli(capfd, *args, "--debug-rrd", rrd)
    assert code == 1 and "rejected samples recorded" in err
    chunks = read_rrd(rrd)
    texts = column(chunks["/rejected"], "TextLog:text")
    assert texts and all(t.split(":")[0] in REASONS for t in texts)
    assert "/world/object" in chunks  # the object (and the hand) at each sample


def test_rejected_samples_are_kept_per_reason_up_to_the_cap():
    v = ValidityStats()
    x = np.zeros(19)
    for _ in range(KEPT_PER_REASON + 10):
        v.keep(x, "collision", "a / b")
        v.rejected["collision"] += 1
    v.keep(x, "force_closure")
    reasons = [s.reason for s in v.samples]
    assert reasons.count("collision") == KEPT_PER_REASON and reasons[-1] == "force_closure"
