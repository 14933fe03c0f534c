"""Force closure against an independent convex-hull reference (scipy / qhull)."""

import math

import numpy as np
import pytest
from scipy.spatial import ConvexHull, QhullError

from dexplan.exceptions import InvalidInputError
from dexplan.grasp import (
    contact_wrenches,
    force_closure_quality,
    friction_cone_edges,
    min_subgrasp_quality,
)
from dexplan.pose import quat_to_matrix, random_quaternion


def reference_epsilon(points, normals_in, mu, edges, torque_scale) -> float:
    """Ferrari-Canny epsilon (L1) from the convex hull of the edge wrenches.

    The linearized cones are the model under test's (same edge directions:
    a different tangent basis is a different polyhedral cone, whose verdict
    may differ near the boundary); the wrenches, the hull and the epsilon are
    computed here, independently of dexplan.grasp's solver.
    """
    cones = friction_cone_edges(np.asarray(normals_in), mu, edges)
    w = []
    for p, fs in zip(points, cones, strict=True):
        for f in fs:
            w.append(np.concatenate([f, np.cross(p, f) / torque_scale]))
    w = np.array(w)
    if np.linalg.matrix_rank(w, tol=1e-9) < 6:
        return 0.0
    try:
        hull = ConvexHull(w)
    except QhullError:
        return 0.0
    offsets = hull.equations[:, -1]  # unit normals: n.x + offset <= 0 inside
    return float(max(0.0, np.min(-offsets)))


def random_grasp(rng: np.random.Generator):
    k = int(rng.integers(2, 6))
    if rng.random() < 0.5:  # sphere
        r = rng.uniform(0.02, 0.08)
        d = rng.normal(size=(k, 3))
        d /= np.linalg.norm(d, axis=1)[:, None]
        p, n = r * d, -d
    else:  # box faces
        half = rng.uniform(0.01, 0.06, 3)
        axis = rng.integers(0, 3, k)
        sign = rng.choice([-1.0, 1.0], k)
        p = rng.uniform(-half, half, (k, 3))
        p[np.arange(k), axis] = sign * half[axis]
        n = np.zeros((k, 3))
        n[np.arange(k), axis] = -sign
    mu = rng.uniform(0.0, 1.5)
    return p, n, mu


def test_agrees_with_hull_reference_on_random_grasps() -> None:
    rng = np.random.default_rng(0)
    edges = 6
    n_fc = n_not = 0
    for _ in range(1000):
        p, n, mu = random_grasp(rng)
        ts = float(np.max(np.linalg.norm(p, axis=1)))
        eps = reference_epsilon(p, n, mu, edges, ts)
        q = force_closure_quality(p, n, mu, edges=edges, torque_scale=ts)
        m = len(p) * edges
        if eps == 0.0:
            assert q == 0.0 or q < 1e-6, (p, n, mu, q)
            n_not += 1
        elif eps > 1e-3:
            assert q > 0.0, (p, n, mu, eps)
            n_fc += 1
            # proven bounds: Q / sqrt(6 m) <= eps <= Q (solver tolerance aside)
            assert eps <= q * (1 + 1e-3) + 1e-6
            assert q / math.sqrt(6 * m) <= eps * (1 + 1e-3) + 1e-6
    assert n_fc > 150 and n_not > 150  # both kinds well represented


def _spread(k: int, lat: float = -0.3) -> tuple[np.ndarray, np.ndarray]:
    az = 2 * np.pi * np.arange(k) / k
    d = np.stack([np.cos(lat) * np.cos(az), np.cos(lat) * np.sin(az), np.full(k, np.sin(lat))], 1)
    d[:, :2] *= 1.0
    d /= np.linalg.norm(d, axis=1)[:, None]
    return 0.04 * d, -d


def test_classic_cases() -> None:
    # two point contacts are never force closure in 3D (no torque about their axis)
    p = np.array([[0.04, 0, 0], [-0.04, 0, 0]])
    assert force_closure_quality(p, -p / 0.04, 1.0) == 0.0
    # three or four well-spread contacts on a sphere with friction are
    for k in (3, 4):
        p, n = _spread(k, 0.0)
        for mu in (0.5, 1.0):
            assert force_closure_quality(p, n, mu, torque_scale=0.04) > 0.01
    # frictionless with few contacts is not
    p, n = _spread(4, 0.0)
    assert force_closure_quality(p, n, 0.0, torque_scale=0.04) == 0.0
    p, n = _spread(6, 0.2)
    assert force_closure_quality(p, n, 0.0, torque_scale=0.04) == 0.0
    # all contacts below the equator with little friction cannot push down
    p, n = _spread(4, -0.8)
    assert force_closure_quality(p, n, 0.2, torque_scale=0.04) == 0.0


