"""Wall time against the time limit on unsolvable queries.

Runs ``dexplan plan`` in a fresh process on an unsolvable query, once with the
builtin paper hand (tests/data/unsolvable_lid.toml) and once with the Allegro
URDF given as a custom ``urdf = ...`` hand (the same lid idea: the goal pushes
the sphere through a wall), for each time limit. Reports the planner's own
time (``time_s``), the process wall time, and start-up (imports and model
building: wall - time_s), and the ratio time_s / limit, which must be <= 1.1.

    python scripts/time_limits.py [--limits 5 20 60] [--planner PRM]
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

ALLEGRO_LID = """name = "allegro_unsolvable"
[hand]
urdf = "{urdf}"
fingertip_frames = ["link_3.0_tip", "link_7.0_tip", "link_11.0_tip", "link_15.0_tip"]
fingertip_radius = 0.012
collision_exclude = [["palm_link", "link_13.0"]]
[object]
shape = "sphere"
radius = 0.06
[contact]
mu = 0.8
[[obstacles]]   # a wall 2 cm beyond the sphere: the goal pushes the sphere into it
shape = "box"
size = [0.01, 0.3, 0.3]
pose_xyzquat = [0.19, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]
[start]         # a valid fingertip grasp of the ball, in palm_link coordinates
object_pose_xyzquat = [0.09, 0.0, -0.01, 0.0, 0.0, 0.0, 1.0]
q = [0.224, 0.8432, 0.7398, 1.5262, 1.2633, 0.4505, -0.1501, 0.9058,
     0.1159, 0.491, 0.9425, 0.4704, -0.2485, 0.4538, 1.6597, 0.6968]
[goal]
object_pose_xyzquat = [0.11, 0.0, -0.01, 1.0, 0.0, 0.0, 0.0]
[planner]
name = "PRM"
time_limit = 30.0
"""


def allegro_urdf() -> Path:
    from dexplan.model.hand.builtin import example_robot_data_file

    return example_robot_data_file("allegro_hand_description/urdf/allegro_right_hand.urdf")


def run(scenario: Path, limit: float, planner: str) -> tuple[float, float, int]:
    cmd = [
        sys.executable,
        "-m",
        "dexplan.cli",
        "plan",
        str(scenario),
        "--time-limit",
        str(limit),
    ]
    cmd += ["--planner", planner, "-q", "-o", str(scenario.with_suffix(".json"))]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    m = re.search(r"time_s: ([0-9.]+)", proc.stdout)
    if m is None:
        sys.exit(f"unexpected output (exit {proc.returncode}): {proc.stdout} {proc.stderr}")
    return float(m.group(1)), wall, proc.returncode


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--limits", type=float, nargs="+", default=[5.0, 20.0, 60.0])
    ap.add_argument("--planner", default="PRM")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        allegro = Path(tmp) / "allegro_lid.toml"
        allegro.write_text(ALLEGRO_LID.format(urdf=allegro_urdf()))
        cases = [("paper (builtin)", ROOT / "tests" / "data" / "unsolvable_lid.toml")]
        cases.append(("allegro (custom URDF)", allegro))
        print("| hand | limit (s) | time_s | ratio | wall (s) | start-up (s) | exit |")
        print("|---|---|---|---|---|---|---|")
        for name, path in cases:
            for limit in args.limits:
                t, wall, code = run(path, limit, args.planner)
                print(
                    f"| {name} | {limit:g} | {t:.2f} | {t / limit:.3f} | {wall:.2f} "
                    f"| {wall - t:.2f} | {code} |",
                    flush=True,
                )


if __name__ == "__main__":
    main()
