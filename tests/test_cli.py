"""The command line: exit codes, files written, no tracebacks on bad input."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def run(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "dexplan.cli", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
        env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"},
    )


@pytest.fixture(scope="module")
def planned(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("cli")
    res = run(
        "plan",
        "--seed",
        "3",
        "--time-limit",
        "300",
        "-o",
        "p.json",
        "--save-roadmap",
        "rm.npz",
        cwd=out,
    )
    assert res.returncode == 0, res.stderr
    assert "status: solved" in res.stdout
    assert "Traceback" not in res.stderr and "leaked" not in res.stderr
    return out


def test_plan_writes_a_verified_plan(planned: Path) -> None:
    doc = json.loads((planned / "p.json").read_text())
    assert doc["format"] == "dexplan-plan/2"
    assert (planned / "rm.npz").is_file()
    res = run("verify", "p.json", cwd=planned)
    assert res.returncode == 0 and res.stdout.startswith("OK"), res.stdout


def test_verify_rejects_a_tampered_plan(planned: Path) -> None:
    doc = json.loads((planned / "p.json").read_text())
    doc["segments"][0]["waypoints"][1]["object_pose_xyzquat"][2] += 0.01
    (planned / "bad.json").write_text(json.dumps(doc))
    res = run("verify", "bad.json", cwd=planned)
    assert res.returncode == 1
    assert "VIOLATION segment 0, waypoint 1" in res.stdout


def test_load_roadmap_answers(planned: Path) -> None:
    res = run("plan", "--load-roadmap", "rm.npz", "-o", "p2.json", "-q", cwd=planned)
    assert res.returncode == 0, res.stderr
    assert run("verify", "p2.json", cwd=planned).returncode == 0


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (("plan", "missing.toml"), "not found"),
        (("plan", "--planner", "Nope"), "unknown planner 'Nope'"),
        (("plan", "--time-limit", "-1"), "--time-limit"),
        (("plan", "-o", "no/such/dir/p.json"), "folder does not exist"),
        (("verify", "missing.json"), "not found"),
        (("plan", "--load-roadmap", "missing.npz"), "roadmap file not found"),
        (("plan", "--reduction", "magic"), "invalid choice: 'magic'"),
    ],
)
def test_bad_input_exit_code_2_without_traceback(tmp_path: Path, args, needle: str) -> None:
    res = run(*args, cwd=tmp_path)
    assert res.returncode == 2, (res.stdout, res.stderr)
    assert needle in res.stderr
    assert "Traceback" not in res.stderr


def test_malformed_scenario_names_field(tmp_path: Path) -> None:
    text = (ROOT / "scenarios" / "paper_sphere.toml").read_text().replace("mu = 0.8", "mu = -3")
    (tmp_path / "s.toml").write_text(text)
    res = run("plan", "s.toml", cwd=tmp_path)
    assert res.returncode == 2
    assert "contact.mu" in res.stderr and "-3" in res.stderr


def test_info(tmp_path: Path) -> None:
    res = run("info", cwd=tmp_path)
    assert res.returncode == 0
    assert "4 fingers" in res.stdout and "ompl" in res.stdout
