"""The scripts in examples/ run from a fresh process and print what they promise."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"


def run_example(name: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    res = subprocess.run(
        [sys.executable, str(EXAMPLES / name)],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert res.returncode == 0, f"{name} exited {res.returncode}:\n{res.stdout}\n{res.stderr}"
    assert "Traceback" not in res.stderr
    # library users see no nanobind "leaked instances" report at exit (the CLI
    # leaves through os._exit; a plain script exits normally)
    assert "leaked" not in res.stderr, res.stderr
    return res


def test_every_example_is_short_and_documented() -> None:
    scripts = sorted(EXAMPLES.glob("*.py"))
    assert {p.name for p in scripts} >= {
        "plan_and_inspect.py",
        "compare_planners.py",
        "multi_query.py",
        "python_planner.py",
        "own_gsn_path.py",
    }
    for path in scripts:
        text = path.read_text()
        assert len(text.splitlines()) < 60, path.name
        assert text.startswith('"""'), f"{path.name} has no module docstring"


def test_plan_and_inspect(tmp_path: Path) -> None:
    out = run_example("plan_and_inspect.py", tmp_path).stdout
    assert "status: solved" in out
    kinds = re.findall(
        r"^segment +\d+: (transfer|regrasp) +finger (\S+) +(\d+) waypoints$", out, re.M
    )
    assert kinds and {k for k, _, _ in kinds} == {"transfer", "regrasp"}
    assert all((finger == "-") == (kind == "transfer") for kind, finger, _ in kinds)
    counts = re.search(r"^regrasps: (\d+)  transfers: (\d+)$", out, re.M)
    assert counts is not None
    assert int(counts[1]) + int(counts[2]) == len(kinds)
    assert re.search(r"^verify: OK ", out, re.M)
    assert not list(tmp_path.iterdir())  # the plan went to a temporary folder


def test_multi_query(tmp_path: Path) -> None:
    out = run_example("multi_query.py", tmp_path).stdout
    assert re.search(r"^built: \d+ nodes, \d+ edges, \d+ links in ", out, re.M)
    assert re.search(r"^loaded \d+ vertices, \d+ edges$", out, re.M)
    for k in (1, 2, 3):
        assert re.search(rf"^query {k}: solved in .* \(roadmap(_grown)?\)$", out, re.M)


@pytest.mark.slow
def test_compare_planners(tmp_path: Path) -> None:
    out = run_example("compare_planners.py", tmp_path).stdout
    # the table's shape only: how many seeds finish within 20 s is the machine's business
    rows = re.findall(r"^(PRM|RRTConnect|KPIECE1) +([0-3]) / 3 +(\S+) +(\S+)$", out, re.M)
    assert [row[0] for row in rows] == ["PRM", "RRTConnect", "KPIECE1"]


def test_python_planner(tmp_path: Path) -> None:
    """A planner written in Python, in no registry, solves GSn; its plan is verified."""
    out = run_example("python_planner.py", tmp_path).stdout
    assert re.search(r"^GraspTree: exact$", out, re.M)
    path = re.search(r"^GSn path: (\d+) states of dimension 19$", out, re.M)
    assert path is not None and int(path[1]) >= 2
    plan = re.search(r"^plan: solved, (\d+) regrasps, (\d+) transfers$", out, re.M)
    assert plan is not None and int(plan[2]) >= 1


def test_own_gsn_path(tmp_path: Path) -> None:
    """to_plan on a two-grasp path: module 2 links the grasps, the plan file verifies."""
    out = run_example("own_gsn_path.py", tmp_path).stdout
    assert re.search(r"^path: 2 states, goal pose ", out, re.M)
    links = re.search(r"^plan: solved, (\d+) module-2 links, \d+ regrasps$", out, re.M)
    assert links is not None and int(links[1]) >= 1  # the two grasps were joined by module 2
    assert re.search(r"^verify: OK$", out, re.M)
