"""Names of a benchmark: output files, run statuses, progress stages, run columns, SQL schema.

The ``runs`` columns, ``enums`` and views follow OMPL's Planner Arena
(``ompl_benchmark_statistics.py``: tables ``experiments``, ``plannerConfigs``,
``enums``, ``runs``, ``progress`` and the ``bestPlannerConfigs*`` views);
dexplan's bookkeeping goes to two extra tables (``dexplan_experiments``,
``dexplan_runs``). This module holds data only.

The closed sets of names are :class:`~enum.StrEnum` classes: a member equals
its string, so the database, the CSV files and the JSON stay plain text.
"""

from __future__ import annotations

from enum import StrEnum

from dexplan.planning.progress import Stage

DEFAULT_PLANNERS: tuple[str, ...] = ("PRM", "RRTConnect", "KPIECE1")
"""Planners of ``dexplan bench`` when none are given."""

DEFAULT_BASELINE = "PRM"
"""The paper's configuration: every figure is also given as a ratio to it."""

DB_NAME = "bench.db"
CSV_NAME = "runs.csv"
SUMMARY_CSV_NAME = "summary.csv"


class Plot(StrEnum):
    """The PNG plots of a sweep, by file name."""

    TIME = "bench_time.png"
    """Box plots of planning time per planner, one panel per scenario."""
    SUCCESS = "bench_success.png"
    """Success rate per planner and scenario."""
    NODES = "bench_nodes.png"
    """Box plots of roadmap nodes generated."""
    REGRASPS = "bench_regrasps.png"
    """Box plots of regrasps per solved plan."""
    EXECUTION_TIME = "bench_execution_time.png"
    """Box plots of the execution time of each solved plan (the export's timing)."""
    WEAKEST_HOLD = "bench_weakest_hold.png"
    """Box plots of the weakest hold's force-closure quality per solved plan."""
    TORQUE_RATIO = "bench_torque_ratio.png"
    """Box plots of the worst torque ratio per solved plan (1: the effort limits)."""


PLOT_NAMES: tuple[str, ...] = tuple(Plot)
"""File names of the plots, in the order they are written."""


class Backend(StrEnum):
    """Where a sweep's runs execute."""

    LOCAL = "local"
    """A pool of local processes."""
    RAY = "ray"
    """Ray tasks on a cluster."""


class StartMethod(StrEnum):
    """How the local backend starts its worker processes (:mod:`multiprocessing`)."""

    FORKSERVER = "forkserver"
    """Forks of a server that imported the planning modules once."""
    SPAWN = "spawn"
    """Fresh interpreters."""


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


class RunStatus(StrEnum):
    """How a run ended, in the order of the ``plan status`` enum.

    The planner's statuses (:class:`dexplan.planning.progress.PlanStatus`) first,
    then the run's own failures.
    """

    SOLVED = "solved"
    NO_START_GRASP = "no_start_grasp"
    NO_GOAL_GRASP = "no_goal_grasp"
    NO_GSN_PATH = "no_gsn_path"
    REDUCTION_FAILED = "reduction_failed"
    INVALID_PLAN = "invalid_plan"
    ERROR = "error"
    """The run raised."""
    CRASH = "crash"
    """The worker process died."""
    KILLED = "killed"
    """The run overran its hard wall-clock limit."""


PLAN_STATUSES: tuple[str, ...] = tuple(RunStatus)
"""Run outcomes, in the order of the ``plan status`` enum (its values are indexes here)."""

FAILED_RUN_STATUSES = frozenset({RunStatus.ERROR, RunStatus.CRASH})
"""Statuses of runs that failed as runs (see :attr:`~dexplan.bench.sweep.BenchResult.failed`)."""


class ReductionMethod(StrEnum):
    """How a solved run's GSn path became transfers and regrasps.

    In the order of the ``reduction method`` enum (see :func:`dexplan.planning.planner.plan`).
    """

    GAITS = "gaits"
    EDGES = "edges"


REDUCTION_METHODS: tuple[str, ...] = tuple(ReductionMethod)
"""Reduction method names, in the order of the ``reduction method`` enum."""

