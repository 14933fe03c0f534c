"""Benchmarks: Planner Arena schema, resume, CSV, plots, summary, sweeps, backends."""

from __future__ import annotations

import csv
import importlib.util
import math
import os
import sqlite3
import statistics
import subprocess
import sys
from pathlib import Path

import pytest

from dexplan import bench
from dexplan.bench import (
    CSV_COLUMNS,
    PLAN_STATUSES,
    RUN_COLUMNS,
    BenchDatabase,
    RunTask,
    format_summary,
    make_tasks,
    plot_results,
    resolve_scenario,
    run_benchmark,
    scenario_hash,
    summarize,
    write_csv,
)
from dexplan.bench.records import empty_record, fill_quality, set_status
from dexplan.core.errors import InvalidInputError, PlannerError, ScenarioError
from dexplan.execution.quality import PlanQuality
from dexplan.model.scenario import builtin_scenario_path, load_scenario

ROOT = Path(__file__).resolve().parents[1]
OMPL_STATS = None
try:  # OMPL's own log -> SQLite converter, shipped in the wheel (tests may import ompl)
    _spec = importlib.util.find_spec("ompl")
    if _spec is not None and _spec.submodule_search_locations:
        _path = Path(next(iter(_spec.submodule_search_locations))) / "_benchmark_statistics.py"
        if _path.is_file():
            _mod_spec = importlib.util.spec_from_file_location("_ompl_bench_stats", _path)
            assert _mod_spec is not None and _mod_spec.loader is not None
            OMPL_STATS = importlib.util.module_from_spec(_mod_spec)
            _mod_spec.loader.exec_module(OMPL_STATS)
except Exception:  # pragma: no cover - the comparison test skips
    OMPL_STATS = None


def _planning_available() -> bool:
    try:
        import dexplan.planning.planner  # noqa: F401
    except ImportError:
        return False
    return True


needs_planning = pytest.mark.skipif(
    not _planning_available(), reason="the planner cannot be imported yet"
)
needs_matplotlib = pytest.mark.skipif(
    importlib.util.find_spec("matplotlib") is None, reason="matplotlib is not installed"
)


# ------------------------------------------------------------------ synthetic records


def _fake_record(task: RunTask, solved: bool, time_s: float, nodes: int) -> dict:
    rec = empty_record(task)
    set_status(rec, "solved" if solved else "no_gsn_path")
    rec.update(
        time=time_s,
        memory=300.0,
        graph_states=nodes,
        graph_motions=2 * nodes,
        components=1,
        wall_time=time_s + 0.5,
        backend="local",
        progress=[(0.0, 0), (0.1, 1), (time_s, 6)],
        stats={"time_s": time_s},
    )
    if solved:
        rec.update(
            regrasps=10,
            transfers=2,
            solution_segments=12,
            correct_solution=1,
            verify_violations=0,
            verify_time=0.5,
            plan_verify_ratio=time_s / 0.5,
            plan_sha256="ab" * 32,
        )
        fill_quality(rec, _fake_quality(time_s), 0.25)
    return rec


def _fake_quality(time_s: float) -> PlanQuality:
    """Plan-quality figures that vary with the run's time (10 regrasps, 2 transfers)."""
    return PlanQuality(
        regrasps=10,
        transfers=2,
        regrasps_without_progress=int(time_s) % 3,
        rotation_per_transfer_deg_median=20.0 + time_s,
        rotation_per_transfer_deg_min=5.0,
        rotation_per_transfer_deg_max=40.0 + time_s,
        joint_travel_rad=10.0 * time_s,
        execution_time_s=30.0 + time_s,
        max_grip_force_n=2.0 + 0.1 * time_s,
        weakest_hold=0.01 * time_s,
        worst_torque_ratio=0.1 * time_s,
    )


@pytest.fixture(scope="module")
def sphere():
    return load_scenario(builtin_scenario_path("paper_sphere"))


@pytest.fixture(scope="module")
def cube():
    return load_scenario(builtin_scenario_path("cube_obstacle"))


