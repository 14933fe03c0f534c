"""Planner benchmarks: sweeps of scenarios x planners x seeds, in OMPL's language.

:func:`run_benchmark` plans every (scenario, planner, seed) of a sweep, each in
its **own process** (OMPL's random generator is process-global and PRM solves
with two threads, so runs that share a process are neither independent nor
reproducible), times ``dexplan verify`` on every plan, and stores one row per
run in an SQLite database in the schema of OMPL's Planner Arena
(``ompl_benchmark_statistics.py``: tables ``experiments``, ``plannerConfigs``,
``enums``, ``runs``, ``progress`` and the ``bestPlannerConfigs*`` views), with
dexplan's bookkeeping in two extra tables (``dexplan_experiments``,
``dexplan_runs``). It also writes a CSV file, PNG plots (matplotlib) and a
summary with medians, success rates and ratios against a baseline planner.

Every run is committed as soon as it finishes, so a sweep killed half way
leaves a usable database, and running the same sweep again skips the runs that
are already in it (key: scenario name and content hash, planner, seed, time
limit).

Backends: a local pool of worker processes (``forkserver`` by default, with the
planning modules preloaded; ``spawn`` on request), or a Ray cluster
(``ray_address``; ``"local"`` starts one in-process). Each Ray task runs in a
fresh worker process too (``max_calls=1``), so a seed gives the same plan
whichever backend ran it, for the planners that are deterministic (see
``docs/benchmarks.md``).

This module never prints: progress goes to a callback and the CLI owns output.
It does not import ``ompl`` (only the :mod:`dexplan.planning.ompl` package does).
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import json
import math
import multiprocessing
import os
import platform
import resource
import signal
import socket
import sqlite3
import statistics
import time
from collections import deque
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from multiprocessing.connection import Connection
from multiprocessing.connection import wait as wait_connections
from pathlib import Path
from typing import Any

from dexplan.exceptions import DependencyError, InvalidInputError, PlannerError, ScenarioError
from dexplan.files import atomic_output, file_sha256
from dexplan.planning.plan_stats import PlanStats
from dexplan.planning.progress import ProgressEvent, Stage
from dexplan.scenario import Scenario, builtin_scenario_path, load_scenario

__all__ = [
    "DEFAULT_BASELINE",
    "DEFAULT_PLANNERS",
    "PLAN_STATUSES",
    "REDUCTION_METHODS",
    "RUN_COLUMNS",
    "BenchDatabase",
    "BenchProgress",
    "BenchResult",
    "RunTask",
    "execute_run",
    "format_summary",
    "make_tasks",
    "plot_results",
    "resolve_scenario",
    "run_benchmark",
    "scenario_hash",
    "summarize",
    "write_csv",
]

DEFAULT_PLANNERS: tuple[str, ...] = ("PRM", "RRTConnect", "KPIECE1")
"""Planners of ``dexplan bench`` when none are given."""

DEFAULT_BASELINE = "PRM"
"""The paper's configuration: every figure is also given as a ratio to it."""

DB_NAME = "bench.db"
CSV_NAME = "runs.csv"
SUMMARY_CSV_NAME = "summary.csv"
PLOT_NAMES: tuple[str, ...] = (
    "bench_time.png",
    "bench_success.png",
    "bench_nodes.png",
    "bench_regrasps.png",
)

# ------------------------------------------------------------------ statuses

OMPL_STATUSES: tuple[str, ...] = (
    "Unknown status",
    "Invalid start",
    "Invalid goal",
    "Unrecognized goal type",
    "Timeout",
    "Approximate solution",
    "Exact solution",
    "Crash",
    "Abort",
    "Infeasible",
)
"""``ompl::base::PlannerStatus`` names by value, as OMPL's Benchmark writes the
``status`` enum (the 2.0.1 wheel's ``asString`` says "Unknown status" for Abort
and Infeasible; the upstream names are used here)."""

FAILED_RUN_STATUSES = frozenset({"error", "crash"})
"""Statuses of runs that failed as runs (see :attr:`BenchResult.failed`)."""

PLAN_STATUSES: tuple[str, ...] = (
    "solved",
    "no_start_grasp",
    "no_goal_grasp",
    "no_gsn_path",
    "reduction_failed",
    "invalid_plan",
    "error",
    "crash",
    "killed",
)
"""dexplan run outcomes, in the order of the ``plan status`` enum: the planner's
statuses, then ``error`` (the run raised), ``crash`` (the worker process died)
and ``killed`` (the run overran its hard wall-clock limit)."""

REDUCTION_METHODS: tuple[str, ...] = ("gaits", "edges")
"""How a solved run's GSn path became transfers and regrasps, in the order of
the ``reduction method`` enum (see :func:`dexplan.planning.planner.plan`)."""

_OMPL_STATUS_OF: dict[str, int] = {
    "solved": 6,  # Exact solution
    "no_start_grasp": 1,  # Invalid start
    "no_goal_grasp": 2,  # Invalid goal
    "no_gsn_path": 4,  # Timeout
    "reduction_failed": 4,  # the reduction retries until the deadline
    "invalid_plan": 5,  # Approximate solution: a plan that fails the verifier
    "error": 8,  # Abort
    "crash": 7,  # Crash
    "killed": 7,  # OMPL's Benchmark calls an overrunning planner a crash too
}

# Progress stages (the ``stage`` column of the ``progress`` table), by
# dexplan.planning.progress.Stage value.
STAGES: tuple[str, ...] = (
    "setup",
    "start grasp",
    "module 1 (GSn exploration)",
    "module 2 (component links)",
    "reduction",
    "verification",
    "done",
)

# ------------------------------------------------------------------ columns

