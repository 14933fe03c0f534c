"""The tutorials' own files do what the tutorials say, word for word."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
MY_HAND = ROOT / "docs" / "tutorials" / "my_hand"


def dexplan(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """Run the ``dexplan`` command line in a fresh process."""
    return subprocess.run(
        [sys.executable, "-m", "dexplan.cli", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=600,
    )


def test_bring_your_own_hand_plans_and_verifies(tmp_path: Path) -> None:
    # docs/tutorials/bring_your_own_hand.md: the hand and scenario shown in full there
    scenario = MY_HAND / "my_hand_sphere.toml"
    plan_file = tmp_path / "f.json"
    res = dexplan(
        "plan",
        str(scenario),
        "--seed",
        "1",
        "--time-limit",
        "120",
        "-o",
        str(plan_file),
        cwd=tmp_path,
    )
    assert res.returncode == 0, res.stdout + res.stderr
    assert "status: solved" in res.stdout
    res = dexplan("verify", str(plan_file), cwd=tmp_path)
    assert res.returncode == 0, res.stdout + res.stderr
    assert res.stdout.startswith("OK:"), res.stdout
    # the page shows this very plan: the same scenario and seed give the same plan
    page = (ROOT / "docs" / "tutorials" / "bring_your_own_hand.md").read_text()
    assert res.stdout.strip() in page, res.stdout


def test_the_tutorial_shows_its_files_in_full() -> None:
    page = (ROOT / "docs" / "tutorials" / "bring_your_own_hand.md").read_text()
    for name in ("my_hand.urdf", "my_hand_sphere.toml"):
        text = (MY_HAND / name).read_text().strip()
        assert text in page, f"{name} is not shown in full in bring_your_own_hand.md"