def _fill_db(db: BenchDatabase, tasks: list[RunTask]) -> list[dict]:
    recs = []
    for i, t in enumerate(tasks):
        rec = _fake_record(t, solved=(i % 3 != 2), time_s=1.0 + i, nodes=100 + 10 * i)
        exp = db.experiment_id(t.scenario, t.scenario_hash, t.time_limit, 2)
        pid = db.planner_id(t.planner, t.scenario)
        db.add_run(rec, exp, pid)
        recs.append(rec)
    return recs


# ------------------------------------------------------------------ schema


def test_database_has_planner_arena_schema(tmp_path, sphere, cube):
    tasks = make_tasks([sphere, cube], ["PRM", "RRTConnect"], [1, 2], 5.0)
    assert len(tasks) == 8
    with BenchDatabase(tmp_path / "b.db") as db:
        _fill_db(db, tasks)
        counts = db.counts()
    assert counts["experiments"] == 2
    assert counts["plannerConfigs"] == 2  # one per (planner, settings); same settings here
    assert counts["runs"] == 8
    assert counts["dexplan_runs"] == 8
    assert counts["progress"] == 8 * 3
    conn = sqlite3.connect(tmp_path / "b.db")
    cols = {
        t: [r[1] for r in conn.execute(f"PRAGMA table_info({t})")]
        for t in ("experiments", "plannerConfigs", "enums", "runs", "progress")
    }
    # what Planner Arena reads: 12 experiment columns, runs attributes from column 3 on
    assert cols["experiments"] == [
        "id",
        "name",
        "totaltime",
        "timelimit",
        "memorylimit",
        "runcount",
        "version",
        "hostname",
        "cpuinfo",
        "date",
        "seed",
        "setup",
    ]
    assert cols["plannerConfigs"] == ["id", "name", "settings"]
    assert cols["enums"] == ["name", "value", "description"]
    assert cols["runs"][:3] == ["id", "experimentid", "plannerid"]
    assert cols["runs"][3:] == [name for name, _ in RUN_COLUMNS]
    for required in ("time", "memory", "solved", "status", "graph_states", "graph_motions"):
        assert required in cols["runs"]
    assert cols["progress"][:2] == ["runid", "time"]
    names = {r[0] for r in conn.execute("SELECT name FROM plannerConfigs")}
    assert names == {"geometric_PRM", "geometric_RRTConnect"}
    enums = dict(conn.execute("SELECT value, description FROM enums WHERE name='status'"))
    assert enums[6] == "Exact solution" and enums[4] == "Timeout"
    plan_enum = dict(conn.execute("SELECT value, description FROM enums WHERE name='plan status'"))
    assert [plan_enum[i] for i in range(len(PLAN_STATUSES))] == list(PLAN_STATUSES)
    # the views ompl_benchmark_statistics.py creates work on the data
    best = conn.execute("SELECT * FROM bestPlannerConfigs").fetchall()
    assert len(best) == 2
    per_exp = conn.execute("SELECT * FROM bestPlannerConfigsPerExperiment").fetchall()
    assert len(per_exp) == 4
    # solved runs are stored as OMPL stores them
    solved = conn.execute("SELECT solved, status FROM runs ORDER BY id").fetchall()
    assert solved[0] == (1, 6) and solved[2] == (0, 4)
    tot = conn.execute("SELECT SUM(totaltime) FROM experiments").fetchone()[0]
    assert tot == pytest.approx(sum(1.5 + i for i in range(8)))


OMPL_LOG = """OMPL version 2.0.1
Experiment demo
Running on host1
Starting at 2024-01-01T00:00:00
<<<|
setup
|>>>
<<<|
cpu
|>>>
1 is the random seed
10 seconds per run
4096 MB per run
2 runs per planner
3.5 seconds spent to collect the data
1 enum type
status|Unknown status|Invalid start|Invalid goal|Unrecognized goal type|Timeout|Approximate solution|Exact solution|Crash|Abort|Infeasible
1 planners
geometric_RRTConnect
1 common properties
range = 0
4 properties for each run
graph states INTEGER
solved BOOLEAN
status ENUM
time REAL
2 runs
10; 1; 6; 0.5;
12; 0; 4; 10.0;
.
""".replace(";\n", "; \n")  # noqa: E501  (OMPL writes "value; " per run property)


