"""Execution benchmark: export limits check and MuJoCo replay over N seeds.

    python scripts/bench_execution.py [--scenario NAME|TOML] [--seeds 20] [--first-seed 1]
        [--seed-list 3,9,16] [--time-limit S] [--out DIR] [--loop both|closed|open]
        [--gravity both|on|off] [--max-duration S] [--handover S]

Per seed: plan with ``dexplan plan SCENARIO --seed N`` (in-process CLI; a plan
file already in ``--out`` is reused), measure the fingertip slip the plan asks
for (per transfer and finger, the contact's path on the fingertip against its
path on the object, as ``dexplan verify``'s ``transfer_no_slip`` rule does),
export the trajectory and check its limits, then replay it in MuJoCo
(actuators at the plan's effort limits) closed loop (object-pose feedback) and
open loop (the planned joints), with gravity (palm up, the plan's mass, 0.1 kg
by default) and without. Every replay runs in a fresh process, one at a time.
Plans whose execution takes longer than ``--max-duration`` are not replayed
and say so. ``--handover`` sets each hand-over's time (0: none; the replay's
default otherwise). Prints one line per replay, then a markdown table and the totals
per loop and gravity: tracked (every waypoint within 5 mm and 0.1 rad, no
drop), lost track, dropped, and the worst waypoint error of the tracked
replays; and the largest fingertip slip of all plans.
"""

from __future__ import annotations

import argparse
import math
import multiprocessing
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from dexplan.cli import main as cli
from dexplan.core.errors import DexplanError
from dexplan.execution.check import check_trajectory
from dexplan.execution.export import trajectory_document
from dexplan.execution.replay.handover import HANDOVER_TIME
from dexplan.execution.replay.result import Loop, ReplayResult
from dexplan.execution.replay.simulation import replay_plan
from dexplan.execution.trajectory import build_trajectory
from dexplan.planfile import hand_from_plan, read_plan
from dexplan.planfile.document import segments_from_dicts
from dexplan.planfile.tip_contacts import contact_path_lengths

SCENARIOS = Path(__file__).resolve().parents[1] / "dexplan/data/scenarios"


@dataclass
class SeedRow:
    """One seed: its plan, limits check and replays (keyed by ``(loop, gravity)``)."""

    seed: int
    segments: int = 0
    motion: str = "fixed"
    slip: float = math.nan
    duration: float = math.nan
    limits: str = ""
    skipped: str = ""
    replays: dict[tuple[Loop, bool], ReplayResult] = field(default_factory=dict)


def _scenario(name: str) -> str:
    """A scenario name (builtin or suite) or a TOML path, as a path."""
    if Path(name).exists():
        return name
    for p in (SCENARIOS / f"{name}.toml", SCENARIOS / "suite" / f"{name}.toml"):
        if p.exists():
            return str(p)
    # bad input: one line naming the field and the value, exit 2 (as the CLI)
    print(f"bench_execution: error: --scenario {name!r}: no such scenario", file=sys.stderr)
    raise SystemExit(2)


def _plan(seed: int, args: argparse.Namespace, out: Path) -> Path | None:
    """The seed's plan file (planned unless it exists), or None when planning failed."""
    plan = out / f"plan_{seed}.json"
    if plan.exists():
        return plan
    argv = ["plan", _scenario(args.scenario), "--seed", str(seed), "-q", "-o", str(plan)]
    if args.time_limit is not None:
        argv += ["--time-limit", str(args.time_limit)]
    t0 = time.perf_counter()
    code = cli.run(argv)
    if code != 0:
        print(f"seed {seed}: planning failed (exit {code}, {time.perf_counter() - t0:.0f} s)")
        return None
    return plan


def _seed_row(
    seed: int, args: argparse.Namespace, out: Path, runs: list[tuple[Loop, bool]]
) -> SeedRow | None:
    """Plan, export, check and replay one seed (None when planning failed)."""
    plan = _plan(seed, args, out)
    if plan is None:
        return None
    doc = read_plan(plan)
    hand = hand_from_plan(doc["hand"])
    row = SeedRow(seed, segments=len(doc["segments"]), motion=doc.get("contact_motion", "fixed"))
    row.slip = _max_slip(doc, hand)
    try:
        traj = build_trajectory(doc, hand=hand, base_dir=out)
    except DexplanError as exc:
        row.skipped = f"export failed: {exc}"
        return row
    row.duration = traj.duration
    problems = check_trajectory(trajectory_document(traj, doc))
    row.limits = problems[0] if problems else "OK"
    if traj.duration > args.max_duration:
        row.skipped = f"not replayed: execution {traj.duration:.0f} s > {args.max_duration:g} s"
        print(f"seed {seed}: {row.skipped}", flush=True)
        return row
    for loop, g in runs:
        t0 = time.perf_counter()
        # a fresh process per replay: nothing of one run can reach the next
        ctx = multiprocessing.get_context("spawn")
        with ctx.Pool(1) as pool:
            r = pool.apply(_replay, (str(plan), loop, g, str(out), args.handover))
        row.replays[(loop, g)] = r
        print(f"seed {seed} ({time.perf_counter() - t0:.0f} s) " + r.summary().replace("\n", " |"))
        sys.stdout.flush()
    return row


def _replay(plan: str, loop: Loop, gravity: bool, out: str, handover: float) -> ReplayResult:
    """One replay of a plan file (run in its own process)."""
    doc = read_plan(plan)
    return replay_plan(
        doc, gravity=gravity, base_dir=out, feedback=loop == Loop.CLOSED, handover=handover
    )


