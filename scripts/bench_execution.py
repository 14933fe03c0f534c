"""Execution benchmark: export limits check and MuJoCo replay over N seeds.

    python scripts/bench_execution.py [--scenario TOML] [--seeds 20] [--first-seed 1]
        [--seed-list 3,9,16] [--time-limit S] [--out DIR] [--open-loop]

Per seed: plan with ``dexplan plan SCENARIO --seed N`` (in-process CLI; a plan
file already in ``--out`` is reused), export the trajectory and check its
limits, replay without and with gravity (palm up, the plan's mass, 0.1 kg by
default) with the object-pose feedback (``--open-loop``: the planned joints
only). Prints one line per seed, then a markdown table and the totals; runs
one process at a time.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from pathlib import Path
from typing import Any

from dexplan.cli import main as cli
from dexplan.core.errors import DexplanError
from dexplan.execution.check import check_trajectory
from dexplan.execution.export import trajectory_document
from dexplan.execution.replay.simulation import replay_plan
from dexplan.execution.trajectory import build_trajectory
from dexplan.planfile import hand_from_plan, read_plan

PAPER = str(Path(__file__).resolve().parents[1] / "dexplan/data/scenarios/paper_sphere.toml")


def _good(x: Any) -> bool:
    """Within 5 mm and 0.1 rad at every waypoint, at the goal, not dropped."""
    return bool(x.tracked and x.at_goal and not x.dropped)


def _plan(seed: int, args: argparse.Namespace, out: Path) -> Path | None:
    """The seed's plan file (planned unless it exists), or None when planning failed."""
    plan = out / f"plan_{seed}.json"
    if plan.exists():
        return plan
    argv = ["plan", args.scenario, "--seed", str(seed), "-q", "-o", str(plan)]
    if args.time_limit is not None:
        argv += ["--time-limit", str(args.time_limit)]
    t0 = time.perf_counter()
    code = cli.run(argv)
    if code != 0:
        print(
            f"seed {seed}: planning failed (exit {code}, {time.perf_counter() - t0:.0f} s)",
            flush=True,
        )
        return None
    return plan


def _seed_row(seed: int, args: argparse.Namespace, out: Path) -> dict[str, Any] | None:
    """Plan, export, check and replay one seed.

    Returns:
        The seed's row (``r`` maps gravity off/on to the replay result; None when
        the export failed), or None when planning failed.
    """
    plan = _plan(seed, args, out)
    if plan is None:
        return None
    doc = read_plan(plan)
    hand = hand_from_plan(doc["hand"])
    try:
        traj = build_trajectory(doc, hand=hand, base_dir=out)
    except DexplanError as exc:
        print(f"seed {seed}: export failed: {exc}", flush=True)
        return dict(seed=seed, duration=math.nan, ok=False, problem=str(exc), r=None)
    problems = check_trajectory(trajectory_document(traj, doc))
    r = {}
    for g in (False, True):
        t0 = time.perf_counter()
        r[g] = replay_plan(doc, gravity=g, base_dir=out, hand=hand, feedback=not args.open_loop)
        print(
            f"seed {seed} {'gravity' if g else 'no gravity'} ({time.perf_counter() - t0:.0f} s): "
            + r[g].summary().replace("\n", " | "),
            flush=True,
        )
    return dict(
        seed=seed,
        duration=traj.duration,
        ok=not problems,
        problem=problems[0] if problems else "",
        segments=len(doc["segments"]),
        r=r,
    )


def _cell(x: Any) -> str:
    return (
        f"{x.waypoint_position_error * 1e3:.2f} mm {x.waypoint_angle_error:.3f} rad; goal "
        f"{x.goal_position_error * 1e3:.2f} mm {x.goal_angle_error:.3f} rad; "
        f"{len(x.contact_losses)} losses; "
        + ("DROP" if x.dropped else "PASS" if _good(x) else "fail")
    )


def _table(rows: list[dict[str, Any]]) -> None:
    """A markdown table, one row per seed."""
    print(
        "| seed | segments | duration s | limits | no gravity (max at waypoints; goal) | gravity |"
    )
    print("|---|---|---|---|---|---|")
    for row in rows:
        if row["r"] is None:
            print(f"| {row['seed']} | | | export failed: {row['problem']} | | |")
            continue
        lim = "OK" if row["ok"] else row["problem"]
        print(
            f"| {row['seed']} | {row['segments']} | {row['duration']:.2f} | {lim} | "
            f"{_cell(row['r'][False])} | {_cell(row['r'][True])} |"
        )


def _summary(rows: list[dict[str, Any]]) -> None:
    """Print the limit checks, execution times and replay outcomes over all seeds."""
    n = len(rows)
    durations = [r["duration"] for r in rows if r["r"] is not None]
    print(f"plans: {n}; limits check passed: {sum(r['ok'] for r in rows)}/{n}")
    if durations:
        print(
            f"execution time per plan: median {statistics.median(durations):.2f} s "
            f"(min {min(durations):.2f}, max {max(durations):.2f})"
        )
    for g in (False, True):
        rs = [r["r"][g] for r in rows if r["r"] is not None]
        if not rs:
            continue
        print(
            f"replay {'with' if g else 'without'} gravity: within 5 mm / 0.1 rad at every "
            f"waypoint + at goal + no drop {sum(_good(x) for x in rs)}/{n}; "
            f"tracked {sum(x.tracked for x in rs)}/{n}; at goal {sum(x.at_goal for x in rs)}/{n}; "
            f"dropped {sum(x.dropped for x in rs)}/{n}; median max waypoint error "
            f"{statistics.median(x.waypoint_position_error for x in rs) * 1e3:.2f} mm, "
            f"{statistics.median(x.waypoint_angle_error for x in rs):.3f} rad"
        )


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenario", default=PAPER)
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--seed-list", help="comma-separated seeds (overrides --seeds)")
    ap.add_argument("--time-limit", type=float, help="planning time limit (s)")
    ap.add_argument("--out", default="bench_execution")
    ap.add_argument("--open-loop", action="store_true", help="replay without object feedback")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(exist_ok=True)
    if args.seed_list:
        seeds = [int(s) for s in args.seed_list.split(",")]
    else:
        seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    rows = [row for s in seeds if (row := _seed_row(s, args, out)) is not None]
    if not rows:
        return 1
    _table(rows)
    _summary(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