@pytest.mark.skipif(OMPL_STATS is None, reason="ompl's _benchmark_statistics.py not found")
def test_schema_matches_ompl_benchmark_statistics(tmp_path, sphere):
    log = tmp_path / "demo.log"
    log.write_text(OMPL_LOG)
    ref = tmp_path / "ref.db"
    OMPL_STATS.readBenchmarkLog(str(ref), [str(log)], False)
    OMPL_STATS.computeViews(str(ref), False)
    ours = tmp_path / "ours.db"
    with BenchDatabase(ours) as db:
        _fill_db(db, make_tasks([sphere], ["PRM"], [1], 5.0))

    def schema(path, table):
        conn = sqlite3.connect(path)
        return [(r[1], r[2]) for r in conn.execute(f"PRAGMA table_info({table})")]

    for table in ("experiments", "plannerConfigs", "enums"):
        assert schema(ours, table) == schema(ref, table), table
    assert schema(ours, "progress")[:2] == schema(ref, "progress")
    ref_runs = dict(schema(ref, "runs"))
    our_runs = dict(schema(ours, "runs"))
    for name, kind in ref_runs.items():  # same names and declared types
        assert our_runs[name] == kind, name
    # OMPL's converter can append its own results to our database, and the
    # views it computes work on it
    OMPL_STATS.readBenchmarkLog(str(ours), [str(log)], False)
    OMPL_STATS.computeViews(str(ours), False)
    conn = sqlite3.connect(ours)
    assert conn.execute("SELECT COUNT(*) FROM runs").fetchone()[0] == 3
    assert conn.execute("SELECT COUNT(*) FROM experiments").fetchone()[0] == 2
    # and our database opens again after that (resume on a mixed database)
    with BenchDatabase(ours) as db:
        assert len(db.finished_keys()) == 1


def test_resume_keys_and_partial_database(tmp_path, sphere):
    tasks = make_tasks([sphere], ["PRM", "KPIECE1"], [1, 2, 3], 5.0)
    assert [t.seed for t in tasks] == [1, 1, 2, 2, 3, 3]  # seed-major: partial sweeps are fair
    assert len({t.key for t in tasks}) == 6
    with BenchDatabase(tmp_path / "b.db") as db:
        _fill_db(db, tasks[:4])  # "killed" after 4 runs
    with BenchDatabase(tmp_path / "b.db") as db:  # reopens, keeps what was committed
        done = db.finished_keys()
        assert done == {t.key for t in tasks[:4]}
        todo = [t for t in tasks if t.key not in done]
        assert [(t.planner, t.seed) for t in todo] == [("PRM", 3), ("KPIECE1", 3)]
        recs = db.records(t.key for t in tasks)
    assert len(recs) == 4
    assert set(CSV_COLUMNS) <= set(recs[0])
    # the key changes with the time limit and with the scenario's content
    other_limit = make_tasks([sphere], ["PRM"], [1], 6.0)[0]
    assert other_limit.key != tasks[0].key
    assert "paper_sphere@" in tasks[0].key


