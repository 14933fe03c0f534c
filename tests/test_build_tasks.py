"""The learning phase in tasks: ``roadmap build --jobs K`` and ``--ray``."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

import dexplan
from dexplan.model.scenario import load_scenario
from dexplan.planning.roadmap import tasks as bt
from dexplan.planning.roadmap.graph import Roadmap
from dexplan.planning.roadmap.learning import BuildSettings, build_roadmap
from tests.cli_contract import assert_bad_input, run_cli

PAPER = Path(dexplan.__file__).resolve().parent / "data" / "scenarios" / "paper_sphere.toml"


def _same(a: Roadmap, b: Roadmap) -> None:
    np.testing.assert_array_equal(a.vertices, b.vertices)
    np.testing.assert_array_equal(a.edges, b.edges)
    np.testing.assert_array_equal(a.links, b.links)


@pytest.fixture(scope="module")
def inline() -> Roadmap:
    """A 16-node roadmap built in tasks in this process (``--jobs 1``)."""
    rm, st = build_roadmap(load_scenario(PAPER), BuildSettings(nodes=16, seed=3, jobs=1))
    assert st.workers == 1 and st.tasks > 0
    return rm


def test_task_seeds_differ_by_kind_and_index() -> None:
    seeds = {bt.task_seed(1, kind, i) for kind in ("sample", "edge", "link") for i in range(50)}
    assert len(seeds) == 150
    assert bt.task_seed(1, "sample", 4) == bt.task_seed(1, "sample", 4)
    assert bt.task_seed(1, "sample", 4) != bt.task_seed(2, "sample", 4)


def test_task_build_is_a_checked_roadmap(inline: Roadmap) -> None:
    """16 sampled GSn states, edges only between near vertices, and one verdict per pair."""
    scenario = load_scenario(PAPER)
    assert inline.n_vertices == 16
    assert len(inline.edges) > 0
    assert np.all(inline.edges[:, 0] < inline.edges[:, 1])
    assert len(np.unique(inline.edges, axis=0)) == len(inline.edges)
    worker = bt.TaskWorker(scenario, scenario.planner.space)
    v = inline.vertices
    ctx = worker._ctx
    assert all(ctx.validity.is_valid(x) for x in v)
    edges = {tuple(e) for e in inline.edges.tolist()}
    pairs = [(a, b) for a in range(6) for b in range(a + 1, 16)]
    verdicts = worker.run(("edge", [(v[a], v[b]) for a, b in pairs]))
    for (a, b), ok in zip(pairs, verdicts, strict=True):
        if (a, b) in edges:
            assert ok, (a, b)  # every edge is a valid GSn motion


def test_the_roadmap_does_not_depend_on_the_worker_count(inline: Roadmap) -> None:
    """Two local processes give the vertices, edges and links of one."""
    rm, st = build_roadmap(load_scenario(PAPER), BuildSettings(nodes=16, seed=3, jobs=2))
    assert st.workers == 2
    _same(rm, inline)
    other, _ = build_roadmap(load_scenario(PAPER), BuildSettings(nodes=16, seed=4, jobs=1))
    assert not np.array_equal(other.vertices, inline.vertices)


@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("ray") is None, reason="ray is not installed")
def test_ray_builds_the_same_roadmap(inline: Roadmap) -> None:
    """A local Ray instance (2 CPUs) runs the same tasks: the same roadmap."""
    import ray

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        settings = BuildSettings(nodes=16, seed=3, ray_address="auto")
        rm, st = build_roadmap(load_scenario(PAPER), settings)
    finally:
        ray.shutdown()
    assert st.workers == 2
    _same(rm, inline)


def test_cli_jobs(capfd, tmp_path: Path) -> None:
    out = tmp_path / "rm.npz"
    code, stdout, _ = run_cli(
        capfd, "roadmap", "build", PAPER, "--nodes", "16", "--jobs", "2", "-o", out, "-q"
    )
    assert code == 0
    assert "workers: 2" in stdout
    rm = Roadmap.load(out)
    assert rm.n_vertices == 16 and rm.build["workers"] == 2 and rm.build["tasks"] > 0


@pytest.mark.parametrize("jobs", ["0", "300"])
def test_cli_bad_jobs(capfd, tmp_path: Path, jobs: str) -> None:
    out = tmp_path / "rm.npz"
    code, _, err = run_cli(
        capfd, "roadmap", "build", PAPER, "--nodes", "16", "--jobs", jobs, "-o", out
    )
    assert_bad_input(code, err, names=["--jobs", jobs], outputs=[out])