OMPL_STATUS_OF: dict[RunStatus, int] = {
    RunStatus.SOLVED: 6,  # Exact solution
    RunStatus.NO_START_GRASP: 1,  # Invalid start
    RunStatus.NO_GOAL_GRASP: 2,  # Invalid goal
    RunStatus.NO_GSN_PATH: 4,  # Timeout
    RunStatus.REDUCTION_FAILED: 4,  # the reduction retries until the deadline
    RunStatus.INVALID_PLAN: 5,  # Approximate solution: a plan that fails the verifier
    RunStatus.ERROR: 8,  # Abort
    RunStatus.CRASH: 7,  # Crash
    RunStatus.KILLED: 7,  # OMPL's Benchmark calls an overrunning planner a crash too
}
"""The ``ompl::base::PlannerStatus`` value (:data:`OMPL_STATUSES`) of each plan status."""

STAGE_NAMES: dict[Stage, str] = {
    Stage.STARTING: "setup",
    Stage.START_GRASP: "start grasp",
    Stage.MODULE1: "module 1 (GSn exploration)",
    Stage.MODULE2: "module 2 (component links)",
    Stage.REDUCTION: "reduction",
    Stage.VERIFICATION: "verification",
    Stage.DONE: "done",
}
"""What each progress stage (the ``stage`` column of the ``progress`` table) is."""

STAGES: tuple[str, ...] = tuple(STAGE_NAMES[stage] for stage in Stage)
"""The stage names by :class:`~dexplan.planning.progress.Stage` value."""

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
    ("cpu_time", "REAL"),  # processor seconds of the same span as time (load-independent)
    ("gsn_time", "REAL"),
    ("reduction_time", "REAL"),
    ("verify_time", "REAL"),  # dexplan verify, timed separately on the plan
    ("verify_violations", "INTEGER"),
    ("plan_verify_ratio", "REAL"),  # time / verify_time
    ("components", "INTEGER"),
    ("graph_nodes", "INTEGER"),  # nodes of the transfer/regrasp plan graph
    ("module2_attempts", "INTEGER"),
    ("module2_links", "INTEGER"),
    ("geodesic_motion_edges", "INTEGER"),  # module-1 edges joined by the section VI motion
    ("reduction_attempts", "INTEGER"),
    ("reduction_method", "ENUM"),  # REDUCTION_METHODS
    ("regrasps", "INTEGER"),
    ("transfers", "INTEGER"),
    ("waypoints", "INTEGER"),
    ("object_path_m", "REAL"),
    ("object_path_rad", "REAL"),
    ("joint_travel_rad", "REAL"),  # hand joints' total travel along the plan
    # the plan's quality (dexplan.execution.quality), computed after the run
    ("execution_time_s", "REAL"),  # the export's time-optimal execution time
    ("rotation_per_transfer_deg_median", "REAL"),  # object rotation per transfer
    ("rotation_per_transfer_deg_min", "REAL"),
    ("rotation_per_transfer_deg_max", "REAL"),
    ("regrasps_without_progress", "INTEGER"),  # regrasps followed by another regrasp
    ("weakest_hold", "REAL"),  # least force-closure quality of a hold
    ("worst_torque_ratio", "REAL"),  # largest share of the effort limits a hold needs
    ("max_grip_force_n", "REAL"),  # largest grip force at a waypoint
    ("quality_time", "REAL"),  # seconds computing the quality (not in time)
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

QUALITY_COLUMNS: tuple[str, ...] = (
    "execution_time_s",
    "rotation_per_transfer_deg_median",
    "rotation_per_transfer_deg_min",
    "rotation_per_transfer_deg_max",
    "regrasps_without_progress",
    "weakest_hold",
    "worst_torque_ratio",
    "max_grip_force_n",
)
"""The run columns that are the plan's quality figures: fields of
:class:`~dexplan.execution.quality.PlanQuality` of the same names."""

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

SCHEMA = """
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
"""Planner Arena's tables (``runs`` with only its key columns: :data:`RUN_COLUMNS`
are added to it) and dexplan's two bookkeeping tables."""

# The views ompl_benchmark_statistics.py creates (runs have no simplification_time).
VIEWS = {
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