def test_quality_columns_in_database_csv_and_summary(tmp_path, sphere, monkeypatch):
    """Solved runs carry the plan-quality columns; a database without them gains them."""
    from dexplan.bench import database

    assert set(bench.QUALITY_COLUMNS) < set(CSV_COLUMNS)
    tasks = make_tasks([sphere], ["PRM", "RRTConnect"], [1, 2, 3], 5.0)
    old = tuple(c for c in RUN_COLUMNS if c[0] not in {*bench.QUALITY_COLUMNS, "quality_time"})
    monkeypatch.setattr(database, "RUN_COLUMNS", old)  # a database of an earlier version
    with BenchDatabase(tmp_path / "b.db") as db:
        _fill_db(db, tasks[:2])
    monkeypatch.undo()
    with BenchDatabase(tmp_path / "b.db") as db:  # reopened: the columns are added
        recs = _fill_db(db, tasks[2:])
        rows = db.records()
    assert [r["execution_time_s"] for r in rows[:2]] == [None, None]  # stored before
    for rec, row in zip(recs, rows[2:], strict=True):
        for name in (*bench.QUALITY_COLUMNS, "quality_time"):
            assert row[name] == rec[name], name
        if row["solved"]:
            want = _fake_quality(rec["time"])
            assert row["execution_time_s"] == want.execution_time_s
            assert row["worst_torque_ratio"] == want.worst_torque_ratio
            assert rec["stats"]["quality"]["weakest_hold"] == want.weakest_hold
        else:
            assert row["weakest_hold"] is None and row["max_grip_force_n"] is None
    path = write_csv(rows, tmp_path / "runs.csv")
    with open(path, newline="") as fh:
        got = list(csv.DictReader(fh))
    assert float(got[2]["max_grip_force_n"]) == rows[2]["max_grip_force_n"]
    summary = summarize(rows[2:], "PRM")
    solved = [r for r in recs if r["solved"] and r["planner"] == "PRM"]
    by = {r["planner"]: r for r in summary}
    assert by["PRM"]["execution_time_median"] == pytest.approx(
        statistics.median(r["execution_time_s"] for r in solved)
    )
    assert by["PRM"]["worst_torque_ratio_max"] == max(r["worst_torque_ratio"] for r in solved)
    text = format_summary(summary, "PRM")
    assert "rot deg" in text and "no-prog" in text


def test_scenario_hash_tracks_content(tmp_path, sphere):
    assert scenario_hash(sphere) == scenario_hash(load_scenario(builtin_scenario_path()))
    text = builtin_scenario_path().read_text()
    path = tmp_path / "paper_sphere.toml"
    path.write_text(text)
    assert scenario_hash(load_scenario(path)) == scenario_hash(sphere)  # folder does not matter
    path.write_text(text.replace("mu = 0.8", "mu = 0.7"))
    assert scenario_hash(load_scenario(path)) != scenario_hash(sphere)
    # planner name, seed and time limit are set by the sweep: not part of the hash
    path.write_text(text.replace("time_limit = 30.0", "time_limit = 5.0"))
    assert scenario_hash(load_scenario(path)) == scenario_hash(sphere)


def test_resolve_scenario(tmp_path):
    assert resolve_scenario("paper_sphere").name == "paper_sphere"
    assert resolve_scenario(ROOT / "scenarios" / "cube_obstacle.toml").name == "cube_obstacle"
    with pytest.raises(ScenarioError, match="not found"):
        resolve_scenario(tmp_path / "missing.toml")
    with pytest.raises(ScenarioError, match="not found"):
        resolve_scenario("no_such_scenario")


# ------------------------------------------------------------------ summary, CSV, plots


def test_summary_ratios_against_baseline(sphere):
    tasks = make_tasks([sphere], ["PRM", "RRTConnect"], [1, 2, 3, 4], 5.0)
    recs = []
    for t in tasks:
        fast = t.planner == "RRTConnect"
        recs.append(
            _fake_record(t, solved=fast or t.seed != 4, time_s=(1.0 if fast else 2.0), nodes=50)
        )
    rows = summarize(recs, "PRM")
    by = {r["planner"]: r for r in rows}
    assert by["PRM"]["success_rate"] == 0.75 and by["RRTConnect"]["success_rate"] == 1.0
    assert by["PRM"]["time_median_vs_base"] == 1.0
    assert by["RRTConnect"]["time_median_vs_base"] == pytest.approx(0.5)
    assert by["RRTConnect"]["success_rate_vs_base"] == pytest.approx(4 / 3)
    assert by["RRTConnect"]["plan_verify_ratio_median"] == pytest.approx(2.0)
    assert by["PRM"]["verify_ok"] == 3
    text = format_summary(rows, "PRM")
    assert "PRM*" in text and "RRTConnect" in text and "75%" in text
    no_base = summarize(recs, None)
    assert all(math.isnan(r["time_median_vs_base"]) for r in no_base)


