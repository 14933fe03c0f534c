"""Reports of a sweep: the summary table (medians, success rates, ratios to a baseline), CSVs."""

from __future__ import annotations

import csv
import math
import statistics
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import TypedDict

from dexplan.bench.records import RunRow
from dexplan.bench.schema import CSV_COLUMNS, DEFAULT_BASELINE
from dexplan.core.files import atomic_output


class SummaryRow(TypedDict):
    """One row of the summary of a sweep (``summary.csv``): a planner on a scenario.

    Medians are NaN when no run gives the figure; ``*_vs_base`` divide by the
    baseline planner's figure on the same scenario (NaN without a baseline).
    The plan-quality figures (``execution_time_median`` ... ``max_grip_force_median``)
    are over solved runs: medians of the runs' figures (the rotation: of each
    run's median rotation per transfer), except ``worst_torque_ratio_max``, the
    largest.
    """

    scenario: str
    planner: str
    runs: int
    solved: int
    success_rate: float
    time_median: float
    time_solved_median: float
    cpu_time_median: float
    nodes_median: float
    components_median: float
    regrasps_median: float
    transfers_median: float
    verify_ok: int
    verify_time_median: float
    plan_verify_ratio_median: float
    memory_median: float
    execution_time_median: float
    joint_travel_median: float
    rotation_per_transfer_median: float
    regrasps_without_progress_median: float
    weakest_hold_median: float
    worst_torque_ratio_max: float
    max_grip_force_median: float
    success_rate_vs_base: float
    time_median_vs_base: float
    nodes_median_vs_base: float
    regrasps_median_vs_base: float


def _median(values: Iterable[float | None]) -> float:
    """Median of the finite values (None and NaN left out); NaN when there are none."""
    vals = [float(v) for v in values if v is not None and math.isfinite(float(v))]
    return statistics.median(vals) if vals else math.nan


def _ratio(a: float, b: float) -> float:
    """``a / b``, NaN when either is NaN or ``b`` is 0."""
    if math.isnan(a) or math.isnan(b) or b == 0:
        return math.nan
    return a / b


def summarize(
    records: Sequence[RunRow], baseline: str | None = DEFAULT_BASELINE
) -> list[SummaryRow]:
    """Per scenario and planner: success rate, medians, and ratios to the baseline.

    Medians of ``time`` and ``graph_states`` are over all runs (failed runs
    count with the time they used, as in OMPL's benchmarks); regrasps,
    transfers, verification time and the planning/verification ratio are over
    solved runs. Ratios (``*_vs_base``) divide by the baseline planner's figure
    on the same scenario (NaN without a baseline).

    Returns:
        One row per (scenario, planner), in first-seen order.
    """
    groups: dict[tuple[str, str], list[RunRow]] = {}
    for rec in records:
        groups.setdefault((str(rec["scenario"]), str(rec["planner"])), []).append(rec)
    rows: list[SummaryRow] = []
    for (scen, planner), recs in groups.items():
        solved = [r for r in recs if r.get("solved")]
        rows.append(
            {
                "scenario": scen,
                "planner": planner,
                "runs": len(recs),
                "solved": len(solved),
                "success_rate": len(solved) / len(recs),
                "time_median": _median(r.get("time") for r in recs),
                "time_solved_median": _median(r.get("time") for r in solved),
                "cpu_time_median": _median(r.get("cpu_time") for r in recs),
                "nodes_median": _median(r.get("graph_states") for r in recs),
                "components_median": _median(r.get("components") for r in recs),
                "regrasps_median": _median(r.get("regrasps") for r in solved),
                "transfers_median": _median(r.get("transfers") for r in solved),
                "verify_ok": sum(1 for r in solved if r.get("correct_solution")),
                "verify_time_median": _median(r.get("verify_time") for r in solved),
                "plan_verify_ratio_median": _median(r.get("plan_verify_ratio") for r in solved),
                "memory_median": _median(r.get("memory") for r in recs),
                **_quality_figures(solved),
                "success_rate_vs_base": math.nan,
                "time_median_vs_base": math.nan,
                "nodes_median_vs_base": math.nan,
                "regrasps_median_vs_base": math.nan,
            }
        )
    base = {row["scenario"]: row for row in rows if row["planner"] == baseline}
    for row in rows:
        b = base.get(row["scenario"])
        if b is not None:
            row["success_rate_vs_base"] = _ratio(row["success_rate"], b["success_rate"])
            row["time_median_vs_base"] = _ratio(row["time_median"], b["time_median"])
            row["nodes_median_vs_base"] = _ratio(row["nodes_median"], b["nodes_median"])
            row["regrasps_median_vs_base"] = _ratio(row["regrasps_median"], b["regrasps_median"])
    return rows


class _QualityFigures(TypedDict):
    """The plan-quality part of a :class:`SummaryRow`."""

    execution_time_median: float
    joint_travel_median: float
    rotation_per_transfer_median: float
    regrasps_without_progress_median: float
    weakest_hold_median: float
    worst_torque_ratio_max: float
    max_grip_force_median: float


def _largest(values: Iterable[float | None]) -> float:
    """The largest of the finite values (None and NaN left out); NaN when there are none."""
    vals = [float(v) for v in values if v is not None and math.isfinite(float(v))]
    return max(vals) if vals else math.nan