def test_min_subgrasp_is_min_over_subgrasps_and_monotone() -> None:
    rng = np.random.default_rng(1)
    for _ in range(15):
        p, n = _spread(4, rng.uniform(-0.4, 0.3))
        p = p + rng.normal(scale=0.003, size=p.shape)
        mu = rng.uniform(0.4, 1.2)
        subs = [
            force_closure_quality(np.delete(p, i, 0), np.delete(n, i, 0), mu, torque_scale=0.04)
            for i in range(4)
        ]
        full = force_closure_quality(p, n, mu, torque_scale=0.04)
        got = min_subgrasp_quality(p, n, mu, torque_scale=0.04)
        assert got == pytest.approx(min(subs), rel=1e-3, abs=1e-6)
        assert full >= max(subs) * (1 - 1e-3) - 1e-6  # adding a contact never lowers it


def test_margin_mode_is_a_certified_lower_bound() -> None:
    rng = np.random.default_rng(2)
    for _ in range(60):
        p, n, mu = random_grasp(rng)
        if len(p) < 3:
            continue
        ts = float(np.max(np.linalg.norm(p, axis=1)))
        exact = min_subgrasp_quality(p, n, mu, torque_scale=ts)
        for margin in (0.0, 0.005, 0.05):
            fast = min_subgrasp_quality(p, n, mu, torque_scale=ts, margin=margin)
            assert fast <= exact * (1 + 1e-3) + 1e-6
            if fast > margin:
                assert exact > margin


def test_rotated_grasps_keep_their_verdict_and_bounds() -> None:
    # The 12 axes are fixed in the object frame, so the value changes when the
    # grasp turns relative to the object frame (the planner always works in the
    # object frame); the verdict does not, and the value keeps bounding the
    # epsilon of the turned grasp.
    rng = np.random.default_rng(3)
    for lat, mu in ((-0.2, 0.7), (-0.9, 0.2)):
        p, n = _spread(4, lat)
        fc0 = force_closure_quality(p, n, mu, torque_scale=0.04) > 0
        for _ in range(10):
            R = quat_to_matrix(random_quaternion(rng))
            pr, nr = p @ R.T, n @ R.T
            q = force_closure_quality(pr, nr, mu, torque_scale=0.04)
            assert (q > 0) == fc0
            eps = reference_epsilon(pr, nr, mu, 8, 0.04)
            assert eps <= q * (1 + 1e-3) + 1e-6
            assert q / math.sqrt(6 * 32) <= eps * (1 + 1e-3) + 1e-6


def test_cone_edges_and_wrenches() -> None:
    n = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    e = friction_cone_edges(n, 0.5, 8)
    assert e.shape == (2, 8, 3)
    np.testing.assert_allclose(np.linalg.norm(e, axis=2), 1.0)
    cosang = np.einsum("kej,kj->ke", e, n)
    np.testing.assert_allclose(cosang, 1 / math.sqrt(1.25))  # half-angle atan(mu)
    w = contact_wrenches(np.array([[0.0, 0.0, -0.02], [-0.03, 0, 0]]), n, 0.5, 8, 0.03)
    assert w.shape == (16, 6)
    np.testing.assert_allclose(w[:8, 3:], np.cross([0.0, 0.0, -0.02], e[0]) / 0.03)


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"points": np.zeros((3, 2))}, "points"),
        ({"normals": np.zeros((3, 3))}, "normals"),
        ({"normals": np.ones((2, 3))}, "same shape"),
        ({"mu": -0.1}, "mu"),
        ({"mu": float("nan")}, "mu"),
        ({"points": np.full((3, 3), np.inf)}, "points"),
        ({"edges": 2}, "edges"),
        ({"torque_scale": 0.0}, "torque_scale"),
    ],
)
def test_bad_inputs(kwargs, needle: str) -> None:
    args = {"points": _spread(3)[0], "normals": _spread(3)[1], "mu": 0.5}
    args.update({k: v for k, v in kwargs.items() if k in args})
    extra = {k: v for k, v in kwargs.items() if k not in args}
    with pytest.raises(InvalidInputError, match=needle):
        force_closure_quality(args["points"], args["normals"], args["mu"], **extra)