def test_csv_rows(tmp_path, sphere):
    tasks = make_tasks([sphere], ["PRM", "RRTConnect"], [1, 2], 5.0)
    recs = [_fake_record(t, solved=True, time_s=1.5, nodes=7) for t in tasks]
    path = write_csv(recs, tmp_path / "runs.csv")
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 4
    assert list(rows[0]) == list(CSV_COLUMNS)
    assert rows[0]["planner"] == "PRM" and rows[0]["status_name"] == "solved"
    assert float(rows[0]["time"]) == 1.5 and rows[0]["verify_time"] == "0.5"


@needs_matplotlib
def test_plots_from_records(tmp_path, sphere, cube):
    tasks = make_tasks([sphere, cube], ["PRM", "RRTConnect", "KPIECE1"], [1, 2, 3], 5.0)
    recs = [
        _fake_record(t, solved=(i % 4 != 0), time_s=0.5 + i % 5, nodes=10 + i)
        for i, t in enumerate(tasks)
    ]
    # a planner that never solves one scenario still plots
    for r in recs:
        if r["planner"] == "KPIECE1" and r["scenario"] == "cube_obstacle":
            set_status(r, "no_gsn_path")
            r["regrasps"] = None
    paths = plot_results(recs, tmp_path, "PRM")
    assert [p.name for p in paths] == list(bench.PLOT_NAMES)
    for p in paths:
        assert p.stat().st_size > 5000
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@needs_matplotlib
def test_plots_of_a_large_sweep_stay_legible(tmp_path):
    """13 scenarios x 13 planners: panels wrap into rows and success is a heat map."""
    import struct

    recs = []
    for s in range(13):
        for p in range(13):
            for seed in (1, 2):
                recs.append(
                    {
                        "scenario": f"scenario_{s}", "planner": f"Planner{p}", "seed": seed,
                        "solved": (s + p + seed) % 3 != 0, "time": 0.5 + p, "time_limit": 30.0,
                        "graph_states": 10 + s, "regrasps": 1 + s % 4,
                    }
                )  # fmt: skip
    paths = plot_results(recs, tmp_path, None)

    def size(path):  # PNG header: width, height
        return struct.unpack(">II", path.read_bytes()[16:24])

    widths = {p.name: size(p)[0] for p in paths}
    # one row of 13 panels of 13 planners was 16,000 px wide; 24 inches at 110 dpi is 2640
    assert max(widths.values()) < 3000, widths
    w, h = size(tmp_path / "bench_success.png")
    assert w < 2000 and h < 1500


# ------------------------------------------------------------------ bad inputs


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"planners": "PRM,NoSuchPlanner"}, PlannerError, "NoSuchPlanner"),
        ({"planners": " , "}, InvalidInputError, "at least one planner"),
        ({"seeds": 0}, InvalidInputError, "seeds"),
        ({"time_limit": 0.0}, InvalidInputError, "time-limit"),
        ({"time_limit": -1.0}, InvalidInputError, "time-limit"),
        ({"time_limit": float("nan")}, InvalidInputError, "time-limit"),
        ({"jobs": 0}, InvalidInputError, "jobs"),
        ({"first_seed": -1}, InvalidInputError, "first-seed"),
        ({"baseline": "Nope"}, PlannerError, "Nope"),
        ({"scenarios": ["missing.toml"]}, ScenarioError, "not found"),
    ],
)
def test_bad_inputs_raise_before_any_run(tmp_path, kwargs, error, match):
    args = {"scenarios": ["paper_sphere"], "planners": "PRM", "seeds": 1, "time_limit": 1.0}
    args.update(kwargs)
    out = tmp_path / "out"
    with pytest.raises(error, match=match):
        run_benchmark(
            args.pop("scenarios"),
            args.pop("planners"),
            args.pop("seeds"),
            args.pop("time_limit"),
            out_dir=out,
            **args,
        )
    assert not (out / bench.DB_NAME).exists()