RUN_COLUMNS: tuple[tuple[str, str], ...] = (
    # OMPL Benchmark's names and meanings
    ("time", "REAL"),  # seconds in plan() (module 1 + module 2 + reduction + its verify)
    ("memory", "REAL"),  # peak resident set of the worker process, MB
    ("status", "ENUM"),  # ompl::base::PlannerStatus
    ("solved", "BOOLEAN"),
    ("correct_solution", "BOOLEAN"),  # dexplan verify on the plan
    ("graph_states", "INTEGER"),  # roadmap (PlannerData) vertices: generated nodes
    ("graph_motions", "INTEGER"),  # roadmap edges
    ("solution_segments", "INTEGER"),  # transfer + regrasp segments
    # dexplan
    ("seed", "INTEGER"),
    ("plan_status", "ENUM"),  # PLAN_STATUSES
    ("gsn_time", "REAL"),
    ("reduction_time", "REAL"),
    ("verify_time", "REAL"),  # dexplan verify, timed separately on the plan
    ("verify_violations", "INTEGER"),
    ("plan_verify_ratio", "REAL"),  # time / verify_time
    ("components", "INTEGER"),
    ("graph_nodes", "INTEGER"),  # nodes of the transfer/regrasp plan graph
    ("module2_attempts", "INTEGER"),
    ("module2_links", "INTEGER"),
    ("reduction_attempts", "INTEGER"),
    ("reduction_method", "ENUM"),  # REDUCTION_METHODS
    ("regrasps", "INTEGER"),
    ("transfers", "INTEGER"),
    ("waypoints", "INTEGER"),
    ("object_path_m", "REAL"),
    ("object_path_rad", "REAL"),
    ("states_checked", "INTEGER"),
    ("states_valid", "INTEGER"),
    ("rejected_bounds", "INTEGER"),
    ("rejected_joint_limits", "INTEGER"),
    ("rejected_collision", "INTEGER"),
    ("rejected_force_closure", "INTEGER"),
    ("sampler_attempts", "INTEGER"),
    ("sampler_valid", "INTEGER"),
    ("wall_time", "REAL"),  # seconds in the worker process, setup included
)
"""Columns of the ``runs`` table after ``id, experimentid, plannerid``: name and
the type OMPL's log format gives it (``REAL``, ``INTEGER``, ``BOOLEAN``, ``ENUM``)."""

IDENTITY_COLUMNS: tuple[str, ...] = (
    "scenario",
    "scenario_hash",
    "planner",
    "time_limit",
    "status_name",
    "message",
    "plan_sha256",
    "backend",
    "host",
    "code",
)
"""Per-run identity and text fields (``dexplan_runs``), first in every CSV row."""

CSV_COLUMNS: tuple[str, ...] = IDENTITY_COLUMNS + tuple(name for name, _ in RUN_COLUMNS)

_SCHEMA = """
CREATE TABLE IF NOT EXISTS experiments
    (id INTEGER PRIMARY KEY AUTOINCREMENT, name VARCHAR(512),
    totaltime REAL, timelimit REAL, memorylimit REAL, runcount INTEGER,
    version VARCHAR(128), hostname VARCHAR(1024), cpuinfo TEXT,
    date DATETIME, seed VARCHAR(24), setup TEXT);
CREATE TABLE IF NOT EXISTS plannerConfigs
    (id INTEGER PRIMARY KEY AUTOINCREMENT,
    name VARCHAR(512) NOT NULL, settings TEXT);
CREATE TABLE IF NOT EXISTS enums
    (name VARCHAR(512), value INTEGER, description TEXT,
    PRIMARY KEY (name, value));
CREATE TABLE IF NOT EXISTS runs
    (id INTEGER PRIMARY KEY AUTOINCREMENT, experimentid INTEGER, plannerid INTEGER,
    FOREIGN KEY (experimentid) REFERENCES experiments(id) ON DELETE CASCADE,
    FOREIGN KEY (plannerid) REFERENCES plannerConfigs(id) ON DELETE CASCADE);
CREATE TABLE IF NOT EXISTS progress
    (runid INTEGER, time REAL, PRIMARY KEY (runid, time),
    FOREIGN KEY (runid) REFERENCES runs(id) ON DELETE CASCADE);
CREATE TABLE IF NOT EXISTS dexplan_experiments
    (experimentid INTEGER PRIMARY KEY, scenario TEXT NOT NULL, scenario_hash TEXT NOT NULL,
    time_limit REAL NOT NULL, UNIQUE (scenario, scenario_hash, time_limit),
    FOREIGN KEY (experimentid) REFERENCES experiments(id) ON DELETE CASCADE);
CREATE TABLE IF NOT EXISTS dexplan_runs
    (runid INTEGER PRIMARY KEY, key TEXT NOT NULL UNIQUE, scenario TEXT, scenario_hash TEXT,
    planner TEXT, seed INTEGER, time_limit REAL, status TEXT, message TEXT, plan_sha256 TEXT,
    backend TEXT, host TEXT, finished TEXT, stats_json TEXT, code TEXT,
    FOREIGN KEY (runid) REFERENCES runs(id) ON DELETE CASCADE);
"""

# The views ompl_benchmark_statistics.py creates (runs have no simplification_time).
_VIEWS = {
    "bestPlannerConfigsPerExperiment": """
        SELECT plannerid, experimentid, MIN(avg_solved) AS avg_solved, avg_total_time
        FROM (SELECT plannerid, plannerName, experimentid, AVG(solved) AS avg_solved,
              AVG(total_time) AS avg_total_time
              FROM (SELECT plannerid, plannerConfigs.name AS plannerName, experimentid,
                    solved, time AS total_time
                    FROM plannerConfigs INNER JOIN experiments INNER JOIN runs
                    ON plannerConfigs.id=runs.plannerid AND experiments.id=runs.experimentid)
              GROUP BY plannerid, experimentid)
        GROUP BY plannerName, experimentid ORDER BY avg_solved DESC, avg_total_time ASC""",
    "bestPlannerConfigs": """
        SELECT plannerid, MIN(avg_solved) AS avg_solved, avg_total_time
        FROM (SELECT plannerid, plannerName, AVG(solved) AS avg_solved,
              AVG(total_time) AS avg_total_time
              FROM (SELECT plannerid, plannerConfigs.name AS plannerName, experimentid,
                    solved, time AS total_time
                    FROM plannerConfigs INNER JOIN experiments INNER JOIN runs
                    ON plannerConfigs.id=runs.plannerid AND experiments.id=runs.experimentid)
              GROUP BY plannerid)
        GROUP BY plannerName ORDER BY avg_solved DESC, avg_total_time ASC""",
}


# ------------------------------------------------------------------ scenarios and tasks


def resolve_scenario(arg: str | Path) -> Scenario:
    """Load a scenario from a TOML path, or a builtin scenario by name.

    Args:
        arg: a scenario file, or the name of a builtin scenario (``paper_sphere``).

    Raises:
        ScenarioError: no such file or builtin scenario, or an invalid scenario.
    """
    path = Path(arg)
    if path.is_file():
        return load_scenario(path)
    if path.suffix == "" and path.name == str(arg):
        try:
            return load_scenario(builtin_scenario_path(str(arg)))
        except ScenarioError as exc:
            raise ScenarioError(
                f"scenario file not found: {str(arg)!r}, and it is not a builtin scenario ({exc})"
            ) from exc
    raise ScenarioError(f"scenario file not found: {str(arg)!r}")