def _max_slip(doc: dict, hand: object) -> float:
    """Largest ``|path on the fingertip - path on the object|`` (m) of any transfer contact."""
    slips = [
        abs(on_tip - on_obj)
        for seg in segments_from_dicts(doc["segments"])
        if seg.kind == "transfer"
        for _, on_tip, on_obj in contact_path_lengths(hand, seg)  # type: ignore[arg-type]
    ]
    return max(slips, default=0.0)


def _cell(r: ReplayResult) -> str:
    """``TRACKED 0.03 mm 0.5 deg``, ``LOST 4.0 mm 60.0 deg`` or the drop's where and when."""
    err = f"{r.waypoint_position_error * 1e3:.2f} mm {math.degrees(r.waypoint_angle_error):.1f} deg"
    if r.drop is not None:
        d = r.drop
        what = f"regrasp f{d.finger}" if d.kind == "regrasp" else "transfer"
        return (
            f"DROP {d.time:.1f} s seg {d.segment + 1} {what} "
            f"(hold {d.planned_hold_quality:.3f}/{d.measured_hold_quality:.3f})"
        )
    return f"{'TRACKED' if r.tracked else 'LOST'} {err}"


def _name(loop: Loop, g: bool) -> str:
    return f"{loop}, {'gravity' if g else 'no gravity'}"


def _table(rows: list[SeedRow], runs: list[tuple[Loop, bool]]) -> None:
    """A markdown table, one row per seed."""
    heads = " | ".join(_name(*k) for k in runs)
    print(f"| seed | contacts | segments | slip mm | execution s | limits | {heads} |")
    print("|---" * (6 + len(runs)) + "|")
    for row in rows:
        cells = [row.replays[k] for k in runs if k in row.replays]
        body = " | ".join(_cell(r) for r in cells) if cells else row.skipped
        print(
            f"| {row.seed} | {row.motion} | {row.segments} | {row.slip * 1e3:.2f} | "
            f"{row.duration:.1f} | {row.limits} | {body} |"
        )


def _summary(rows: list[SeedRow], runs: list[tuple[Loop, bool]]) -> None:
    """Per loop and gravity: tracked, lost track, dropped, worst tracked waypoint error."""
    n = len(rows)
    print(f"plans: {n}; limits check passed: {sum(r.limits == 'OK' for r in rows)}/{n}")
    print(f"largest fingertip slip of a transfer contact: {max(r.slip for r in rows) * 1e3:.2f} mm")
    replays = [r for row in rows for r in row.replays.values()]
    if any(r.handovers for r in replays):
        added = [r.handover_time for r in replays]
        share = max(r.handover_time / r.duration for r in replays)
        print(
            f"hand-overs add {min(added):.1f}-{max(added):.1f} s to a plan's execution "
            f"(at most {share:.0%} of it)"
        )
    skipped = [r.seed for r in rows if r.skipped]
    if skipped:
        print(f"not replayed: seeds {', '.join(map(str, skipped))}")
    for k in runs:
        rs = [row.replays[k] for row in rows if k in row.replays]
        if not rs:
            continue
        ok = [r for r in rs if r.tracked]
        worst = (
            f"{max(r.waypoint_position_error for r in ok) * 1e3:.2f} mm, "
            f"{math.degrees(max(r.waypoint_angle_error for r in ok)):.2f} deg"
            if ok
            else "none tracked"
        )
        print(
            f"{_name(*k)}: tracked {len(ok)}/{len(rs)}, lost track "
            f"{sum(not r.tracked and not r.dropped for r in rs)}/{len(rs)}, dropped "
            f"{sum(r.dropped for r in rs)}/{len(rs)} (in regrasps "
            f"{sum(r.drop is not None and r.drop.kind == 'regrasp' for r in rs)}); "
            f"worst waypoint error of the tracked: {worst}"
        )


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenario", default="paper_sphere", help="builtin/suite name or TOML")
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--seed-list", help="comma-separated seeds (overrides --seeds)")
    ap.add_argument("--time-limit", type=float, help="planning time limit (s)")
    ap.add_argument("--out", default="bench_execution")
    ap.add_argument("--loop", choices=["both", "closed", "open"], default="both")
    ap.add_argument("--gravity", choices=["both", "on", "off"], default="both")
    ap.add_argument(
        "--max-duration", type=float, default=300.0, help="skip plans executing longer (s)"
    )
    ap.add_argument(
        "--handover",
        type=float,
        default=HANDOVER_TIME,
        help=f"each hand-over's time (s), 0: none (default {HANDOVER_TIME:g})",
    )
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(exist_ok=True)
    if args.seed_list:
        seeds = [int(s) for s in args.seed_list.split(",")]
    else:
        seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    loops = [Loop.CLOSED, Loop.OPEN] if args.loop == "both" else [Loop(args.loop)]
    gravities = {"both": [True, False], "on": [True], "off": [False]}[args.gravity]
    runs = [(loop, g) for loop in loops for g in gravities]
    rows = [row for s in seeds if (row := _seed_row(s, args, out, runs)) is not None]
    print(f"planned: {len(rows)}/{len(seeds)} seeds")
    if not rows:
        return 1
    _table(rows, runs)
    _summary(rows, runs)
    return 0


if __name__ == "__main__":
    sys.exit(main())