def _cli(*args: str, cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    return subprocess.run(
        [sys.executable, "-m", "dexplan.cli", "bench", *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["paper_sphere", "--planners", "PRM,Bogus"], "unknown planner 'Bogus'"),
        (["paper_sphere", "--seeds", "0"], "--seeds"),
        (["paper_sphere", "--time-limit", "0"], "--time-limit"),
        (["nope.toml"], "not found"),
    ],
)
def test_cli_bad_inputs_exit_2(tmp_path, args, match):
    res = _cli(*args, "-o", str(tmp_path / "o"), cwd=tmp_path, timeout=120)
    assert res.returncode == 2, res.stderr
    assert match in res.stderr
    assert "Traceback" not in res.stderr


HAS_RAY = importlib.util.find_spec("ray") is not None


@pytest.mark.skipif(not HAS_RAY, reason="ray is not installed: the cluster check is not reached")
def test_cli_ray_address_where_nothing_listens_exits_2(tmp_path):
    """With Ray installed, ``--ray HOST:PORT`` is checked: nothing listens on port 1."""
    res = _cli("paper_sphere", "--ray", "127.0.0.1:1", "-o", str(tmp_path / "o"), cwd=tmp_path)
    assert res.returncode == 2, res.stderr
    assert "--ray '127.0.0.1:1': no Ray cluster answers there" in res.stderr
    assert "ray start --head --port 1" in res.stderr  # and how to start one
    assert "Traceback" not in res.stderr and not (tmp_path / "o").exists()


@pytest.mark.skipif(HAS_RAY, reason="ray is installed: --ray does not need it")
def test_cli_ray_without_ray_exits_2(tmp_path):
    res = _cli("paper_sphere", "--ray", "127.0.0.1:1", "-o", str(tmp_path / "o"), cwd=tmp_path)
    assert res.returncode == 2, res.stderr
    assert "--ray needs Ray" in res.stderr and "Traceback" not in res.stderr


# ------------------------------------------------------------------ real sweeps

# generous: the sweep's plans take seconds; a slow or busy machine must not fail them
SWEEP_TIME_LIMIT = 120.0


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    """paper_sphere, PRM (the baseline) and RRTConnect, seeds 1-2, through the API."""
    if not _planning_available():
        pytest.skip("the planner cannot be imported yet")
    out = tmp_path_factory.mktemp("sweep")
    events = []
    res = run_benchmark(
        ["paper_sphere"],
        "RRTConnect",  # the baseline PRM is added in front
        2,
        SWEEP_TIME_LIMIT,
        out_dir=out,
        jobs=2,
        plots=importlib.util.find_spec("matplotlib") is not None,
        progress=events.append,
    )
    return res, events


