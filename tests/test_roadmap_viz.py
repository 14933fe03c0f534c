"""Roadmap recordings in orientation space, and a large roadmap in few archetypes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dexplan.planning.roadmap.graph import Roadmap

pytest.importorskip("rerun")

from dexplan.viz.roadmap_recording import record_roadmap, rotation_vectors
from tests.test_viz import column, read_rrd


def _random_quats(rng: np.random.Generator, n: int) -> np.ndarray:
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def test_rotation_vectors_match_scipy() -> None:
    from scipy.spatial.transform import Rotation

    q = _random_quats(np.random.default_rng(0), 500)
    got = rotation_vectors(q)
    want = Rotation.from_quat(q).as_rotvec()  # scipy: XYZW, angle in [0, pi]
    np.testing.assert_allclose(got, want, atol=1e-9)
    np.testing.assert_allclose(rotation_vectors(-q), got, atol=1e-9)  # double cover
    assert np.allclose(rotation_vectors(np.array([[0, 0, 0, 1.0]])), 0.0)


def _big_roadmap(n: int, seed: int = 1) -> Roadmap:
    rng = np.random.default_rng(seed)
    V = np.zeros((n, 19))
    V[:, :3] = rng.uniform(-0.02, 0.02, (n, 3)) + np.array([0.0, 0.0, 0.1])
    V[:, 3:7] = _random_quats(rng, n)
    # chains of 10 nodes (n / 10 components), every other chain linked to the next
    edges = np.array([(i, i + 1) for i in range(n - 1) if (i + 1) % 10], dtype=np.int64)
    links = np.array([(i, i + 10) for i in range(9, n - 10, 20)], dtype=np.int64)
    return Roadmap(V, edges, links, "PRM", "test")


def test_ten_thousand_nodes_in_few_archetypes(tmp_path: Path) -> None:
    rm = _big_roadmap(10_000)
    out = tmp_path / "big.rrd"
    summary = record_roadmap(rm, out)
    assert summary.components == 1000 and sum(summary.nodes) == 10_000
    assert summary.merged_components == 1000 - len(rm.links)
    assert summary.links[0] == 1 and summary.links[1] == 1 and summary.links[2] == 1
    ents = read_rrd(out)
    for path, comp, count in (
        ("/orientation/nodes", "Points3D:positions", 10_000),
        ("/orientation/edges", "LineStrips3D:strips", len(rm.edges)),
        ("/orientation/links", "LineStrips3D:strips", len(rm.links)),
        ("/world/roadmap/nodes", "Points3D:positions", 10_000),
        ("/world/roadmap/axes", "LineStrips3D:strips", 30_000),
    ):
        assert len(ents[path]) <= 2, path  # one archetype each: a chunk or two, not per node
        assert len(column(ents[path], comp)) == count, path
    P = np.array(column(ents["/orientation/nodes"], "Points3D:positions"))
    assert np.all(np.linalg.norm(P, axis=1) <= np.pi + 1e-5)
    np.testing.assert_allclose(P, rotation_vectors(rm.vertices[:, 3:7]), atol=1e-5)
