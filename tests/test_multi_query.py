"""Multi-query: ``roadmap build|info``, many goals on one roadmap, the Python API."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

import dexplan
from dexplan.api import RoadmapPlanner
from dexplan.model.scenario import GoalSpec, load_scenario
from dexplan.model.scenario.goals import load_goals, parse_goals, random_goals
from dexplan.planning.roadmap.file import read_roadmap_arrays
from dexplan.planning.roadmap.learning import BuildSettings
from tests.cli_contract import assert_bad_input, run_cli

DATA = Path(dexplan.__file__).resolve().parent / "data" / "scenarios"
PAPER = DATA / "paper_sphere.toml"
CUBE = DATA / "cube_obstacle.toml"


def _yaw(deg: float) -> list[float]:
    h = math.radians(deg) / 2
    return [0.0, 0.0, 0.1, 0.0, 0.0, math.sin(h), math.cos(h)]


@pytest.fixture(scope="module")
def roadmap_file(tmp_path_factory) -> Path:
    """A small paper_sphere roadmap, built by the CLI (deterministic: --nodes)."""
    from dexplan.cli import main as cli

    out = tmp_path_factory.mktemp("rm") / "rm.npz"
    assert cli.run(["roadmap", "build", str(PAPER), "--nodes", "16", "-o", str(out), "-q"]) == 0
    return out


def test_build_writes_a_linked_versioned_roadmap(roadmap_file: Path) -> None:
    vertices, edges, links, meta = read_roadmap_arrays(roadmap_file)
    assert meta["format"] == "dexplan-roadmap/1"
    build = meta["build"]
    assert build["nodes"] == len(vertices) >= 10
    assert build["edges"] == len(edges) > 0 and build["links"] == len(links)
    assert build["target_nodes"] == 16 and build["seed"] == 1
    # every vertex is a GSn state of the paper hand (7 pose + 12 joints), unit quaternion
    assert vertices.shape[1] == 19
    assert np.allclose(np.linalg.norm(vertices[:, 3:7], axis=1), 1.0, atol=1e-3)


def test_build_is_deterministic_for_a_seed(capfd, tmp_path: Path, roadmap_file: Path) -> None:
    again = tmp_path / "again.npz"
    code, out, _ = run_cli(capfd, "roadmap", "build", PAPER, "--nodes", "16", "-o", again, "-q")
    assert code == 0 and "nodes:" in out
    a, b = read_roadmap_arrays(roadmap_file), read_roadmap_arrays(again)
    for x, y in zip(a[:3], b[:3], strict=True):
        assert np.array_equal(x, y)
    timing = {"time_s", "module1_time_s", "module2_time_s"}
    strip = lambda m: {k: v for k, v in m["build"].items() if k not in timing}  # noqa: E731
    assert strip(a[3]) == strip(b[3])
    assert a[3]["scenario_key"] == b[3]["scenario_key"]


def test_info_reports_sizes_components_hash_and_build(capfd, roadmap_file: Path) -> None:
    code, out, _ = run_cli(capfd, "roadmap", "info", roadmap_file)
    assert code == 0
    _, edges, links, meta = read_roadmap_arrays(roadmap_file)
    assert f"scenario_key: {meta['scenario_key']}" in out
    assert f"edges: {len(edges)}  links: {len(links)}" in out
    assert "components: " in out and "component sizes: " in out
    assert "build.module1_time_s: " in out and "build.link_attempts: " in out


@pytest.mark.parametrize(
    ("args", "names"),
    [
        (("--time", "0"), ["--time", "0"]),
        (("--nodes", "1"), ["--nodes", "1"]),
        (("--nodes", "8", "--planner", "RRTConnect"), ["--planner", "RRTConnect"]),
        (("--nodes", "8", "--seed", "-1"), ["--seed", "-1"]),
    ],
)
def test_build_bad_options(capfd, tmp_path: Path, args: tuple[str, ...], names: list[str]) -> None:
    out = tmp_path / "rm.npz"
    code, _, err = run_cli(capfd, "roadmap", "build", PAPER, *args, "-o", out)
    assert_bad_input(code, err, names=names, outputs=[out])


def test_roadmap_of_other_models_is_refused(capfd, tmp_path: Path, roadmap_file: Path) -> None:
    out = tmp_path / "q"
    code, _, err = run_cli(
        capfd, "plan", CUBE, "--load-roadmap", roadmap_file, "--random-goals", "2", "-o", out
    )
    assert_bad_input(code, err, names=["other models"])
    code, _, err = run_cli(
        capfd, "plan", CUBE, "--load-roadmap", roadmap_file, "-o", out / "p.json"
    )
    assert_bad_input(code, err, names=["other models"])


def _goals_file(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "goals.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("text", "names"),
    [
        ("goals = [", ["not valid TOML"]),
        ("name = 1\n", ["name"]),
        ("goals = []\n", ["goals", "non-empty"]),
        ("[[goals]]\nposition_tol = 0.01\n", ["goals[0].object_pose_xyzquat", "missing"]),
        (
            "[[goals]]\nobject_pose_xyzquat = [0, 0, 0.1, 0, 0, 0, 2]\n",
            ["goals[0].object_pose_xyzquat", "norm 2"],
        ),
        (
            "[[goals]]\nobject_pose_xyzquat = [0, 0, 0.1, 0, 0, 0, 1]\n"
            "[[goals]]\nobject_pose_xyzquat = [0, 0, 0.1, 0, 0, 0, 1]\nangle_tol = -1\n",
            ["goals[1].angle_tol", "-1"],
        ),
        (
            "[[goals]]\nobject_pose_xyzquat = [0, 0, 0.1, 0, 0, 0, 1]\ncolour = 'red'\n",
            ["goals[0]", "colour"],
        ),
    ],
)
def test_bad_goals_files(capfd, tmp_path: Path, text: str, names: list[str]) -> None:
    goals = _goals_file(tmp_path, text)
    out = tmp_path / "q"
    code, _, err = run_cli(capfd, "plan", PAPER, "--goals", goals, "-o", out)
    assert_bad_input(code, err, names=names, outputs=[out / "summary.csv"])


def test_missing_goals_file_and_json_output(capfd, tmp_path: Path) -> None:
    code, _, err = run_cli(capfd, "plan", PAPER, "--goals", tmp_path / "none.toml")
    assert_bad_input(code, err, names=["goals file not found"])
    code, _, err = run_cli(
        capfd, "plan", PAPER, "--random-goals", "2", "-o", tmp_path / "plan.json"
    )
    assert_bad_input(code, err, names=["-o", "folder"])
    code, _, err = run_cli(capfd, "plan", PAPER, "--random-goals", "0", "-o", tmp_path / "q")
    assert_bad_input(code, err, names=["--random-goals", "0"])


def test_goals_parse_defaults_and_random_goals() -> None:
    default = GoalSpec(np.array(_yaw(0)), 0.004, 0.04)
    goals = parse_goals({"goals": [{"object_pose_xyzquat": _yaw(30), "angle_tol": 0.1}]}, default)
    assert goals[0].position_tol == 0.004 and goals[0].angle_tol == 0.1
    scen = load_scenario(PAPER)
    a, b = random_goals(scen, 5, 3), random_goals(scen, 5, 3)
    assert all(
        np.array_equal(x.object_pose_xyzquat, y.object_pose_xyzquat)
        for x, y in zip(a, b, strict=True)
    )
    start = scen.start.object_pose_xyzquat[:3]
    assert all(np.array_equal(g.object_pose_xyzquat[:3], start) for g in a)
    poses = random_goals(scen, 20, 3, "pose")
    half = scen.workspace_half_extent
    assert all(np.all(np.abs(g.object_pose_xyzquat[:3] - start) <= half) for g in poses)


def test_each_plan_from_goals_passes_verify(capfd, tmp_path: Path, roadmap_file: Path) -> None:
    goals = _goals_file(
        tmp_path,
        "".join(f"[[goals]]\nobject_pose_xyzquat = {_yaw(d)}\n" for d in (30.0, -45.0)),
    )
    out = tmp_path / "queries"
    saved = tmp_path / "grown.npz"
    code, stdout, err = run_cli(
        capfd,
        "plan",
        PAPER,
        "--load-roadmap",
        roadmap_file,
        "--goals",
        goals,
        "--time-limit",
        "300",
        "-o",
        out,
        "--save-roadmap",
        saved,
    )
    assert code == 0, err
    rows = list(csv.DictReader((out / "summary.csv").open()))
    assert [r["query"] for r in rows] == ["1", "2"]
    assert all(r["status"] == "solved" and r["plan"] for r in rows)
    assert "solved: 2/2" in stdout
    for k, row in enumerate(rows, start=1):
        plan_file = out / f"query_{k:03d}.json"
        assert row["plan"] == plan_file.name
        report = dexplan.verify(plan_file)
        assert report.ok, report.violations[:3]
        stats = json.loads(plan_file.read_text())["stats"]
        assert stats["time_s"] == pytest.approx(float(row["time_s"]))
        assert stats["gsn_status"] in ("roadmap", "roadmap_grown")
    assert read_roadmap_arrays(saved)[0].shape[0] >= read_roadmap_arrays(roadmap_file)[0].shape[0]


def test_api_build_save_load_query(tmp_path: Path) -> None:
    scen = load_scenario(PAPER)
    built = RoadmapPlanner.build(scen, nodes=16, seed=2)
    assert built.build_stats is not None and built.build_stats.nodes == built.roadmap.n_vertices
    path = built.save(tmp_path / "rm.npz")
    rp = RoadmapPlanner.load(scen, path)
    assert np.array_equal(rp.roadmap.vertices, built.roadmap.vertices)
    assert rp.roadmap.build["seed"] == 2
    goals = [np.array(_yaw(40.0)), GoalSpec(np.array(_yaw(-20.0)))]
    plans = list(rp.query_many(goals, time_limit=300.0))
    assert [p.solved for p in plans] == [True, True]
    for p in plans:
        assert p.result.stats.gsn_status in ("roadmap", "roadmap_grown")
        assert p.result.stats.time_s > 0
        assert dexplan.verify(p.to_document(tmp_path)).ok


def test_build_settings_need_one_budget() -> None:
    with pytest.raises(dexplan.core.errors.InvalidInputError, match="exactly one"):
        BuildSettings(time_limit=1.0, nodes=10)
    with pytest.raises(dexplan.core.errors.InvalidInputError, match="exactly one"):
        BuildSettings()


def test_load_goals_file(tmp_path: Path) -> None:
    path = _goals_file(tmp_path, f"[[goals]]\nobject_pose_xyzquat = {_yaw(10)}\n")
    (g,) = load_goals(path, GoalSpec(np.array(_yaw(0))))
    assert np.allclose(g.object_pose_xyzquat, _yaw(10))


def _query_memory(roadmap_file: Path, n: int) -> tuple[list[float], list[float], int, int]:
    """Python heap (tracemalloc) and RSS (MiB) after each of ``n`` cheap queries."""
    import gc
    import tracemalloc

    rp = RoadmapPlanner.load(PAPER, roadmap_file)
    before = rp.roadmap.n_vertices
    heap, rss = [], []
    tracemalloc.start()
    try:
        for _ in range(n):
            p = rp.query(_yaw(3.0))  # a small turn: answered on the roadmap, cheap
            assert p.solved, p.result.message
            del p
            gc.collect()
            heap.append(tracemalloc.get_traced_memory()[0] / 2**20)
            with open("/proc/self/statm") as fh:
                rss.append(int(fh.read().split()[1]) * 4096 / 2**20)
    finally:
        tracemalloc.stop()
    return heap, rss, before, rp.roadmap.n_vertices


@pytest.mark.skipif(not Path("/proc/self/statm").exists(), reason="needs /proc")
def test_queries_do_not_grow_memory(roadmap_file: Path) -> None:
    """A query answered on the roadmap leaves nothing behind (fast variant: 12 queries)."""
    heap, _, before, after = _query_memory(roadmap_file, 12)
    assert after == before  # answered as it is: the roadmap did not grow
    assert heap[-1] - heap[3] < 0.25  # MiB over 8 queries (a plan kept per query would show)


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/statm").exists(), reason="needs /proc")
def test_a_thousand_queries_do_not_grow_memory(roadmap_file: Path) -> None:
    heap, rss, before, after = _query_memory(roadmap_file, 1000)
    assert after == before
    assert heap[-1] - heap[99] < 2.0  # MiB over 900 queries
    assert rss[-1] - rss[99] < 32.0


@pytest.mark.parametrize(
    ("build", "needle"),
    [([1, 2], "meta.build must be a JSON object"), ({"nodes": [1]}, "meta.build.nodes")],
)
def test_malformed_build_statistics_are_refused(
    capfd, tmp_path: Path, roadmap_file: Path, build: object, needle: str
) -> None:
    vertices, edges, links, meta = read_roadmap_arrays(roadmap_file)
    meta = {**meta, "build": build}
    bad = tmp_path / "bad.npz"
    np.savez(bad, vertices=vertices, edges=edges, links=links, meta=np.array(json.dumps(meta)))
    code, _, err = run_cli(capfd, "roadmap", "info", bad)
    assert_bad_input(code, err, names=[needle])


def test_queries_are_deterministic_and_do_not_depend_on_their_order(
    tmp_path: Path, roadmap_file: Path
) -> None:
    """The same goal gives the same plan; two goals answered in either order, the same two.

    Each run loads the roadmap afresh. A query the roadmap answers without
    growing leaves it as it was, so the next query's answer cannot depend on it.
    """
    scen = load_scenario(PAPER)
    goals = [np.array(_yaw(40.0)), np.array(_yaw(-20.0))]

    def answers(order: list[int]) -> dict[int, tuple[str, str]]:
        rp = RoadmapPlanner.load(scen, roadmap_file)
        out = {}
        for k in order:
            p = rp.query(goals[k], seed=1, time_limit=300.0)
            assert p.solved, p.result.message
            doc = p.to_document(tmp_path)
            out[k] = (p.result.stats.gsn_status, json.dumps(doc["segments"]))
        return out

    forward, backward, again = answers([0, 1]), answers([1, 0]), answers([0, 1])
    assert again == forward  # the same queries, the same plans
    assert all(status == "roadmap" for status, _ in forward.values())  # no growth
    assert backward == forward


def test_random_goals_are_planned_and_verified(capfd, tmp_path: Path, roadmap_file: Path) -> None:
    """``--random-goals 2``: two plans, each verified, each ending at its drawn goal."""
    out = tmp_path / "random"
    args = ["--random-goals", "2", "--seed", "1", "--time-limit", "300", "-o", out]
    code, stdout, err = run_cli(capfd, "plan", PAPER, "--load-roadmap", roadmap_file, *args)
    assert code == 0, err
    assert "solved: 2/2" in stdout
    rows = list(csv.DictReader((out / "summary.csv").open()))
    assert [(r["query"], r["status"]) for r in rows] == [("1", "solved"), ("2", "solved")]
    scen = load_scenario(PAPER)
    # the goals drawn: the same seed gives the same goals (the object clear of obstacles)
    drawn = random_goals(scen, 2, 1)
    for k, goal in enumerate(drawn, start=1):
        doc = json.loads((out / f"query_{k:03d}.json").read_text())
        assert dexplan.verify(doc).ok
        np.testing.assert_allclose(doc["goal"]["object_pose_xyzquat"], goal.object_pose_xyzquat)