@needs_planning
def test_sweep_writes_database_csv_plots(sweep):
    res, events = sweep
    assert res.planners == ["PRM", "RRTConnect"]
    assert res.new_runs == 4 and res.skipped == 0
    assert res.counts["experiments"] == 1
    assert res.counts["plannerConfigs"] == 2
    assert res.counts["runs"] == 4 and res.counts["dexplan_runs"] == 4
    assert res.counts["progress"] >= 4 * 3  # setup, stages..., done
    assert [(r["planner"], r["seed"]) for r in res.records] == [
        ("PRM", 1),
        ("PRM", 2),
        ("RRTConnect", 1),
        ("RRTConnect", 2),
    ]
    for r in res.records:
        assert r["status_name"] in PLAN_STATUSES and r["status_name"] not in ("error", "crash")
        assert r["time"] is not None and r["time"] > 0
        # the planner's processor time: the worker's own, so > 0 and finite
        assert r["cpu_time"] is not None and 0 < r["cpu_time"] < math.inf
        assert r["memory"] > 50  # MB: the worker holds the hand, ompl and the models
        assert r["graph_states"] is not None
        assert r["states_checked"] is not None and r["rejected_collision"] is not None
        if r["solved"]:
            assert r["correct_solution"] == 1 and r["verify_violations"] == 0
            assert r["verify_time"] > 0
            assert r["plan_verify_ratio"] == pytest.approx(r["time"] / r["verify_time"])
            assert len(r["plan_sha256"]) == 64
            assert r["regrasps"] + r["transfers"] == r["solution_segments"] >= 1
            assert bench.REDUCTION_METHODS[r["reduction_method"]] in ("gaits", "edges")
            # the plan's quality, computed after the query
            assert r["execution_time_s"] > 0 and r["max_grip_force_n"] > 0
            assert r["weakest_hold"] > 0 and 0 <= r["worst_torque_ratio"] <= 1
            assert 0 <= r["regrasps_without_progress"] <= r["regrasps"]
            assert r["quality_time"] > 0
    assert any(r["solved"] for r in res.records), "no run solved paper_sphere"
    # progress: a first call with the totals, then one per run
    assert events[0].record is None and events[0].total == 4
    assert [e.done for e in events[1:]] == [1, 2, 3, 4]
    with open(res.csv, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 4 and {r["planner"] for r in rows} == {"PRM", "RRTConnect"}
    assert [row["planner"] for row in res.summary] == ["PRM", "RRTConnect"]
    assert res.summary[0]["time_median_vs_base"] == 1.0
    assert res.summary[0]["cpu_time_median"] > 0
    if importlib.util.find_spec("matplotlib") is not None:
        assert sorted(p.name for p in res.plots) == sorted(bench.PLOT_NAMES)
        assert all(p.is_file() for p in res.plots)
    conn = sqlite3.connect(res.database)
    assert conn.execute("SELECT COUNT(*) FROM runs WHERE experimentid IS NULL").fetchone()[0] == 0
    assert conn.execute("SELECT name, timelimit FROM experiments").fetchall() == [
        ("paper_sphere", SWEEP_TIME_LIMIT)
    ]
    methods = conn.execute("SELECT value, description FROM enums WHERE name='reduction method'")
    assert dict(methods.fetchall()) == {0: "gaits", 1: "edges"}


@needs_planning
def test_sweep_resumes_without_running_again(sweep):
    res, _ = sweep
    events = []
    again = run_benchmark(
        ["paper_sphere"],
        "PRM,RRTConnect",
        2,
        SWEEP_TIME_LIMIT,
        out_dir=res.out_dir,
        plots=False,
        progress=events.append,
    )
    assert again.new_runs == 0 and again.skipped == 4
    assert len(events) == 1 and events[0].skipped == 4 and events[0].total == 0
    assert again.counts["runs"] == 4
    assert [r["key"] for r in again.records] == [r["key"] for r in res.records]


@needs_planning
def test_cli_bench_spawn_backend_same_plans_and_resume(sweep, tmp_path):
    """The CLI, with spawned workers, plans RRTConnect seed 1 as the forkserver pool did."""
    res, _ = sweep
    out = tmp_path / "cli"
    args = ["paper_sphere", "--planners", "RRTConnect", "--baseline", "none", "--seeds", "1"]
    args += ["--time-limit", str(SWEEP_TIME_LIMIT), "-o", str(out), "--start-method", "spawn"]
    first = _cli(*args, "--no-plots", cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    assert "RRTConnect" in first.stdout and "runs: 1 new, 0 resumed" in first.stdout
    with BenchDatabase(out / bench.DB_NAME) as db:
        (rec,) = db.records()
    ref = next(r for r in res.records if r["planner"] == "RRTConnect" and r["seed"] == 1)
    assert ref["solved"], "RRTConnect seed 1 did not solve: nothing to compare"
    assert rec["status_name"] == ref["status_name"]
    # a seed gives the same plan in any fresh process (the roadmap size may differ: the
    # GSn search runs in clock-limited rounds)
    assert rec["plan_sha256"] == ref["plan_sha256"]
    assert (rec["regrasps"], rec["transfers"]) == (ref["regrasps"], ref["transfers"])
    second = _cli(*args, "--no-plots", cwd=tmp_path)
    assert second.returncode == 0, second.stderr
    assert "runs: 0 new, 1 resumed" in second.stdout


@needs_planning
def test_overrunning_run_is_killed_and_recorded(tmp_path):
    # an unsolvable query with a 600 s limit cannot end within the 0.3 s run
    # timeout however fast the machine or the planner is: it must be killed
    unsolvable = str(ROOT / "tests" / "data" / "unsolvable_lid.toml")
    res = run_benchmark(
        [unsolvable],
        "RRTConnect",
        1,
        600.0,
        out_dir=tmp_path,
        baseline=None,
        plots=False,
        run_timeout=0.3,
    )
    (rec,) = res.records
    assert rec["status_name"] == "killed" and rec["status"] == 7 and rec["solved"] == 0
    assert "exceeded" in rec["message"]
    again = run_benchmark(
        [unsolvable], "RRTConnect", 1, 600.0, out_dir=tmp_path, baseline=None, plots=False
    )
    assert again.new_runs == 0  # a killed run is a result: resuming does not retry it


@needs_planning
def test_sweep_killed_half_way_leaves_a_usable_database(tmp_path):
    """SIGKILL the CLI after its first committed run; the database opens and resumes."""
    import signal
    import time

    out = tmp_path / "killed"
    args = ["paper_sphere", "--planners", "KPIECE1", "--baseline", "none", "--seeds", "4"]
    args += ["--time-limit", "10", "-j", "1", "-o", str(out), "--no-plots", "-q"]
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    proc = subprocess.Popen(
        [sys.executable, "-m", "dexplan.cli", "bench", *args],
        cwd=tmp_path,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    db_path = out / bench.DB_NAME
    n = 0
    # no deadline of its own: however slow the machine, the first run commits
    # (or the sweep ends); pytest's timeout is the net
    while proc.poll() is None:
        if db_path.exists():
            try:
                conn = sqlite3.connect(f"file:{db_path}?mode=ro", uri=True, timeout=5)
                n = conn.execute("SELECT COUNT(*) FROM dexplan_runs").fetchone()[0]
                conn.close()
            except sqlite3.OperationalError:
                n = 0
            if n >= 1:
                break
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)  # no clean-up at all: as if the machine went down
    proc.wait(30)
    with BenchDatabase(db_path) as db:
        done = len(db.finished_keys())
        counts = db.counts()
    assert 1 <= done <= 4
    assert counts["runs"] == counts["dexplan_runs"] == done  # no half-written run
    again = _cli(*args, cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    assert f"runs: {4 - done} new, {done} resumed" in again.stdout
    with BenchDatabase(db_path) as db:
        assert len(db.finished_keys()) == 4


@pytest.mark.slow
@needs_planning
@pytest.mark.skipif(importlib.util.find_spec("ray") is None, reason="ray is not installed")
def test_ray_backend_matches_local_pool(sweep, tmp_path):
    res, _ = sweep
    ray_res = run_benchmark(
        ["paper_sphere"],
        "PRM,RRTConnect",
        2,
        SWEEP_TIME_LIMIT,
        out_dir=tmp_path,
        jobs=2,
        ray_address="local",
        plots=False,
    )
    assert ray_res.backend == "ray" and ray_res.new_runs == 4
    local = {r["key"]: r for r in res.records}
    compared = 0
    for r in ray_res.records:
        assert r["backend"] == "ray"
        ref = local[r["key"]]
        if r["planner"] == "RRTConnect" and ref["solved"]:  # deterministic: seed for seed
            assert r["status_name"] == ref["status_name"]
            assert r["plan_sha256"] == ref["plan_sha256"]
            for col in (
                "regrasps",
                "transfers",
                "waypoints",
                "object_path_rad",
                "joint_travel_rad",
            ):
                assert r[col] == ref[col], col
            compared += 1
    assert compared >= 1, "RRTConnect solved no seed: nothing to compare"


@needs_planning
def test_report_covers_earlier_seeds_of_the_same_sweep(sweep):
    res, _ = sweep
    fewer = run_benchmark(
        ["paper_sphere"], "PRM,RRTConnect", 1, SWEEP_TIME_LIMIT, out_dir=res.out_dir, plots=False
    )
    assert fewer.new_runs == 0 and fewer.skipped == 2
    assert len(fewer.records) == 4  # seed 2, stored by the longer sweep, is reported too
    assert all(r["code"] == bench.code_fingerprint() for r in fewer.records)
