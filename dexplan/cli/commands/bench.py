"""``dexplan bench``: planners on scenarios; Planner Arena SQLite, CSV, plots, summary."""

from __future__ import annotations

import sys
from typing import Any

from dexplan import bench
from dexplan.bench import BenchProgress, BenchResult
from dexplan.bench.schema import StartMethod
from dexplan.bench.tasks import parse_planners
from dexplan.cli.console import ExitCode, err
from dexplan.cli.options import BenchOptions

try:
    from tqdm import tqdm
except ImportError:  # plain progress lines instead of a bar
    tqdm = None

__all__ = ["BenchProgressView", "run"]


class BenchProgressView:
    """Renders a sweep's progress on stderr: a tqdm bar, or a line per run."""

    def __init__(self, quiet: bool, note: str = "") -> None:
        self.quiet = quiet
        self.note = note  # said once the sweep's input is checked, before the first run
        self.bar: Any = None

    def __call__(self, p: BenchProgress) -> None:
        """Show one finished run (or, first, the size of the sweep)."""
        if self.quiet:
            return
        if p.record is None:
            if self.note:
                err(self.note)
            if p.skipped:
                err(f"resuming: {p.skipped} runs already in the database, {p.total} to do")
            if tqdm is not None:
                self.bar = tqdm(total=p.total, file=sys.stderr, unit="run", dynamic_ncols=True)
            return
        r, t = p.record, p.record.get("time")
        what = f"{r['scenario']} {r['planner']} seed {r['seed']}: {r['status_name']}"
        what += f" {t:.2f}s" if t is not None else ""
        if self.bar is not None:
            self.bar.set_postfix_str(what, refresh=False)
            self.bar.update(1)
        else:
            err(f"[{p.done}/{p.total}] {what}")

    def close(self) -> None:
        """Close the bar, if one was opened."""
        if self.bar is not None:
            self.bar.close()


def _sweep(opts: BenchOptions, view: BenchProgressView) -> BenchResult:
    """Run the sweep (through the package attribute, which tests replace)."""
    return bench.run_benchmark(
        list(opts.scenarios),
        opts.planners,
        opts.seeds,
        opts.time_limit,
        out_dir=opts.output,
        first_seed=opts.first_seed,
        jobs=opts.jobs,
        ray_address=opts.ray,
        baseline=opts.baseline,
        plots=opts.plots,
        save_plans=opts.save_plans,
        start_method=StartMethod(opts.start_method.value),
        run_timeout=opts.run_timeout,
        progress=view,
        params=dict(opts.params),
    )


def run(opts: BenchOptions) -> int:
    """Run (or resume) the sweep; print the summary and where everything is."""
    base, names = opts.baseline, parse_planners(opts.planners)
    note = ""
    if base is not None and base not in names and "default" not in names:
        note = f"adding the baseline planner {base} to the sweep (--baseline none leaves it out)"
    view = BenchProgressView(opts.quiet, note)
    try:
        result = _sweep(opts, view)
    finally:
        view.close()
    sys.stdout.write(bench.format_summary(result.summary, opts.baseline) + "\n")
    sys.stdout.write(
        f"runs: {result.new_runs} new, {result.skipped} resumed ({result.backend} backend)\n"
        f"database: {result.database}  (Planner Arena: upload it at plannerarena.org, or "
        f"pip install plannerarena && DATABASE={result.database} plannerarena)\n"
        f"csv: {result.csv}  summary: {result.summary_csv}\n"
    )
    for path in result.plots:
        sys.stdout.write(f"plot: {path}\n")
    failed = result.failed
    if failed:
        first = failed[0]
        err(
            f"{len(failed)} of {len(result.records)} runs failed ({first['status_name']}: "
            f"{first['scenario']} {first['planner']} seed {first['seed']}: "
            f"{str(first.get('message') or '')[:200]}); see {result.csv}"
        )
        return ExitCode.FAILED
    return ExitCode.OK
