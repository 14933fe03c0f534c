"""Execution benchmark (issue 16): export limits check and MuJoCo replay over N paper_sphere seeds.

    python scripts/bench_execution.py [--seeds 20] [--first-seed 1] [--out DIR]

Per seed: plan with ``dexplan plan --seed N`` (in-process CLI), export the
trajectory and check its limits, replay without and with gravity (palm up,
0.1 kg). Prints one line per seed and the totals; runs one process at a time.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from pathlib import Path
from typing import Any

from dexplan import cli
from dexplan.exceptions import DexplanError
from dexplan.export import build_trajectory, check_trajectory, trajectory_document
from dexplan.plan_file import hand_from_plan, read_plan
from dexplan.replay import replay_plan


def _seed_row(seed: int, out: Path) -> dict[str, Any] | None:
    """Plan (unless the plan file exists), export, check and replay one seed.

    Returns:
        The seed's row (``r`` maps gravity off/on to the replay result; None when
        the export failed), or None when planning failed.
    """
    plan = out / f"plan_{seed}.json"
    if not plan.exists():
        code = cli.run(["plan", "--seed", str(seed), "-q", "-o", str(plan)])
        if code != 0:
            print(f"seed {seed}: planning failed (exit {code})", flush=True)
            return None
    doc = read_plan(plan)
    hand = hand_from_plan(doc["hand"])
    t0 = time.perf_counter()
    try:
        traj = build_trajectory(doc, hand=hand, base_dir=out)
    except DexplanError as exc:
        print(f"seed {seed}: export failed: {exc}", flush=True)
        return dict(seed=seed, duration=math.nan, ok=False, export_s=0.0, r=None)
    problems = check_trajectory(trajectory_document(traj, doc))
    t_exp = time.perf_counter() - t0
    r = {g: replay_plan(doc, gravity=g, base_dir=out, hand=hand) for g in (False, True)}
    print(
        f"seed {seed}: duration {traj.duration:.2f} s, "
        f"limits {'OK' if not problems else problems[0]}"
        + "".join(
            f" | {'g' if g else 'no-g'}: wp {x.waypoint_position_error * 1e3:.1f} mm "
            f"{x.waypoint_angle_error:.3f} rad, goal {x.goal_position_error * 1e3:.1f} mm "
            f"{x.goal_angle_error:.3f} rad, losses {len(x.contact_losses)}, "
            f"slips {len(x.slips)}, "
            f"{'DROP' if x.dropped else 'held'}"
            for g, x in r.items()
        ),
        flush=True,
    )
    return dict(seed=seed, duration=traj.duration, ok=not problems, export_s=t_exp, r=r)


def _summary(rows: list[dict[str, Any]]) -> None:
    """Print the limit checks, execution times and replay outcomes over all seeds."""
    n = len(rows)
    print(f"plans: {n}; limits check passed: {sum(r['ok'] for r in rows)}/{n}")
    print(
        f"execution time per plan: median {statistics.median(r['duration'] for r in rows):.2f} s "
        f"(min {min(r['duration'] for r in rows):.2f}, max {max(r['duration'] for r in rows):.2f})"
    )
    for g in (False, True):
        rs = [r["r"][g] for r in rows if r["r"] is not None]
        good = sum(x.tracked and x.at_goal and not x.dropped for x in rs)
        print(
            f"replay {'with' if g else 'without'} gravity: tracked+goal+no drop {good}/{n}; "
            f"tracked {sum(x.tracked for x in rs)}/{n}; at goal {sum(x.at_goal for x in rs)}/{n}; "
            f"dropped {sum(x.dropped for x in rs)}/{n}; median waypoint error "
            f"{statistics.median(x.waypoint_position_error for x in rs) * 1e3:.1f} mm, "
            f"{statistics.median(x.waypoint_angle_error for x in rs):.3f} rad"
        )


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--out", default="bench_execution")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(exist_ok=True)
    rows = []
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        row = _seed_row(seed, out)
        if row is not None:
            rows.append(row)
    if not rows:
        return 1
    _summary(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
