"""Benchmark plots (PNG, matplotlib, the ``bench`` extra): time, success, nodes, plan quality."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Literal

from dexplan.bench.extras import require_matplotlib
from dexplan.bench.records import RunRow
from dexplan.bench.schema import DEFAULT_BASELINE, Plot
from dexplan.core.files import atomic_output

if TYPE_CHECKING:  # matplotlib's types for annotations; at run time it loads on first use
    from matplotlib.figure import Figure

#: Widest row of box-plot panels (inches) before they wrap to a new row.
_ROW_WIDTH = 24.0
#: Most (scenario, planner) cells drawn as grouped bars; more get a heat map.
_MAX_BARS = 24


def _ordered(values: Iterable[str]) -> list[str]:
    """The distinct values, in first-seen order."""
    out: list[str] = []
    for value in values:
        if value not in out:
            out.append(str(value))
    return out


@dataclass(frozen=True)
class _Grid:
    """Records by (scenario, planner), and the folder the plots go to.

    Attributes:
        plt: ``matplotlib.pyplot`` (Agg backend).
        out_dir: output folder.
        scenarios: scenario names, in first-seen order.
        planners: planner names, the baseline first.
        by: the records of each (scenario, planner).
    """

    plt: ModuleType
    out_dir: Path
    scenarios: list[str]
    planners: list[str]
    by: dict[tuple[str, str], list[RunRow]]

    def save(self, fig: Figure, name: str) -> Path:
        """Write a figure as ``out_dir/name`` (PNG, atomically) and close it."""
        path = self.out_dir / name
        with atomic_output(path, "plot") as tmp:
            fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight")
        self.plt.close(fig)
        return path


_Column = Literal[
    "time",
    "graph_states",
    "regrasps",
    "execution_time_s",
    "weakest_hold",
    "worst_torque_ratio",
]

#: The plan-quality box plots: (column, title, y label, file name); solved runs.
_QUALITY_PLOTS: tuple[tuple[_Column, str, str, Plot], ...] = (
    (
        "execution_time_s",
        "execution time per plan, toppra (solved runs)",
        "execution time (s)",
        Plot.EXECUTION_TIME,
    ),
    (
        "weakest_hold",
        "weakest hold per plan: least force-closure quality (solved runs)",
        "force-closure quality",
        Plot.WEAKEST_HOLD,
    ),
    (
        "worst_torque_ratio",
        "worst torque ratio per plan: share of the effort limits (solved runs)",
        "torque ratio",
        Plot.TORQUE_RATIO,
    ),
)


def plot_results(
    records: Sequence[RunRow],
    out_dir: str | Path,
    baseline: str | None = DEFAULT_BASELINE,
) -> list[Path]:
    """Write the benchmark plots (PNG) of some run records.

    ``bench_time.png``: box plots of planning time per planner (all runs; the
    time limit dashed), one panel per scenario. ``bench_success.png``: success
    rate per planner and scenario. ``bench_nodes.png``: box plots of roadmap
    nodes (``graph_states``). ``bench_regrasps.png``: regrasps per solved plan.
    The plan quality of solved plans: ``bench_execution_time.png`` (the
    export's execution time), ``bench_weakest_hold.png`` (the weakest hold's
    force-closure quality) and ``bench_torque_ratio.png`` (the worst torque
    ratio; 1, the effort limits, dashed).

    Returns:
        The paths written.

    Raises:
        DependencyError: matplotlib is not installed.
    """
    require_matplotlib()
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    scenarios = _ordered(r["scenario"] for r in records)
    planners = _ordered(r["planner"] for r in records)
    if baseline in planners:
        planners.remove(baseline)
        planners.insert(0, baseline)
    by = {(s, p): [r for r in records if r["scenario"] == s and r["planner"] == p]
          for s in scenarios for p in planners}  # fmt: skip
    grid = _Grid(plt, Path(out_dir), scenarios, planners, by)
    return [
        _boxes(grid, "time", "planning time per run (all runs)", "time (s)", Plot.TIME),
        _success(grid, Plot.SUCCESS),
        _boxes(grid, "graph_states", "roadmap nodes generated (all runs)", "nodes", Plot.NODES),
        _boxes(
            grid,
            "regrasps",
            "regrasps per plan (solved runs)",
            "regrasps",
            Plot.REGRASPS,
            solved_only=True,
            log=False,
        ),
        *(
            _boxes(grid, column, title, ylabel, name, solved_only=True, log=False)
            for column, title, ylabel, name in _QUALITY_PLOTS
        ),
    ]


def _boxes(
    grid: _Grid,
    column: _Column,
    title: str,
    ylabel: str,
    name: str,
    *,
    solved_only: bool = False,
    log: bool = True,
) -> Path:
    """Box plots of a column per planner, one panel per scenario, every run a point.

    Panels wrap into rows of at most :data:`_ROW_WIDTH` inches, so a sweep of
    many scenarios stays readable.
    """
    n_panels, n_planners = len(grid.scenarios), len(grid.planners)
    panel_w = 1.5 * n_planners + 0.5
    ncols = max(1, min(n_panels, int(_ROW_WIDTH // panel_w)))
    nrows = math.ceil(n_panels / ncols)
    fig, axes = grid.plt.subplots(
        nrows, ncols, figsize=(0.8 + panel_w * ncols, 4.2 * nrows), squeeze=False
    )
    for ax in axes.flat[n_panels:]:
        ax.set_visible(False)
    for ax, scen in zip(axes.flat, grid.scenarios, strict=False):
        data, labels = [], []
        for i, p in enumerate(grid.planners):
            rs = [r for r in grid.by[(scen, p)] if r.get("solved") or not solved_only]
            figures = [(r, r.get(column)) for r in rs]
            rs = [r for r, v in figures if v is not None]
            vals = [float(v) for _, v in figures if v is not None]
            data.append(vals)
            labels.append(f"{p}\n(n={len(vals)})")
            # every run as a point (deterministic jitter): solved o, unsolved x
            for j, r in enumerate(rs):
                x = i + 1 + 0.3 * ((j * 0.618034) % 1.0 - 0.5)
                ok = bool(r.get("solved"))
                ax.plot(
                    x, vals[j], "o" if ok else "x", ms=3, alpha=0.5,
                    color="tab:green" if ok else "tab:red", zorder=3,
                )  # fmt: skip
        ax.boxplot(data, showfliers=False)
        ax.set_xticks(range(1, len(labels) + 1), labels, fontsize=8)
        if column == "time":
            limits = {float(r["time_limit"]) for p in grid.planners for r in grid.by[(scen, p)]}
            for lim in limits:
                ax.axhline(lim, color="0.5", ls="--", lw=0.8)
        if column == "worst_torque_ratio":
            ax.axhline(1.0, color="tab:red", ls="--", lw=0.8)  # the effort limits
        if log and any(v > 0 for d in data for v in d if not math.isnan(v)):
            ax.set_yscale("log")
        ax.set_title(scen)
        ax.set_ylabel(ylabel)
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle(title)
    return grid.save(fig, name)


def _success(grid: _Grid, name: str) -> Path:
    """Bars of the success rate per planner, one colour per scenario, each with its n.

    Sweeps of more than :data:`_MAX_BARS` (scenario, planner) cells get a
    table-like heat map instead (scenarios by planners), which stays legible.
    """
    scenarios, planners = grid.scenarios, grid.planners
    if len(scenarios) * len(planners) > _MAX_BARS:
        return _success_map(grid, name)
    fig, ax = grid.plt.subplots(figsize=(1.5 + 1.1 * len(planners) * max(1, len(scenarios)), 3.8))
    width = 0.8 / max(1, len(scenarios))
    for k, scen in enumerate(scenarios):
        rates = []
        for p in planners:
            rs = grid.by[(scen, p)]
            rates.append(100.0 * sum(1 for r in rs if r.get("solved")) / len(rs) if rs else 0.0)
        xs = [i + (k - (len(scenarios) - 1) / 2) * width for i in range(len(planners))]
        bars = ax.bar(xs, rates, width, label=scen)
        for bar, p in zip(bars, planners, strict=True):
            n = len(grid.by[(scen, p)])
            ax.annotate(
                f"{bar.get_height():.0f}%\nn={n}",
                (bar.get_x() + bar.get_width() / 2, bar.get_height()),
                ha="center",
                va="bottom",
                fontsize=7,
            )
    ax.set_xticks(range(len(planners)), planners)
    ax.set_ylim(0, 118)
    ax.set_ylabel("success rate (%)")
    ax.set_title("solved runs (plans that passed the verifier)")
    ax.legend(
        fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=max(1, len(scenarios))
    )
    ax.grid(axis="y", alpha=0.3)
    return grid.save(fig, name)


def _success_map(grid: _Grid, name: str) -> Path:
    """Success rate of every (scenario, planner) as a coloured cell with its n."""
    scenarios, planners = grid.scenarios, grid.planners
    rates = [
        [
            100.0 * sum(1 for r in grid.by[(s, p)] if r.get("solved")) / len(grid.by[(s, p)])
            if grid.by[(s, p)]
            else float("nan")
            for p in planners
        ]
        for s in scenarios
    ]
    fig, ax = grid.plt.subplots(figsize=(2.5 + 0.9 * len(planners), 1.2 + 0.45 * len(scenarios)))
    image = ax.imshow(rates, cmap="RdYlGn", vmin=0.0, vmax=100.0, aspect="auto")
    for i, s in enumerate(scenarios):
        for j, p in enumerate(planners):
            n = len(grid.by[(s, p)])
            if n:
                ax.text(j, i, f"{rates[i][j]:.0f}%\nn={n}", ha="center", va="center", fontsize=7)
    ax.set_xticks(range(len(planners)), planners, rotation=45, ha="right", fontsize=8)
    ax.set_yticks(range(len(scenarios)), scenarios, fontsize=8)
    ax.set_title("solved runs (plans that passed the verifier)")
    fig.colorbar(image, ax=ax, label="success rate (%)", shrink=0.8)
    return grid.save(fig, name)
