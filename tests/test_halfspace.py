"""The half-space test: sound against the force-closure quality, and it does reject."""

from __future__ import annotations

import numpy as np
import pytest

from dexplan.model.grasp import force_closure_quality, min_subgrasp_quality
from dexplan.model.grasp.halfspace import cannot_be_force_closure


def _random_normals(rng: np.random.Generator, m: int, k: int) -> np.ndarray:
    n = rng.normal(size=(m, k, 3))
    return n / np.linalg.norm(n, axis=2, keepdims=True)


@pytest.mark.parametrize(("mu", "contact_model"), [(0.8, "point"), (0.4, "point"), (0.5, "soft")])
def test_rejected_subgrasps_are_not_force_closure(mu: float, contact_model: str) -> None:
    rng = np.random.default_rng(3)
    normals = _random_normals(rng, 1500, 4)
    rejected = cannot_be_force_closure(normals, mu)
    assert 0 < rejected.sum() < len(normals)
    torsion = 0.01 if contact_model == "soft" else 0.0
    for n_out in normals[rejected][:150]:
        points = 0.05 * n_out  # a sphere: outward normal = direction of the point
        q = min_subgrasp_quality(points, -n_out, mu, contact_model=contact_model, torsion=torsion)
        assert q == 0.0


def test_whole_grasp_test_is_sound() -> None:
    rng = np.random.default_rng(4)
    normals = _random_normals(rng, 1500, 3)
    rejected = cannot_be_force_closure(normals, 0.6, subgrasps=False)
    assert 0 < rejected.sum() < len(normals)
    for n_out in normals[rejected][:150]:
        assert force_closure_quality(0.05 * n_out, -n_out, 0.6) == 0.0


def test_clustered_normals_are_rejected_and_opposed_ones_are_not() -> None:
    up = np.array([0.0, 0.0, 1.0])
    tilt = np.array([[0.1, 0.0, 1.0], [-0.1, 0.05, 1.0], [0.0, -0.1, 1.0]])
    clustered = tilt / np.linalg.norm(tilt, axis=1, keepdims=True)
    opposed = np.array([up, -up, [1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    out = cannot_be_force_closure(np.stack([clustered, opposed[:3]]), 0.5, subgrasps=False)
    assert out.tolist() == [True, False]
    # every 3-contact subgrasp of four spread normals may hold: not ruled out
    assert not cannot_be_force_closure(opposed[None], 0.8)[0]
