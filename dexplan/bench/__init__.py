"""Planner benchmarks: sweeps of scenarios x planners x seeds, in OMPL's language.

:func:`run_benchmark` plans every (scenario, planner, seed) of a sweep, each in
its own process, reads the verifier's verdict and time on every plan, and
stores one row per run in an SQLite database in the schema of OMPL's Planner
Arena, committed as soon as the run finishes (a sweep run again skips the runs
already stored). It also writes a CSV file, PNG plots and a summary with
medians, success rates and ratios against a baseline planner; every solved
run's plan quality (:mod:`dexplan.execution.quality`) has columns, a summary
table and plots of its own.

The package, along its seams:

- :mod:`~dexplan.bench.schema`: output names, statuses, stages, run columns, SQL
  schema; the closed sets of names are StrEnums (:class:`RunStatus`, ...).
- :mod:`~dexplan.bench.tasks`: scenarios resolved and hashed, run tasks, resume keys.
- :mod:`~dexplan.bench.records` and :mod:`~dexplan.bench.worker`: one run, in a
  worker process, and the record it returns.
- :mod:`~dexplan.bench.database`: the Planner Arena database.
- :mod:`~dexplan.bench.runners`: the local process pool and the Ray backend.
- :mod:`~dexplan.bench.report` and :mod:`~dexplan.bench.plots`: summary, CSVs, plots.
- :mod:`~dexplan.bench.extras`: the optional dependencies (matplotlib, Ray).
- :mod:`~dexplan.bench.sweep`: :func:`run_benchmark`.

The package never prints: progress goes to a callback and the CLI owns output.
It does not import ``ompl`` (only the :mod:`dexplan.planning.ompl` package does).
"""

from __future__ import annotations

from dexplan.bench.database import BenchDatabase, code_fingerprint
from dexplan.bench.extras import require_matplotlib
from dexplan.bench.plots import plot_results
from dexplan.bench.records import RunRecord, RunRow, failure_record, segments_sha256
from dexplan.bench.report import (
    SummaryRow,
    format_summary,
    summarize,
    write_csv,
    write_summary_csv,
)
from dexplan.bench.runners import BenchProgress, ProgressCallback, default_run_timeout
from dexplan.bench.schema import (
    CSV_COLUMNS,
    CSV_NAME,
    DB_NAME,
    DEFAULT_BASELINE,
    DEFAULT_PLANNERS,
    FAILED_RUN_STATUSES,
    IDENTITY_COLUMNS,
    OMPL_STATUSES,
    PLAN_STATUSES,
    PLOT_NAMES,
    QUALITY_COLUMNS,
    REDUCTION_METHODS,
    RUN_COLUMNS,
    STAGE_NAMES,
    STAGES,
    SUMMARY_CSV_NAME,
    Backend,
    Plot,
    ReductionMethod,
    RunStatus,
    StartMethod,
)
from dexplan.bench.sweep import BenchResult, run_benchmark
from dexplan.bench.tasks import (
    PlannerWord,
    RunTask,
    make_tasks,
    resolve_scenario,
    run_key,
    validate_sweep,
)
from dexplan.bench.worker import execute_run
from dexplan.model.scenario import scenario_description, scenario_hash

__all__ = [
    "CSV_COLUMNS",
    "CSV_NAME",
    "DB_NAME",
    "DEFAULT_BASELINE",
    "DEFAULT_PLANNERS",
    "FAILED_RUN_STATUSES",
    "IDENTITY_COLUMNS",
    "OMPL_STATUSES",
    "PLAN_STATUSES",
    "PLOT_NAMES",
    "QUALITY_COLUMNS",
    "REDUCTION_METHODS",
    "RUN_COLUMNS",
    "STAGES",
    "STAGE_NAMES",
    "SUMMARY_CSV_NAME",
    "Backend",
    "BenchDatabase",
    "BenchProgress",
    "BenchResult",
    "PlannerWord",
    "Plot",
    "ProgressCallback",
    "ReductionMethod",
    "RunRecord",
    "RunRow",
    "RunStatus",
    "RunTask",
    "StartMethod",
    "SummaryRow",
    "code_fingerprint",
    "default_run_timeout",
    "execute_run",
    "failure_record",
    "format_summary",
    "make_tasks",
    "plot_results",
    "require_matplotlib",
    "resolve_scenario",
    "run_benchmark",
    "run_key",
    "scenario_description",
    "scenario_hash",
    "segments_sha256",
    "summarize",
    "validate_sweep",
    "write_csv",
    "write_summary_csv",
]
