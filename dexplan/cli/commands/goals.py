"""Many-goal ``dexplan plan`` (``--goals``, ``--random-goals``): one query per goal.

Every goal is answered in this process, on the loaded roadmap if there is one
(which then grows with each query); each plan goes to ``query_NNN.json`` in
the output folder, a row per query to ``summary.csv`` and a table to stdout.
"""

from __future__ import annotations

import csv
import dataclasses
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from dexplan.api import Plan, plan
from dexplan.cli import interrupt
from dexplan.cli.console import ExitCode, err, quiet_progress
from dexplan.cli.options import PlanOptions
from dexplan.core.errors import InvalidInputError
from dexplan.core.files import atomic_output
from dexplan.model.hand.hand import Hand
from dexplan.model.scenario import GoalSpec, Scenario
from dexplan.model.scenario.goals import load_goals, random_goals
from dexplan.planfile import write_plan
from dexplan.planning.context import PlanningContext
from dexplan.planning.roadmap.graph import Roadmap

__all__ = ["SUMMARY_FIELDS", "QueryRow", "format_table", "output_dir", "query_goals", "run_queries"]


@dataclass(frozen=True)
class QueryRow:
    """One query's row of ``summary.csv`` and of the stdout table.

    Attributes:
        query: its number, from 1.
        status: how it ended (a :class:`~dexplan.planning.progress.PlanStatus`).
        solved: 1 if solved, else 0.
        time_s: wall-clock seconds of the query; cpu_s: process CPU seconds.
        gsn_time_s, reduction_time_s, verify_time_s: seconds per stage.
        regrasps, transfers: segments of the plan.
        gsn_status: how module 1 ended.
        plan: the plan file's name in the folder ("" when none was written).
    """

    query: int
    status: str
    solved: int
    time_s: float
    cpu_s: float
    gsn_time_s: float | None
    reduction_time_s: float | None
    verify_time_s: float | None
    regrasps: int | None
    transfers: int | None
    gsn_status: str | None
    plan: str


SUMMARY_FIELDS = tuple(f.name for f in dataclasses.fields(QueryRow))
"""Columns of ``summary.csv`` (one row per query)."""


def query_goals(
    opts: PlanOptions, scenario: Scenario, context: Callable[[], PlanningContext]
) -> list[GoalSpec]:
    """The goals of ``--goals`` or ``--random-goals`` (checked).

    Random goal poses where the object alone meets an obstacle are drawn
    again; ``context`` gives the planning context whose world says so.
    """
    if opts.goals is not None:
        return load_goals(opts.goals, scenario.goal)
    assert opts.random_goals is not None
    seed = scenario.planner.seed if opts.seed is None else opts.seed
    world = context().world
    return random_goals(
        scenario,
        opts.random_goals,
        seed,
        opts.goal_kind.value,
        lambda p: not world.object_collides(p),
    )


def output_dir(opts: PlanOptions) -> Path:
    """The folder of a many-goal ``plan`` (``-o``, default ``queries``), created."""
    out = Path(opts.output or "queries")
    if out.suffix.lower() == ".json":
        raise InvalidInputError(
            f"-o: with several queries -o is a folder for query_NNN.json and summary.csv, "
            f"got {str(out)!r}"
        )
    if out.exists() and not out.is_dir():
        raise InvalidInputError(f"-o: {str(out)!r} exists and is not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InvalidInputError(f"-o: cannot create the folder {str(out)!r}: {exc}") from exc
    return out


def run_queries(
    opts: PlanOptions,
    scenario: Scenario,
    hand: Hand,
    roadmap: Roadmap | None,
    goals: Sequence[GoalSpec],
    out: Path,
) -> int:
    """Answer every goal in this process; write the plans, summary.csv and the table."""
    mode = "the roadmap" if roadmap is not None else "single-query planning"
    if not opts.quiet:
        err(f"answering {len(goals)} queries of {scenario.name!r} with {mode}")
    rows = []
    for k, goal in enumerate(goals, start=1):
        scen = dataclasses.replace(scenario, goal=goal)
        cpu0 = time.process_time()
        planned = plan(
            scen,
            planner=opts.planner,
            seed=opts.seed,
            time_limit=opts.time_limit,
            roadmap=roadmap,
            progress=quiet_progress,
            reduction=opts.reduction.value,
            hand=hand,
        )
        cpu = time.process_time() - cpu0
        interrupt.check()
        rows.append(_write_query(out, k, planned, cpu))
        if not opts.quiet:
            err(f"query {k}/{len(goals)}: {rows[-1].status} in {rows[-1].time_s:.3f} s")
    if opts.save_roadmap is not None and roadmap is not None:
        roadmap.save(opts.save_roadmap)
        if not opts.quiet:
            err(f"roadmap written to {opts.save_roadmap}")
    _write_summary(out / "summary.csv", rows)
    sys.stdout.write(format_table(rows) + f"plans: {out}  summary: {out / 'summary.csv'}\n")
    return ExitCode.OK if all(r.solved for r in rows) else ExitCode.FAILED


def _write_query(out: Path, k: int, planned: Plan, cpu_s: float) -> QueryRow:
    """Write one query's plan file (solved or failed verification); its summary row."""
    result = planned.result
    st = result.stats
    name = ""
    if result.segments:
        path = out / (f"query_{k:03d}.json" if result.solved else f"query_{k:03d}.invalid.json")
        doc = planned.to_document(out.resolve())
        if not result.solved:
            doc["stats"]["violations"] = list(result.violations)
        write_plan(path, doc)
        name = path.name
    return QueryRow(
        query=k,
        status=str(result.status),
        solved=int(result.solved),
        time_s=st.time_s,
        cpu_s=cpu_s,
        gsn_time_s=st.gsn_time_s,
        reduction_time_s=st.reduction_time_s,
        verify_time_s=st.verify_time_s,
        regrasps=st.regrasps,
        transfers=st.transfers,
        gsn_status=st.gsn_status,
        plan=name,
    )


def _write_summary(path: Path, rows: Sequence[QueryRow]) -> None:
    with atomic_output(path, "summary") as tmp, open(tmp, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=SUMMARY_FIELDS)
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if v is None else v) for k, v in dataclasses.asdict(r).items()})


def format_table(rows: Sequence[QueryRow]) -> str:
    """The stdout table: one line per query, then solved count and time quantiles."""
    head = f"{'query':>5}  {'status':<16} {'time_s':>8} {'cpu_s':>8} {'regrasps':>8}  roadmap"
    lines = [head]
    for r in rows:
        reg = "-" if r.regrasps is None else str(r.regrasps)
        lines.append(
            f"{r.query:>5}  {r.status:<16} {r.time_s:>8.3f} {r.cpu_s:>8.3f} "
            f"{reg:>8}  {r.gsn_status or '-'}"
        )
    times = [r.time_s for r in rows]
    cpu = [r.cpu_s for r in rows]
    solved = sum(r.solved for r in rows)
    lines.append(
        f"solved: {solved}/{len(rows)}  time_s median {statistics.median(times):.3f}  "
        f"mean {statistics.fmean(times):.3f}  max {max(times):.3f}  "
        f"cpu_s median {statistics.median(cpu):.3f}"
    )
    return "\n".join(lines) + "\n"