def _canonical(value: Any) -> Any:
    """JSON-ready view of scenario fields (arrays as lists, paths as strings)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _canonical(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, Mapping):
        return {str(k): _canonical(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_canonical(v) for v in value]
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    return value


def _file_digest(path: Path) -> str:
    try:
        return file_sha256(path)
    except OSError:
        return f"unreadable:{path}"


def scenario_description(scenario: Scenario) -> dict[str, Any]:
    """The fields of a scenario that decide its runs, as plain JSON values.

    The folder of the file, and the planner name, seed and time limit (a sweep
    sets them) are left out; files the scenario refers to (URDF, meshes) enter
    by their SHA-256. The contact model and its torsion enter when the model is
    not the default ``point`` (whose torsion is 0), so the hashes of point-contact
    scenarios are those they had before contact models existed.
    """
    doc = _canonical(scenario)
    doc.pop("base_dir", None)
    if doc.get("contact_model", "point") == "point":
        doc.pop("contact_model", None)
        doc.pop("torsion", None)
    doc["planner"] = {k: v for k, v in doc["planner"].items() if k in ("params", "space")}
    if scenario.hand.urdf is not None:
        doc["hand"]["urdf"] = _file_digest(Path(scenario.base_dir) / scenario.hand.urdf)
    for shape in [doc["object"], *doc["obstacles"]]:
        if isinstance(shape, dict) and "path" in shape:
            shape["path_sha256"] = _file_digest(Path(scenario.base_dir) / str(shape["path"]))
    return doc


def scenario_hash(scenario: Scenario) -> str:
    """Short content hash of a scenario (:func:`scenario_description`), 16 hex digits."""
    text = json.dumps(scenario_description(scenario), sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class RunTask:
    """One run of a sweep: a scenario solved by one planner with one seed.

    Attributes:
        scenario: the problem.
        scenario_hash: :func:`scenario_hash` of it.
        planner: OMPL planner name.
        seed: random seed.
        time_limit: seconds for the plan() call.
        plan_dir: folder to write the plan JSON to (None: don't).
    """

    scenario: Scenario
    scenario_hash: str
    planner: str
    seed: int
    time_limit: float
    plan_dir: str | None = None

    @property
    def key(self) -> str:
        """Resume key: scenario name and hash, planner, seed, time limit."""
        return run_key(
            self.scenario.name, self.scenario_hash, self.planner, self.seed, self.time_limit
        )


def run_key(scenario: str, digest: str, planner: str, seed: int, time_limit: float) -> str:
    """The resume key of a run (``name@hash/planner/seed/time limit``)."""
    return f"{scenario}@{digest}/{planner}/{int(seed)}/{float(time_limit)!r}"


def _parse_planners(planners: str | Sequence[str]) -> list[str]:
    names = planners.split(",") if isinstance(planners, str) else list(planners)
    out: list[str] = []
    for name in (str(n).strip() for n in names):
        if name and name not in out:
            out.append(name)
    if not out:
        raise InvalidInputError(f"--planners: give at least one planner name, got {planners!r}")
    return out


def validate_sweep(
    planners: Sequence[str],
    seeds: int,
    time_limit: float | None,
    *,
    first_seed: int = 1,
    jobs: int | None = None,
    baseline: str | None = DEFAULT_BASELINE,
) -> None:
    """Check a sweep's arguments before any work.

    Raises:
        InvalidInputError: seeds < 1, first seed < 0, time limit not > 0, jobs < 1.
        PlannerError: an unknown planner or baseline.
    """
    if isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 1:
        raise InvalidInputError(f"--seeds must be an integer >= 1, got {seeds!r}")
    if isinstance(first_seed, bool) or not isinstance(first_seed, int) or first_seed < 0:
        raise InvalidInputError(f"--first-seed must be an integer >= 0, got {first_seed!r}")
    if time_limit is not None and not (
        isinstance(time_limit, int | float) and math.isfinite(time_limit) and time_limit > 0
    ):
        raise InvalidInputError(f"--time-limit must be a finite number > 0, got {time_limit!r}")
    if jobs is not None and (isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1):
        raise InvalidInputError(f"--jobs must be an integer >= 1, got {jobs!r}")
    from dexplan.planning.ompl import available_planners

    valid = available_planners()
    for name in [*planners, *([baseline] if baseline else [])]:
        if name not in valid:
            raise PlannerError(f"unknown planner {name!r}; valid planners: {', '.join(valid)}")


def make_tasks(
    scenarios: Sequence[Scenario],
    planners: Sequence[str],
    seeds: Iterable[int],
    time_limit: float | None = None,
    plan_dir: str | Path | None = None,
) -> list[RunTask]:
    """The runs of a sweep, seed-major (a partial sweep covers every planner).

    Args:
        scenarios: problems.
        planners: planner names.
        seeds: random seeds.
        time_limit: seconds per run (None: each scenario's own).
        plan_dir: folder to write plans to (None: don't write them).
    """
    digests = [scenario_hash(s) for s in scenarios]
    out = []
    for seed in seeds:
        for scenario, digest in zip(scenarios, digests, strict=True):
            limit = float(scenario.planner.time_limit if time_limit is None else time_limit)
            for planner in planners:
                out.append(
                    RunTask(
                        scenario,
                        digest,
                        planner,
                        int(seed),
                        limit,
                        None if plan_dir is None else str(plan_dir),
                    )
                )
    return out


# ------------------------------------------------------------------ one run (worker side)


def _empty_record(task: RunTask) -> dict[str, Any]:
    rec: dict[str, Any] = dict.fromkeys(CSV_COLUMNS)
    rec.update(
        scenario=task.scenario.name,
        scenario_hash=task.scenario_hash,
        planner=task.planner,
        seed=task.seed,
        time_limit=task.time_limit,
        key=task.key,
        solved=0,
        message="",
        host=socket.gethostname(),
        progress=[],
        stats={},
    )
    return rec


def _set_status(rec: dict[str, Any], status: str) -> None:
    rec["status_name"] = status
    rec["plan_status"] = PLAN_STATUSES.index(status)
    rec["status"] = _OMPL_STATUS_OF[status]
    rec["solved"] = int(status == "solved")


def failure_record(task: RunTask, status: str, message: str) -> dict[str, Any]:
    """The record of a run that produced no result (``crash``, ``killed``, ``error``)."""
    rec = _empty_record(task)
    _set_status(rec, status)
    rec["message"] = message
    return rec


def segments_sha256(segments: Sequence[Mapping[str, Any]]) -> str:
    """SHA-256 of a plan's segments (plan-file dicts): equal plans, equal hashes."""
    text = json.dumps(list(segments), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def _fill_stats(rec: dict[str, Any], stats: PlanStats) -> None:
    rec["time"] = stats.time_s
    rec["gsn_time"] = stats.gsn_time_s
    rec["reduction_time"] = stats.reduction_time_s
    rec["graph_states"] = stats.roadmap_nodes
    rec["graph_motions"] = stats.roadmap_edges
    for name in (
        "components",
        "graph_nodes",
        "module2_attempts",
        "module2_links",
        "reduction_attempts",
        "regrasps",
        "transfers",
        "waypoints",
        "object_path_m",
        "object_path_rad",
    ):
        rec[name] = getattr(stats, name)
    method = stats.reduction_method
    known = method in REDUCTION_METHODS
    rec["reduction_method"] = REDUCTION_METHODS.index(method) if known else None
    if rec["regrasps"] is not None and rec["transfers"] is not None:
        rec["solution_segments"] = int(rec["regrasps"]) + int(rec["transfers"])
    validity = stats.validity
    rec["states_checked"] = validity.get("checked")
    rec["states_valid"] = validity.get("valid")
    rejected = validity.get("rejected") or {}
    for reason in ("bounds", "joint_limits", "collision", "force_closure"):
        rec[f"rejected_{reason}"] = rejected.get(reason)
    rec["sampler_attempts"] = stats.sampler.get("attempts")
    rec["sampler_valid"] = stats.sampler.get("valid")


def _jsonable(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if hasattr(value, "item") and not hasattr(value, "__len__"):
        return value.item()
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def execute_run(task: RunTask) -> dict[str, Any]:
    """Plan one run, time ``dexplan verify`` on its plan, and return its record.

    Meant to run in a fresh process (see the module docstring). Never raises:
    an exception becomes a record with status ``error``.

    Returns:
        A dict with every key of :data:`CSV_COLUMNS`, plus ``key``, ``progress``
        (``[(seconds, stage), ...]``) and ``stats`` (the planner's statistics).
    """
    t_wall = time.perf_counter()
    rec = _empty_record(task)
    events: list[tuple[float, int]] = [(0.0, 0)]
    try:
        from dexplan.api import plan

        t0 = time.perf_counter()

        def on_event(event: ProgressEvent) -> None:
            events.append((time.perf_counter() - t0, int(event.stage)))

        # the planner runs the plan-file verifier itself (once): a plan that
        # fails it comes back as invalid_plan, with its violations
        planned = plan(
            task.scenario,
            planner=task.planner,
            seed=task.seed,
            time_limit=task.time_limit,
            progress=on_event,
        )
        result = planned.result
        stats = result.stats
        rec["stats"] = _jsonable(stats.as_dict())
        rec["message"] = result.message
        _fill_stats(rec, stats)
        _set_status(rec, result.status if result.status in PLAN_STATUSES else "error")
        if result.solved or result.violations:
            rec["verify_time"] = stats.verify_time_s
            rec["correct_solution"] = int(result.solved)
            rec["verify_violations"] = len(result.violations)
            if rec["verify_time"] and rec["time"] is not None:
                rec["plan_verify_ratio"] = rec["time"] / rec["verify_time"]
        if result.solved:
            base = task.scenario.base_dir
            rec["plan_sha256"] = segments_sha256(planned.to_document(base)["segments"])
            if task.plan_dir is not None:
                name = f"{task.scenario.name}_{task.planner}_seed{task.seed}.json"
                planned.save(Path(task.plan_dir) / name)
        events.append((time.perf_counter() - t0, int(Stage.DONE)))
    except Exception as exc:  # a run that raises is a data point, not the end of a sweep
        _set_status(rec, "error")
        rec["message"] = f"{type(exc).__name__}: {exc}"
    rec["memory"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    rec["wall_time"] = time.perf_counter() - t_wall
    rec["progress"] = events
    return rec


def _child_main(task: RunTask, conn: Connection) -> None:
    """Worker process entry: run, send the record, exit without interpreter teardown."""
    # Ctrl-C reaches the whole process group: the parent stops the sweep and kills
    # the workers; a worker must not turn it into a failed run of its own
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        rec = execute_run(task)
        conn.send(rec)
        conn.close()
    finally:
        # nanobind (ompl) reports "leaked instances" at interpreter exit; skip it
        os._exit(0)


# ------------------------------------------------------------------ database


_NOT_PLANNING = frozenset({"bench.py", "cli.py", "viz.py"})


def code_fingerprint() -> str:
    """SHA-256 (16 hex digits) of the dexplan sources a plan depends on.

    Every module but the benchmark, CLI and viewer: runs with equal
    fingerprints ran the same planning code.
    """
    root = Path(__file__).resolve().parent
    h = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        if path.name in _NOT_PLANNING and path.parent == root:
            continue
        h.update(str(path.relative_to(root)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def _cpuinfo() -> str:
    model = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{model} ({os.cpu_count()} cores)"


def _dexplan_version() -> str:
    from importlib import metadata

    try:
        return metadata.version("dexplan")
    except metadata.PackageNotFoundError:
        from dexplan import __version__

        return __version__


class BenchDatabase:
    """A benchmark database in Planner Arena's schema (plus dexplan's bookkeeping).

    Opening creates the tables that are missing and adds missing ``runs``
    columns, so an existing database (from an earlier sweep, or written by
    ``ompl_benchmark_statistics.py``) is extended, never rewritten. Every
    :meth:`add_run` is one committed transaction.

    Args:
        path: SQLite file (created if missing).
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        try:
            self.conn = sqlite3.connect(str(self.path), timeout=60.0)
        except sqlite3.Error as exc:
            raise InvalidInputError(f"cannot open database {str(self.path)!r}: {exc}") from exc
        self.conn.execute("PRAGMA foreign_keys = ON")
        try:
            self._create_schema()
        except sqlite3.DatabaseError as exc:
            self.conn.close()
            raise InvalidInputError(
                f"{str(self.path)!r} is not a usable benchmark database: {exc}"
            ) from exc

    def __enter__(self) -> BenchDatabase:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Close the connection (everything is committed already)."""
        self.conn.close()

    def _columns(self, table: str) -> list[str]:
        return [row[1] for row in self.conn.execute(f"PRAGMA table_info({table})")]

    def _create_schema(self) -> None:
        c = self.conn
        c.executescript(_SCHEMA)
        have = set(self._columns("runs"))
        for name, kind in RUN_COLUMNS:
            if name not in have:
                c.execute(f"ALTER TABLE runs ADD {name} {kind}")
        if "code" not in self._columns("dexplan_runs"):  # databases of dexplan < 0.1.1
            c.execute("ALTER TABLE dexplan_runs ADD code TEXT")
        if "stage" not in self._columns("progress"):
            c.execute("ALTER TABLE progress ADD stage INTEGER")
        enums = [("status", i, d) for i, d in enumerate(OMPL_STATUSES)]
        enums += [("plan status", i, d) for i, d in enumerate(PLAN_STATUSES)]
        enums += [("reduction method", i, d) for i, d in enumerate(REDUCTION_METHODS)]
        c.executemany("INSERT OR IGNORE INTO enums VALUES (?, ?, ?)", enums)
        for name, sql in _VIEWS.items():
            c.execute(f"DROP VIEW IF EXISTS {name}")
            c.execute(f"CREATE VIEW {name} AS {sql}")
        c.commit()

    def experiment_id(
        self, scenario: Scenario, digest: str, time_limit: float, runcount: int
    ) -> int:
        """The ``experiments`` row of (scenario, hash, time limit), created if missing."""
        c = self.conn
        row = c.execute(
            "SELECT experimentid FROM dexplan_experiments "
            "WHERE scenario=? AND scenario_hash=? AND time_limit=?",
            (scenario.name, digest, float(time_limit)),
        ).fetchone()
        if row is not None:
            c.execute(
                "UPDATE experiments SET runcount=MAX(COALESCE(runcount, 0), ?) WHERE id=?",
                (runcount, row[0]),
            )
            c.commit()
            return int(row[0])
        setup = json.dumps(
            {"scenario": scenario_description(scenario), "scenario_hash": digest},
            sort_keys=True,
            indent=1,
            default=str,
        )
        cur = c.execute(
            "INSERT INTO experiments (name, totaltime, timelimit, memorylimit, runcount, "
            "version, hostname, cpuinfo, date, seed, setup) VALUES (?,?,?,?,?,?,?,?,?,?,?)",
            (
                scenario.name,
                0.0,
                float(time_limit),
                0.0,
                runcount,
                f"dexplan {_dexplan_version()}",
                socket.gethostname(),
                _cpuinfo(),
                datetime.now().isoformat(timespec="seconds"),
                "per run",
                setup,
            ),
        )
        exp_id = int(cur.lastrowid or 0)
        c.execute(
            "INSERT INTO dexplan_experiments VALUES (?,?,?,?)",
            (exp_id, scenario.name, digest, float(time_limit)),
        )
        c.commit()
        return exp_id

    def planner_id(self, planner: str, scenario: Scenario) -> int:
        """The ``plannerConfigs`` row of a planner with the scenario's settings."""
        items = {"space": scenario.planner.space, **dict(scenario.planner.params)}
        settings = "".join(f"{k} = {v}\n;" for k, v in sorted(items.items()))
        name = f"geometric_{planner}"
        c = self.conn
        row = c.execute(
            "SELECT id FROM plannerConfigs WHERE name=? AND settings=?", (name, settings)
        ).fetchone()
        if row is not None:
            return int(row[0])
        cur = c.execute("INSERT INTO plannerConfigs VALUES (?,?,?)", (None, name, settings))
        c.commit()
        return int(cur.lastrowid or 0)

    def finished_keys(self) -> set[str]:
        """Resume keys of the runs already stored."""
        return {row[0] for row in self.conn.execute("SELECT key FROM dexplan_runs")}

    def add_run(self, rec: Mapping[str, Any], experiment_id: int, planner_id: int) -> int:
        """Store one run (``runs``, ``progress``, ``dexplan_runs``) in one transaction.

        Returns:
            The ``runs.id`` of the new row.
        """
        names = [name for name, _ in RUN_COLUMNS]
        values = [_sql_value(rec.get(name)) for name in names]
        c = self.conn
        with c:  # one transaction: all of it or nothing
            cur = c.execute(
                f"INSERT INTO runs (experimentid, plannerid, {', '.join(names)}) "
                f"VALUES (?, ?, {', '.join('?' * len(names))})",
                [experiment_id, planner_id, *values],
            )
            run_id = int(cur.lastrowid or 0)
            c.executemany(
                "INSERT OR IGNORE INTO progress (runid, time, stage) VALUES (?,?,?)",
                [(run_id, float(t), int(s)) for t, s in rec.get("progress") or []],
            )
            c.execute(
                "INSERT INTO dexplan_runs (runid, key, scenario, scenario_hash, planner, seed, "
                "time_limit, status, message, plan_sha256, backend, host, finished, stats_json, "
                "code) VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)",
                (
                    run_id,
                    rec["key"],
                    rec["scenario"],
                    rec["scenario_hash"],
                    rec["planner"],
                    int(rec["seed"]),
                    float(rec["time_limit"]),
                    rec.get("status_name"),
                    rec.get("message") or "",
                    rec.get("plan_sha256"),
                    rec.get("backend"),
                    rec.get("host"),
                    datetime.now().isoformat(timespec="seconds"),
                    json.dumps(_jsonable(rec.get("stats") or {}), sort_keys=True),
                    rec.get("code"),
                ),
            )
            c.execute(
                "UPDATE experiments SET totaltime = COALESCE(totaltime, 0) + ? WHERE id=?",
                (float(rec.get("wall_time") or 0.0), experiment_id),
            )
        return run_id

    def records(self, keys: Iterable[str] | None = None) -> list[dict[str, Any]]:
        """Stored runs as flat records (:data:`CSV_COLUMNS` plus ``key``), in run order.

        Args:
            keys: resume keys to return (None: every run).
        """
        names = [name for name, _ in RUN_COLUMNS]
        sql = (
            "SELECT d.key, d.scenario, d.scenario_hash, d.planner, d.time_limit, d.status, "
            "d.message, d.plan_sha256, d.backend, d.host, d.code, "
            + ", ".join(f"r.{n}" for n in names)
            + " FROM dexplan_runs d JOIN runs r ON r.id = d.runid ORDER BY r.id"
        )
        wanted = None if keys is None else set(keys)
        out = []
        for row in self.conn.execute(sql):
            if wanted is not None and row[0] not in wanted:
                continue
            rec = dict(zip(("key", *IDENTITY_COLUMNS, *names), row, strict=True))
            out.append(rec)
        return out

    def counts(self) -> dict[str, int]:
        """Row counts of the Planner Arena tables and dexplan's."""
        tables = ("experiments", "plannerConfigs", "enums", "runs", "progress", "dexplan_runs")
        return {
            t: int(self.conn.execute(f"SELECT COUNT(*) FROM {t}").fetchone()[0]) for t in tables
        }


def _sql_value(value: Any) -> Any:
    if value is None:
        return None
    if isinstance(value, bool):
        return int(value)
    if hasattr(value, "item"):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None  # as ompl_benchmark_statistics.py stores nan and inf
    return value


# ------------------------------------------------------------------ backends


@dataclass(frozen=True)
class BenchProgress:
    """What a sweep reports to its progress callback after each finished run.

    Attributes:
        done: runs finished in this call (new runs only).
        total: runs to do in this call (finished ones excluded).
        skipped: runs already in the database, not run again.
        record: the record of the run that just finished (None for the first call).
    """

    done: int
    total: int
    skipped: int
    record: Mapping[str, Any] | None = None


ProgressCallback = Callable[[BenchProgress], None]
_OnResult = Callable[[RunTask, dict[str, Any]], None]


def default_run_timeout(time_limit: float) -> float:
    """Hard wall-clock limit of one run: planning, verification and process start-up."""
    return max(3.0 * time_limit, time_limit + 120.0)


def _mp_context(start_method: str) -> Any:
    if start_method not in ("forkserver", "spawn"):
        raise InvalidInputError(
            f"start method must be 'forkserver' or 'spawn', got {start_method!r}"
        )
    ctx = multiprocessing.get_context(start_method)
    # Python 3.11's fork server starts with `python -c` and keeps the working
    # folder first on sys.path (it ignores the parent's path): a folder named
    # `dexplan` there would shadow the installed package in every worker
    os.environ.setdefault("PYTHONSAFEPATH", "1")
    if start_method == "forkserver":
        # imports happen once in the server; every run still forks a fresh process
        ctx.set_forkserver_preload(["dexplan.bench", "dexplan.planning.planner"])
    return ctx


def _run_local(
    tasks: Sequence[RunTask],
    jobs: int,
    on_result: _OnResult,
    *,
    start_method: str,
    run_timeout: Callable[[RunTask], float],
) -> None:
    """Run each task in its own process, at most ``jobs`` at a time."""
    ctx = _mp_context(start_method)
    pending = deque(tasks)
    active: dict[Connection, tuple[Any, RunTask, float]] = {}
    try:
        while pending or active:
            while pending and len(active) < jobs:
                task = pending.popleft()
                recv, send = ctx.Pipe(duplex=False)
                proc = ctx.Process(target=_child_main, args=(task, send), daemon=True)
                proc.start()
                send.close()
                active[recv] = (proc, task, time.monotonic())
            for conn in wait_connections(list(active), timeout=0.5):
                proc, task, _ = active.pop(conn)  # type: ignore[index]
                try:
                    rec = conn.recv()
                except (EOFError, OSError):
                    proc.join(5.0)
                    rec = failure_record(
                        task, "crash", f"worker process died (exit code {proc.exitcode})"
                    )
                conn.close()
                proc.join(10.0)
                if proc.is_alive():
                    proc.kill()
                    proc.join()
                on_result(task, rec)
            now = time.monotonic()
            for conn, (proc, task, started) in list(active.items()):
                limit = run_timeout(task)
                if now - started > limit:
                    proc.kill()
                    proc.join()
                    conn.close()
                    del active[conn]
                    on_result(
                        task,
                        failure_record(task, "killed", f"run exceeded {limit:.0f} s wall clock"),
                    )
    finally:
        for conn, (proc, _, _) in active.items():
            proc.kill()
            proc.join()
            conn.close()


def _require_ray() -> Any:
    try:
        import ray
    except ImportError as exc:
        raise DependencyError(
            "--ray needs Ray: pip install 'dexplan[ray]' (or pip install ray)"
        ) from exc
    return ray


def _check_ray_address(address: str) -> None:
    """Fail fast (instead of Ray's long retries) when ``host:port`` does not answer.

    Raises:
        InvalidInputError: nothing listens at the address.
    """
    if address in ("local", "auto"):
        return
    hostport = address.split("://", 1)[-1]
    host, sep, port = hostport.rpartition(":")
    if not sep or not port.isdigit():
        return  # leave other forms to Ray
    try:
        with socket.create_connection((host, int(port)), timeout=5.0):
            pass
    except OSError as exc:
        raise InvalidInputError(f"--ray {address!r}: no Ray cluster answers there ({exc})") from exc


def _run_ray(
    tasks: Sequence[RunTask],
    address: str,
    jobs: int | None,
    on_result: _OnResult,
    *,
    run_timeout: Callable[[RunTask], float],
) -> None:
    """Run each task as a Ray task in a fresh worker process (``max_calls=1``)."""
    import logging

    ray = _require_ray()
    started_here = False
    if not ray.is_initialized():
        kwargs: dict[str, Any] = {
            "log_to_driver": False,
            "logging_level": logging.ERROR,
            "configure_logging": True,
        }
        try:
            if address == "local":
                kwargs.update(num_cpus=jobs or os.cpu_count() or 1, include_dashboard=False)
                ray.init(**kwargs)
            else:
                ray.init(address=address, **kwargs)
        except Exception as exc:  # no cluster there, version mismatch, ...
            raise InvalidInputError(
                f"--ray {address!r}: cannot start or join a Ray cluster: {exc}"
            ) from exc
        started_here = True
    try:
        window = jobs or max(1, int(ray.cluster_resources().get("CPU", 1)))
        remote = ray.remote(num_cpus=1, max_calls=1, max_retries=0)(execute_run)
        pending = deque(tasks)
        active: dict[Any, tuple[RunTask, float]] = {}
        while pending or active:
            while pending and len(active) < window:
                task = pending.popleft()
                active[remote.remote(task)] = (task, time.monotonic())
            ready, _ = ray.wait(list(active), num_returns=1, timeout=0.5)
            for ref in ready:
                task, _ = active.pop(ref)
                try:
                    rec = ray.get(ref)
                except Exception as exc:  # worker died or the task was lost
                    rec = failure_record(task, "crash", f"Ray task failed: {type(exc).__name__}")
                on_result(task, rec)
            now = time.monotonic()
            for ref, (task, started) in list(active.items()):
                limit = run_timeout(task)
                if now - started > limit:
                    ray.cancel(ref, force=True)
                    del active[ref]
                    on_result(
                        task,
                        failure_record(task, "killed", f"run exceeded {limit:.0f} s wall clock"),
                    )
    finally:
        if started_here:
            ray.shutdown()


# ------------------------------------------------------------------ summary


def _median(values: Iterable[Any]) -> float:
    vals = [float(v) for v in values if v is not None and math.isfinite(float(v))]
    return statistics.median(vals) if vals else math.nan


def _ratio(a: float, b: float) -> float:
    if math.isnan(a) or math.isnan(b) or b == 0:
        return math.nan
    return a / b


def summarize(
    records: Sequence[Mapping[str, Any]], baseline: str | None = DEFAULT_BASELINE
) -> list[dict[str, Any]]:
    """Per scenario and planner: success rate, medians, and ratios to the baseline.

    Medians of ``time`` and ``graph_states`` are over all runs (failed runs
    count with the time they used, as in OMPL's benchmarks); regrasps,
    transfers, verification time and the planning/verification ratio are over
    solved runs. Ratios (``*_vs_base``) divide by the baseline planner's figure
    on the same scenario (NaN without a baseline).

    Returns:
        One dict per (scenario, planner), in first-seen order.
    """
    groups: dict[tuple[str, str], list[Mapping[str, Any]]] = {}
    for rec in records:
        groups.setdefault((str(rec["scenario"]), str(rec["planner"])), []).append(rec)
    rows = []
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
                "nodes_median": _median(r.get("graph_states") for r in recs),
                "components_median": _median(r.get("components") for r in recs),
                "regrasps_median": _median(r.get("regrasps") for r in solved),
                "transfers_median": _median(r.get("transfers") for r in solved),
                "verify_ok": sum(1 for r in solved if r.get("correct_solution")),
                "verify_time_median": _median(r.get("verify_time") for r in solved),
                "plan_verify_ratio_median": _median(r.get("plan_verify_ratio") for r in solved),
                "memory_median": _median(r.get("memory") for r in recs),
            }
        )
    base = {row["scenario"]: row for row in rows if row["planner"] == baseline}
    for row in rows:
        b = base.get(row["scenario"])
        for name in ("success_rate", "time_median", "nodes_median", "regrasps_median"):
            row[f"{name}_vs_base"] = _ratio(row[name], b[name]) if b else math.nan
    return rows


def _fmt(value: Any, spec: str) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        width = spec.split(".")[0]
        return "-".rjust(int(width) if width.isdigit() else 1)
    return format(value, spec)


def format_summary(rows: Sequence[Mapping[str, Any]], baseline: str | None = None) -> str:
    """A fixed-width text table of :func:`summarize` rows (the CLI prints it)."""
    head = (
        f"{'scenario':<16} {'planner':<11} {'runs':>4} {'solved':>7} {'x base':>6} "
        f"{'time med':>8} {'x base':>6} {'nodes med':>9} {'x base':>6} "
        f"{'regrasps':>8} {'transf':>6} {'verify':>6} {'plan/ver':>8} {'MB':>5}"
    )
    lines = [head, "-" * len(head)]
    for r in rows:
        mark = "*" if baseline is not None and r["planner"] == baseline else ""
        lines.append(
            f"{r['scenario'][:16]:<16} {(r['planner'] + mark)[:11]:<11} {r['runs']:>4} "
            f"{_fmt(100 * r['success_rate'], '6.0f')}% {_fmt(r['success_rate_vs_base'], '6.2f')} "
            f"{_fmt(r['time_median'], '7.2f')}s {_fmt(r['time_median_vs_base'], '6.2f')} "
            f"{_fmt(r['nodes_median'], '9.0f')} {_fmt(r['nodes_median_vs_base'], '6.2f')} "
            f"{_fmt(r['regrasps_median'], '8.1f')} {_fmt(r['transfers_median'], '6.1f')} "
            f"{r['verify_ok']:>3}/{r['solved']:<2} {_fmt(r['plan_verify_ratio_median'], '8.1f')} "
            f"{_fmt(r['memory_median'], '5.0f')}"
        )
    lines.append(
        "time and nodes: medians over all runs; regrasps, transfers, plan/verify: over solved "
        "runs; verify: plans passing dexplan verify / solved"
        + (f"; x base: ratio to {baseline} (*)" if baseline else "")
    )
    return "\n".join(lines)


# ------------------------------------------------------------------ CSV and plots


def write_csv(records: Sequence[Mapping[str, Any]], path: str | Path) -> Path:
    """Write run records (:data:`CSV_COLUMNS`) to a CSV file, atomically."""
    path = Path(path)
    with atomic_output(path, "CSV") as tmp, open(tmp, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(CSV_COLUMNS), extrasaction="ignore")
        writer.writeheader()
        for rec in records:
            writer.writerow({k: _csv_value(rec.get(k)) for k in CSV_COLUMNS})
    return path


def write_summary_csv(rows: Sequence[Mapping[str, Any]], path: str | Path) -> Path:
    """Write :func:`summarize` rows to a CSV file, atomically."""
    path = Path(path)
    if not rows:
        fields: list[str] = ["scenario", "planner"]
    else:
        fields = list(rows[0])
    with atomic_output(path, "CSV") as tmp, open(tmp, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=fields)
        writer.writeheader()
        for row in rows:
            writer.writerow({k: _csv_value(row.get(k)) for k in fields})
    return path


def _csv_value(value: Any) -> Any:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    if isinstance(value, float):
        return repr(value)
    return value


def require_matplotlib() -> None:
    """Raise a clear error when matplotlib (the ``bench`` extra) is missing.

    Raises:
        DependencyError: matplotlib is not installed.
    """
    try:
        import matplotlib  # noqa: F401
    except ImportError as exc:
        raise DependencyError(
            "benchmark plots need matplotlib: pip install 'dexplan[bench]' (or pass --no-plots)"
        ) from exc


def _ordered(records: Sequence[Mapping[str, Any]], key: str) -> list[str]:
    out: list[str] = []
    for rec in records:
        if rec[key] not in out:
            out.append(str(rec[key]))
    return out


def plot_results(
    records: Sequence[Mapping[str, Any]],
    out_dir: str | Path,
    baseline: str | None = DEFAULT_BASELINE,
) -> list[Path]:
    """Write the benchmark plots (PNG) of some run records.

    ``bench_time.png``: box plots of planning time per planner (all runs; the
    time limit dashed), one panel per scenario. ``bench_success.png``: success
    rate per planner and scenario. ``bench_nodes.png``: box plots of roadmap
    nodes (``graph_states``). ``bench_regrasps.png``: regrasps per solved plan.

    Returns:
        The paths written.

    Raises:
        DependencyError: matplotlib is not installed.
    """
    require_matplotlib()
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    scenarios = _ordered(records, "scenario")
    planners = _ordered(records, "planner")
    if baseline in planners:
        planners.remove(baseline)
        planners.insert(0, baseline)
    by = {(s, p): [r for r in records if r["scenario"] == s and r["planner"] == p]
          for s in scenarios for p in planners}  # fmt: skip
    written: list[Path] = []

    def save(fig: Any, name: str) -> None:
        path = out_dir / name
        with atomic_output(path, "plot") as tmp:
            fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight")
        plt.close(fig)
        written.append(path)

    def boxes(column: str, title: str, ylabel: str, name: str, solved_only: bool, log: bool):
        fig, axes = plt.subplots(
            1, len(scenarios), figsize=(1.3 + 1.5 * len(planners) * len(scenarios), 3.8),
            squeeze=False,
        )  # fmt: skip
        for ax, scen in zip(axes[0], scenarios, strict=True):
            data, labels = [], []
            for i, p in enumerate(planners):
                rs = [r for r in by[(scen, p)] if r.get("solved") or not solved_only]
                rs = [r for r in rs if r.get(column) is not None]
                vals = [float(r[column]) for r in rs]
                data.append(vals)
                labels.append(f"{p}\n(n={len(vals)})")
                # every run as a point (deterministic jitter): solved o, unsolved x
                for j, r in enumerate(rs):
                    x = i + 1 + 0.3 * ((j * 0.618034) % 1.0 - 0.5)
                    ok = bool(r.get("solved"))
                    ax.plot(
                        x, float(r[column]), "o" if ok else "x", ms=3, alpha=0.5,
                        color="tab:green" if ok else "tab:red", zorder=3,
                    )  # fmt: skip
            ax.boxplot(data, showfliers=False)
            ax.set_xticks(range(1, len(labels) + 1), labels, fontsize=8)
            if column == "time":
                limits = {float(r["time_limit"]) for p in planners for r in by[(scen, p)]}
                for lim in limits:
                    ax.axhline(lim, color="0.5", ls="--", lw=0.8)
            if log and any(v > 0 for d in data for v in d if not math.isnan(v)):
                ax.set_yscale("log")
            ax.set_title(scen)
            ax.set_ylabel(ylabel)
            ax.grid(axis="y", alpha=0.3)
        fig.suptitle(title)
        save(fig, name)

    boxes("time", "planning time per run (all runs)", "time (s)", PLOT_NAMES[0], False, True)

    fig, ax = plt.subplots(figsize=(1.5 + 1.1 * len(planners) * max(1, len(scenarios)), 3.8))
    width = 0.8 / max(1, len(scenarios))
    for k, scen in enumerate(scenarios):
        rates = []
        for p in planners:
            rs = by[(scen, p)]
            rates.append(100.0 * sum(1 for r in rs if r.get("solved")) / len(rs) if rs else 0.0)
        xs = [i + (k - (len(scenarios) - 1) / 2) * width for i in range(len(planners))]
        bars = ax.bar(xs, rates, width, label=scen)
        for bar, p in zip(bars, planners, strict=True):
            n = len(by[(scen, p)])
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
    save(fig, PLOT_NAMES[1])

    boxes("graph_states", "roadmap nodes generated (all runs)", "nodes", PLOT_NAMES[2], False, True)
    boxes("regrasps", "regrasps per plan (solved runs)", "regrasps", PLOT_NAMES[3], True, False)
    return written


# ------------------------------------------------------------------ the sweep


@dataclass
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
    records: list[dict[str, Any]]
    summary: list[dict[str, Any]]
    new_runs: int
    skipped: int
    backend: str
    planners: list[str]
    counts: dict[str, int] = field(default_factory=dict)

    @property
    def failed(self) -> list[dict[str, Any]]:
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
    start_method: str = "forkserver",
    run_timeout: float | None = None,
    progress: ProgressCallback | None = None,
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

    Returns:
        A :class:`BenchResult`.

    Raises:
        InvalidInputError: bad seeds, time limit, jobs or output folder.
        PlannerError: unknown planner or baseline.
        ScenarioError: missing or invalid scenario.
        DependencyError: plots without matplotlib, or ``ray_address`` without Ray.
    """
    names = _parse_planners(planners)
    if baseline is not None and baseline not in names:
        names.insert(0, baseline)
    validate_sweep(names, seeds, time_limit, first_seed=first_seed, jobs=jobs, baseline=baseline)
    if run_timeout is not None and not (math.isfinite(run_timeout) and run_timeout > 0):
        raise InvalidInputError(f"run timeout must be > 0, got {run_timeout!r}")
    if not scenarios:
        raise InvalidInputError("give at least one scenario")
    loaded = [s if isinstance(s, Scenario) else resolve_scenario(s) for s in scenarios]
    seen: dict[str, str] = {}
    for s in loaded:
        digest = scenario_hash(s)
        if seen.get(s.name, digest) != digest:
            raise InvalidInputError(
                f"two different scenarios are both named {s.name!r}; rename one of them"
            )
        seen[s.name] = digest
    from dexplan.planning.ompl import check_planner

    for s in loaded:  # planner parameters of the scenario must suit every planner
        for name in names:
            check_planner(name, s.planner.params)
    if plots:
        require_matplotlib()
    if ray_address is not None:
        _require_ray()
        _check_ray_address(ray_address)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InvalidInputError(f"-o: {str(out)!r} exists and is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    plan_dir = None
    if save_plans:
        plan_dir = out / "plans"
        plan_dir.mkdir(exist_ok=True)

    unique: list[Scenario] = []
    for s in loaded:
        if all(u.name != s.name for u in unique):
            unique.append(s)
    tasks = make_tasks(unique, names, range(first_seed, first_seed + seeds), time_limit, plan_dir)
    backend = "local" if ray_address is None else "ray"
    db = BenchDatabase(out / DB_NAME)
    try:
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

        def on_result(task: RunTask, rec: dict[str, Any]) -> None:
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

        def timeout_of(task: RunTask) -> float:
            return run_timeout if run_timeout is not None else default_run_timeout(task.time_limit)

        if todo:
            if ray_address is None:
                n_jobs = min(jobs or os.cpu_count() or 1, len(todo))
                _run_local(
                    todo, n_jobs, on_result, start_method=start_method, run_timeout=timeout_of
                )
            else:
                _run_ray(todo, ray_address, jobs, on_result, run_timeout=timeout_of)
        # the report covers every stored run of the sweep's scenarios, planners and
        # time limits: seeds of earlier, longer sweeps into the same folder count too
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
        counts = db.counts()
    finally:
        db.close()
    rows = summarize(records, baseline)
    csv_path = write_csv(records, out / CSV_NAME)
    summary_path = write_summary_csv(rows, out / SUMMARY_CSV_NAME)
    written = plot_results(records, out, baseline) if plots and records else []
    return BenchResult(
        out_dir=out,
        database=out / DB_NAME,
        csv=csv_path,
        summary_csv=summary_path,
        plots=written,
        records=records,
        summary=rows,
        new_runs=done,
        skipped=skipped,
        backend=backend,
        planners=names,
        counts=counts,
    )
