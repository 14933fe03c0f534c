"""Names of a benchmark: output files, run statuses, progress stages, run columns, SQL schema.

The ``runs`` columns, ``enums`` and views follow OMPL's Planner Arena
(``ompl_benchmark_statistics.py``: tables ``experiments``, ``plannerConfigs``,
``enums``, ``runs``, ``progress`` and the ``bestPlannerConfigs*`` views);
dexplan's bookkeeping goes to two extra tables (``dexplan_experiments``,
``dexplan_runs``). This module holds data only.
"""

from __future__ import annotations

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

OMPL_STATUS_OF: dict[str, int] = {
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
"""The ``ompl::base::PlannerStatus`` value (:data:`OMPL_STATUSES`) of each plan status."""

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
    ("geodesic_motion_edges", "INTEGER"),  # module-1 edges joined by the section VI motion
    ("reduction_attempts", "INTEGER"),
    ("reduction_method", "ENUM"),  # REDUCTION_METHODS
    ("regrasps", "INTEGER"),
    ("transfers", "INTEGER"),
    ("waypoints", "INTEGER"),
    ("object_path_m", "REAL"),
    ("object_path_rad", "REAL"),
    ("joint_travel_rad", "REAL"),  # hand joints' total travel along the plan
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
