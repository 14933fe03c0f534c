"""A benchmark sweep: every (scenario, planner, seed) planned, stored, summarised and plotted.

:func:`run_benchmark` runs each task of a sweep in its own process
(:mod:`dexplan.bench.runners`), commits every run to the database as soon as it
finishes (:mod:`dexplan.bench.database`), so a sweep killed half way leaves a
usable database and running it again skips the runs already stored, then
writes the CSVs, the summary (:mod:`dexplan.bench.report`) and the plots
(:mod:`dexplan.bench.plots`) of every stored run of the sweep's scenarios,
planners and time limits.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dexplan.bench.database import BenchDatabase, code_fingerprint
from dexplan.bench.extras import require_matplotlib, require_ray
from dexplan.bench.plots import plot_results
from dexplan.bench.records import RunRecord, RunRow
from dexplan.bench.report import SummaryRow, summarize, write_csv, write_summary_csv
from dexplan.bench.runners import (
    BenchProgress,
    OnResult,
    ProgressCallback,
    check_ray_address,
    default_run_timeout,
    run_local,
    run_ray,
)
from dexplan.bench.schema import (
    CSV_NAME,
    DB_NAME,
    DEFAULT_BASELINE,
    DEFAULT_PLANNERS,
    FAILED_RUN_STATUSES,
    SUMMARY_CSV_NAME,
    Backend,
    StartMethod,
)
from dexplan.bench.tasks import (
    RunTask,
    make_tasks,
    parse_planners,
    resolve_scenario,
    scenario_files,
    scenario_hash,
    scenario_planners,
    validate_sweep,
)
from dexplan.core.errors import InvalidInputError, PlannerError
from dexplan.model.scenario import Scenario
from dexplan.planning.ompl import check_planner


@dataclass(frozen=True)
class BenchResult:
    """Outcome of :func:`run_benchmark`.

    Attributes:
        out_dir: output folder.
        database: the SQLite file.
        csv: runs CSV of the sweep.
        summary_csv: summary CSV.
        plots: PNG files written.
        records: run records of the sweep's scenarios, planners and time limits
            (new, resumed, and other seeds already in the database), ordered by
            scenario, planner, seed.
        summary: :func:`summarize` rows.
        new_runs: runs done by this call.
        skipped: runs found in the database and not run again.
        backend: ``local`` or ``ray``.
        planners: planners of the sweep (baseline included).
        counts: row counts of the database tables.
    """

    out_dir: Path
    database: Path
    csv: Path
    summary_csv: Path
    plots: list[Path]
    records: list[RunRow]
    summary: list[SummaryRow]
    new_runs: int
    skipped: int
    backend: Backend
    planners: list[str]
    counts: dict[str, int] = field(default_factory=dict)

    @property
    def failed(self) -> list[RunRow]:
        """Records of runs that failed as runs (``error``, ``crash``), not as plans.

        "No plan within the time limit" and a killed overrun are results;
        a run that raised or whose process died says nothing about the planner.
        """
        return [r for r in self.records if r.get("status_name") in FAILED_RUN_STATUSES]


def run_benchmark(
    scenarios: Sequence[str | Path | Scenario],
    planners: str | Sequence[str] = DEFAULT_PLANNERS,
    seeds: int = 10,
    time_limit: float | None = None,
    *,
    out_dir: str | Path = "bench_results",
    first_seed: int = 1,
    jobs: int | None = None,
    ray_address: str | None = None,
    baseline: str | None = DEFAULT_BASELINE,
    plots: bool = True,
    save_plans: bool = False,
    start_method: StartMethod | str = StartMethod.FORKSERVER,
    run_timeout: float | None = None,
    progress: ProgressCallback | None = None,
    params: Mapping[str, Any] | None = None,
) -> BenchResult:
    """Run (or resume) a benchmark sweep and write database, CSV, plots and summary.

    Args:
        scenarios: scenario files, builtin scenario names, or :class:`Scenario` objects.
        planners: planner names (a list, or comma-separated).
        seeds: number of seeds per (scenario, planner): ``first_seed ...``.
        time_limit: seconds per run (None: each scenario's own).
        out_dir: output folder (created if missing): ``bench.db``, ``runs.csv``,
            ``summary.csv``, ``bench_*.png`` and, with ``save_plans``, ``plans/``.
        first_seed: first seed.
        jobs: parallel runs (None: ``os.cpu_count()`` locally, the cluster's
            CPUs with Ray).
        ray_address: run on this Ray cluster (``"local"``: start one in-process).
        baseline: planner every figure is compared with; added to the sweep if
            missing (None: no ratios).
        plots: write the PNG plots.
        save_plans: write every solved plan to ``out_dir/plans``.
        start_method: ``forkserver`` or ``spawn`` (local backend).
        run_timeout: hard wall-clock seconds per run before it is killed
            (None: :func:`default_run_timeout`).
        progress: called after each finished run (and once at the start).
        params: OMPL planner parameters over each scenario's ``[planner]
            params``, for every planner of the sweep (each must declare them).

    Returns:
        A :class:`BenchResult`.

    Raises:
        InvalidInputError: bad seeds, time limit, jobs or output folder.
        PlannerError: unknown planner or baseline.
        ScenarioError: missing or invalid scenario.
        DependencyError: plots without matplotlib, or ``ray_address`` without Ray.
    """
    names, unique = _check_sweep(
        scenarios,
        planners,
        seeds,
        time_limit,
        params or {},
        first_seed=first_seed,
        jobs=jobs,
        baseline=baseline,
        plots=plots,
        ray_address=ray_address,
        run_timeout=run_timeout,
    )
    out, plan_dir = _output_folder(out_dir, save_plans)
    tasks = make_tasks(unique, names, range(first_seed, first_seed + seeds), time_limit, plan_dir)
    backend = Backend.LOCAL if ray_address is None else Backend.RAY
    execute = functools.partial(
        _execute,
        jobs=jobs,
        ray_address=ray_address,
        start_method=start_method,
        run_timeout=run_timeout,
    )
    done, skipped, names, records, counts = _run_and_read(
        out / DB_NAME, tasks, unique, seeds, backend, execute, progress
    )
    rows = summarize(records, baseline)
    return BenchResult(
        out_dir=out,
        database=out / DB_NAME,
        csv=write_csv(records, out / CSV_NAME),
        summary_csv=write_summary_csv(rows, out / SUMMARY_CSV_NAME),
        plots=plot_results(records, out, baseline) if plots and records else [],
        records=records,
        summary=rows,
        new_runs=done,
        skipped=skipped,
        backend=backend,
        planners=names,
        counts=counts,
    )


def _run_and_read(
    db_path: Path,
    tasks: list[RunTask],
    unique: list[Scenario],
    seeds: int,
    backend: Backend,
    execute: Callable[[Sequence[RunTask], OnResult], None],
    progress: ProgressCallback | None,
) -> tuple[int, int, list[str], list[RunRow], dict[str, int]]:
    """Run the sweep's new tasks; ``(done, skipped, planners, records, counts)`` of its database."""
    with BenchDatabase(db_path) as db:
        done, skipped = _run_new(db, tasks, seeds, backend, execute, progress)
        names = list(dict.fromkeys(t.planner for t in tasks))  # "default" resolved
        return done, skipped, names, _sweep_records(db, tasks, unique, names), db.counts()


def _check_sweep(
    scenarios: Sequence[str | Path | Scenario],
    planners: str | Sequence[str],
    seeds: int,
    time_limit: float | None,
    params: Mapping[str, Any],
    *,
    first_seed: int,
    jobs: int | None,
    baseline: str | None,
    plots: bool,
    ray_address: str | None,
    run_timeout: float | None,
) -> tuple[list[str], list[Scenario]]:
    """Check a sweep's arguments and load its scenarios, before any work.

    Returns:
        The planner names (the baseline first if it was missing) and the
        scenarios, one per name.

    Raises:
        InvalidInputError, PlannerError, ScenarioError, DependencyError: as
            :func:`run_benchmark`.
    """
    names = parse_planners(planners)
    added = baseline is not None and baseline not in names
    if baseline is not None and added:
        names.insert(0, baseline)
    validate_sweep(names, seeds, time_limit, first_seed=first_seed, jobs=jobs, baseline=baseline)
    if run_timeout is not None and not (math.isfinite(run_timeout) and run_timeout > 0):
        raise InvalidInputError(f"run timeout must be > 0, got {run_timeout!r}")
    unique = [_with_params(s, params) for s in _load_scenarios(scenarios)]
    for s in unique:  # planner parameters of the scenario must suit every planner
        for name in scenario_planners(s, names):
            try:
                check_planner(name, s.planner.params)
            except PlannerError as exc:
                if not (added and name == baseline):
                    raise
                raise PlannerError(
                    f"{exc} [{name} is the baseline, added to the sweep: --baseline none "
                    "leaves it out]"
                ) from exc
    if plots:
        require_matplotlib()
    if ray_address is not None:
        require_ray()
        check_ray_address(ray_address)
    return names, unique


def _with_params(scenario: Scenario, params: Mapping[str, Any]) -> Scenario:
    """``scenario`` with ``params`` over its ``[planner] params``."""
    if not params:
        return scenario
    spec = dataclasses.replace(scenario.planner, params={**scenario.planner.params, **params})
    return dataclasses.replace(scenario, planner=spec)


def _load_scenarios(scenarios: Sequence[str | Path | Scenario]) -> list[Scenario]:
    """Load the scenarios of a sweep, one per name (a name given twice is run once).

    Raises:
        InvalidInputError: no scenario, or two different scenarios of one name.
        ScenarioError: a missing or invalid scenario.
    """
    if not scenarios:
        raise InvalidInputError("give at least one scenario")
    loaded: list[Scenario] = []
    for s in scenarios:
        if isinstance(s, Scenario):
            loaded.append(s)
        else:
            loaded.extend(resolve_scenario(f) for f in scenario_files(s))
    seen: dict[str, str] = {}
    unique: list[Scenario] = []
    for s in loaded:
        digest = scenario_hash(s)
        if seen.get(s.name, digest) != digest:
            raise InvalidInputError(
                f"two different scenarios are both named {s.name!r}; rename one of them"
            )
        if s.name not in seen:
            unique.append(s)
        seen[s.name] = digest
    return unique


def _output_folder(out_dir: str | Path, save_plans: bool) -> tuple[Path, Path | None]:
    """Create the output folder (and ``plans/`` in it with ``save_plans``).

    Returns:
        The folder, and the plans folder (None without ``save_plans``).

    Raises:
        InvalidInputError: the output path exists and is not a folder.
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InvalidInputError(f"-o: {str(out)!r} exists and is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    plan_dir = None
    if save_plans:
        plan_dir = out / "plans"
        plan_dir.mkdir(exist_ok=True)
    return out, plan_dir


def _execute(
    todo: Sequence[RunTask],
    on_result: OnResult,
    *,
    jobs: int | None,
    ray_address: str | None,
    start_method: StartMethod | str,
    run_timeout: float | None,
) -> None:
    """Run tasks on the local pool (no ``ray_address``) or on Ray."""

    def timeout_of(task: RunTask) -> float:
        return run_timeout if run_timeout is not None else default_run_timeout(task.time_limit)

    if ray_address is None:
        n_jobs = min(jobs or os.cpu_count() or 1, len(todo))
        run_local(todo, n_jobs, on_result, start_method=start_method, run_timeout=timeout_of)
    else:
        run_ray(todo, ray_address, jobs, on_result, run_timeout=timeout_of)


def _run_new(
    db: BenchDatabase,
    tasks: Sequence[RunTask],
    seeds: int,
    backend: Backend,
    execute: Callable[[Sequence[RunTask], OnResult], None],
    progress: ProgressCallback | None,
) -> tuple[int, int]:
    """Run the tasks not in the database yet, storing each run as it finishes.

    Returns:
        Runs done, and runs skipped (already stored).
    """
    exp_ids = {
        (t.scenario_hash, t.time_limit): db.experiment_id(
            t.scenario, t.scenario_hash, t.time_limit, seeds
        )
        for t in tasks
    }
    planner_ids = {
        (t.scenario_hash, t.planner): db.planner_id(t.planner, t.scenario) for t in tasks
    }
    finished = db.finished_keys()
    todo = [t for t in tasks if t.key not in finished]
    skipped = len(tasks) - len(todo)
    done = 0
    say = progress or (lambda _p: None)
    say(BenchProgress(0, len(todo), skipped))
    code = code_fingerprint()

    def on_result(task: RunTask, rec: RunRecord) -> None:
        nonlocal done
        rec["backend"] = backend
        rec["code"] = code
        db.add_run(
            rec,
            exp_ids[(task.scenario_hash, task.time_limit)],
            planner_ids[(task.scenario_hash, task.planner)],
        )
        done += 1
        say(BenchProgress(done, len(todo), skipped, rec))

    if todo:
        execute(todo, on_result)
    return done, skipped


def _sweep_records(
    db: BenchDatabase, tasks: Sequence[RunTask], unique: Sequence[Scenario], names: Sequence[str]
) -> list[RunRow]:
    """Every stored run of the sweep's scenarios, planners and time limits.

    Seeds of earlier, longer sweeps into the same folder count too. Ordered by
    scenario, planner, seed.
    """
    hashes = [scenario_hash(s) for s in unique]
    combos = {(t.scenario_hash, t.planner, t.time_limit) for t in tasks}
    records = [
        r
        for r in db.records()
        if (r["scenario_hash"], r["planner"], float(r["time_limit"])) in combos
    ]
    records.sort(
        key=lambda r: (hashes.index(r["scenario_hash"]), names.index(r["planner"]), r["seed"])
    )
    return records