def _quality_figures(solved: Sequence[RunRow]) -> _QualityFigures:
    """Medians of the plan-quality columns over solved runs (the torque ratio: the largest)."""
    return {
        "execution_time_median": _median(r.get("execution_time_s") for r in solved),
        "joint_travel_median": _median(r.get("joint_travel_rad") for r in solved),
        "rotation_per_transfer_median": _median(
            r.get("rotation_per_transfer_deg_median") for r in solved
        ),
        "regrasps_without_progress_median": _median(
            r.get("regrasps_without_progress") for r in solved
        ),
        "weakest_hold_median": _median(r.get("weakest_hold") for r in solved),
        "worst_torque_ratio_max": _largest(r.get("worst_torque_ratio") for r in solved),
        "max_grip_force_median": _median(r.get("max_grip_force_n") for r in solved),
    }


def _fmt(value: object, spec: str) -> str:
    """Format a table cell; a missing or NaN value as ``-`` in the field's width."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        width = spec.split(".")[0]
        return "-".rjust(int(width) if width.isdigit() else 1)
    return format(value, spec)


def format_summary(rows: Sequence[SummaryRow], baseline: str | None = None) -> str:
    """A fixed-width text table of :func:`summarize` rows (the CLI prints it)."""
    head = (
        f"{'scenario':<16} {'planner':<11} {'runs':>4} {'solved':>7} {'x base':>6} "
        f"{'time med':>8} {'x base':>6} {'cpu med':>7} {'nodes med':>9} {'x base':>6} "
        f"{'regrasps':>8} {'transf':>6} {'verify':>6} {'plan/ver':>8} {'MB':>5}"
    )
    lines = [head, "-" * len(head)]
    for r in rows:
        mark = "*" if baseline is not None and r["planner"] == baseline else ""
        lines.append(
            f"{r['scenario'][:16]:<16} {(r['planner'] + mark)[:11]:<11} {r['runs']:>4} "
            f"{_fmt(100 * r['success_rate'], '6.0f')}% {_fmt(r['success_rate_vs_base'], '6.2f')} "
            f"{_fmt(r['time_median'], '7.2f')}s {_fmt(r['time_median_vs_base'], '6.2f')} "
            f"{_fmt(r['cpu_time_median'], '6.2f')}s "
            f"{_fmt(r['nodes_median'], '9.0f')} {_fmt(r['nodes_median_vs_base'], '6.2f')} "
            f"{_fmt(r['regrasps_median'], '8.1f')} {_fmt(r['transfers_median'], '6.1f')} "
            f"{r['verify_ok']:>3}/{r['solved']:<2} {_fmt(r['plan_verify_ratio_median'], '8.1f')} "
            f"{_fmt(r['memory_median'], '5.0f')}"
        )
    lines.append(
        "time (wall clock), cpu (processor time of the same span) and nodes: medians over "
        "all runs; regrasps, transfers, plan/verify: over solved "
        "runs; verify: plans passing dexplan verify / solved"
        + (f"; x base: ratio to {baseline} (*)" if baseline else "")
    )
    return "\n".join([*lines, "", *_quality_table(rows, baseline)])


def _quality_table(rows: Sequence[SummaryRow], baseline: str | None) -> list[str]:
    """The lines of the plan-quality table of :func:`format_summary` (solved runs)."""
    head = (
        f"{'scenario':<16} {'planner':<11} {'solved':>6} {'exec s':>7} {'travel':>7} "
        f"{'rot deg':>7} {'no-prog':>7} {'hold':>8} {'torque':>6} {'grip N':>7}"
    )
    lines = [head, "-" * len(head)]
    for r in rows:
        mark = "*" if baseline is not None and r["planner"] == baseline else ""
        lines.append(
            f"{r['scenario'][:16]:<16} {(r['planner'] + mark)[:11]:<11} {r['solved']:>6} "
            f"{_fmt(r['execution_time_median'], '7.1f')} "
            f"{_fmt(r['joint_travel_median'], '7.1f')} "
            f"{_fmt(r['rotation_per_transfer_median'], '7.1f')} "
            f"{_fmt(r['regrasps_without_progress_median'], '7.1f')} "
            f"{_fmt(r['weakest_hold_median'], '8.4f')} "
            f"{_fmt(r['worst_torque_ratio_max'], '6.2f')} "
            f"{_fmt(r['max_grip_force_median'], '7.2f')}"
        )
    lines.append(
        "plan quality, solved runs: medians of execution time (s), joint travel (rad), "
        "rotation per transfer (deg), regrasps without progress (no-prog), weakest hold "
        "(force-closure quality) and largest grip force (N); torque: the worst torque "
        "ratio (> 1: beyond the effort limits)"
    )
    return lines


def write_csv(records: Sequence[RunRow], path: str | Path) -> Path:
    """Write run records (:data:`CSV_COLUMNS`) to a CSV file, atomically."""
    return _write_table(records, list(CSV_COLUMNS), path)


def write_summary_csv(rows: Sequence[SummaryRow], path: str | Path) -> Path:
    """Write :func:`summarize` rows to a CSV file, atomically."""
    fields = list(rows[0]) if rows else ["scenario", "planner"]
    return _write_table(rows, fields, path)


def _write_table(rows: Sequence[Mapping[str, object]], fields: list[str], path: str | Path) -> Path:
    """Write the ``fields`` of some rows to a CSV file, atomically (other keys left out)."""
    path = Path(path)
    with atomic_output(path, "CSV") as tmp, open(tmp, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=fields)
        writer.writeheader()
        for row in rows:
            writer.writerow({k: _csv_value(row.get(k)) for k in fields})
    return path


def _csv_value(value: object) -> object:
    """A value as the CSV gives it: missing and NaN empty, floats in full (``repr``)."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    if isinstance(value, float):
        return repr(value)
    return value
