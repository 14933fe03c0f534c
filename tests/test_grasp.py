"""Force closure against independent references (scipy qhull hull and HiGHS LPs).

The references rebuild the linearized cones, the edge wrenches, the hull and the
12-direction LP here, from the definitions, without dexplan.model.grasp's solver. The
pyramid orientation (tangent basis) is part of the model: the reference uses the
same documented basis (Duff et al. 2017), re-implemented here and checked against
``friction_cone_edges``.
"""

import itertools
import math

import numpy as np
import pytest
from scipy.optimize import linprog
from scipy.spatial import ConvexHull, QhullError

from dexplan.core.errors import InvalidInputError
from dexplan.model.grasp import (
    ForceClosure,
    contact_wrenches,
    force_closure_quality,
    friction_cone_edges,
    friction_cone_facets,
    is_force_closure,
    min_subgrasp_quality,
)

EDGES = 8
NNLS = ForceClosure(solver="nnls")


# ---------------------------------------------------------------------------
# Independent references
# ---------------------------------------------------------------------------


def ref_edges(normals, mu, edges):
    """Pyramid edges from the definition (Duff et al. basis), shape (k, edges, 3)."""
    out = []
    for n in np.asarray(normals, dtype=float):
        n = n / np.linalg.norm(n)
        sign = 1.0 if n[2] >= 0 else -1.0
        a = -1.0 / (sign + n[2])
        b = n[0] * n[1] * a
        t1 = np.array([1.0 + sign * n[0] ** 2 * a, sign * b, -sign * n[0]])
        t2 = np.array([b, sign + n[1] ** 2 * a, -n[1]])
        rows = []
        for e in range(edges):
            th = 2 * math.pi * e / edges
            f = n + mu * (math.cos(th) * t1 + math.sin(th) * t2)
            rows.append(f / np.linalg.norm(f))
        out.append(rows)
    return np.array(out)


def ref_wrenches(points, normals, mu, edges, torque_scale):
    w = []
    for p, fs in zip(np.asarray(points, float), ref_edges(normals, mu, edges), strict=True):
        for f in fs:
            w.append(np.concatenate([f, np.cross(p, f) / torque_scale]))
    return np.array(w)


def hull_epsilon(w):
    """Signed Ferrari-Canny epsilon of the hull of wrenches ``w`` (-inf: rank < 6).

    Positive: radius of the largest origin-centred ball inside the hull. Negative
    (or -inf when the wrenches do not span 6D): the origin is outside the hull.
    """
    if np.linalg.matrix_rank(w - w.mean(axis=0), tol=1e-9) < 6:
        return -math.inf
    try:
        hull = ConvexHull(w)
    except QhullError:
        return -math.inf
    return float(np.min(-hull.equations[:, -1]))  # unit normals: n.x + off <= 0 inside


def lp_quality(w):
    """q = min_j max{t : t d_j = W^T lam, lam >= 0, sum(lam) <= 1} (HiGHS)."""
    m = len(w)
    best = math.inf
    for j in range(12):
        d = np.zeros(6)
        d[j % 6] = 1.0 if j < 6 else -1.0
        c = np.zeros(m + 1)
        c[-1] = -1.0
        a_eq = np.hstack([w.T, -d[:, None]])
        a_ub = np.concatenate([np.ones(m), [0.0]])[None, :]
        res = linprog(c, A_ub=a_ub, b_ub=[1.0], A_eq=a_eq, b_eq=np.zeros(6), method="highs")
        assert res.status == 0
        best = min(best, -res.fun)
    return best


def ref_signed_epsilon(points, normals, mu, edges, torque_scale):
    """Signed Ferrari-Canny epsilon of the hull of the grasp's edge wrenches."""
    return hull_epsilon(ref_wrenches(points, normals, mu, edges, torque_scale))


def ref_lp_quality(points, normals, mu, edges, torque_scale):
    """The 12-direction LP quality ``q`` of the grasp's edge wrenches."""
    return lp_quality(ref_wrenches(points, normals, mu, edges, torque_scale))


def random_grasp(rng, k=None, mu=None, kind=None):
    """Contacts on a sphere or a box of random size, inward normals."""
    k = int(rng.integers(2, 6)) if k is None else k
    kind = kind or ("sphere" if rng.random() < 0.5 else "box")
    if kind == "sphere":
        r = rng.uniform(0.01, 0.1)
        d = rng.normal(size=(k, 3))
        d /= np.linalg.norm(d, axis=1)[:, None]
        p, n = r * d, -d
    else:
        half = rng.uniform(0.005, 0.08, 3)
        axis = rng.integers(0, 3, k)
        sign = rng.choice([-1.0, 1.0], k)
        p = rng.uniform(-half, half, (k, 3))
        p[np.arange(k), axis] = sign * half[axis]
        n = np.zeros((k, 3))
        n[np.arange(k), axis] = -sign
        p = p + rng.normal(scale=0.01, size=3)  # object frame origin off-centre
    if mu is None:
        mu = 0.0 if rng.random() < 0.05 else float(rng.uniform(0.0, 1.5))
    return p, n, mu


def torque_scale(p):
    return float(np.max(np.linalg.norm(p, axis=1)))


def bound_factor(k, mu):
    """Q <= sqrt(6 k (1 + mu^2)) eps (module docstring)."""
    return math.sqrt(6 * k * (1 + mu * mu))


def sphere(dirs, r=0.04):
    d = np.asarray(dirs, dtype=float)
    d = d / np.linalg.norm(d, axis=1)[:, None]
    return r * d, -d


TETRA = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=float)


def rotation(rng):
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


# ---------------------------------------------------------------------------
# Against the references
# ---------------------------------------------------------------------------


def test_agrees_with_hull_reference_on_1000_random_grasps() -> None:
    rng = np.random.default_rng(0)
    n_fc = n_not = n_skip = 0
    for _ in range(1000):
        p, n, mu = random_grasp(rng)
        ts = torque_scale(p)
        signed = ref_signed_epsilon(p, n, mu, EDGES, ts)
        eps = max(signed, 0.0)
        q = force_closure_quality(p, n, mu, edges=EDGES, torque_scale=ts)
        assert q >= 0.0
        assert (q > 0) == is_force_closure(p, n, mu, edges=EDGES, torque_scale=ts)
        if signed < -1e-9:  # origin outside the hull (or rank < 6): not FC
            assert q == 0.0, (p, n, mu, q)
            n_not += 1
        elif eps > 1e-3:
            assert q > 0.0, (p, n, mu, eps)
            # eps <= Q <= sqrt(6 k (1 + mu^2)) eps (solver tolerance aside)
            assert eps <= q * (1 + 1e-6)
            assert q <= bound_factor(len(p), mu) * eps * (1 + 1e-6)
            n_fc += 1
        else:
            n_skip += 1
    assert n_fc >= 250 and n_not >= 250, (n_fc, n_not, n_skip)
    assert n_skip <= 50


def test_bounds_against_the_12_direction_lp() -> None:
    """q <= Q <= sqrt(k (1 + mu^2)) q and q / sqrt(6) <= eps <= q."""
    rng = np.random.default_rng(1)
    checked = 0
    while checked < 60:
        p, n, mu = random_grasp(rng, k=int(rng.integers(3, 6)), mu=float(rng.uniform(0.2, 1.5)))
        ts = torque_scale(p)
        q_ours = force_closure_quality(p, n, mu, edges=EDGES, torque_scale=ts)
        if q_ours == 0.0:
            continue
        q_lp = ref_lp_quality(p, n, mu, EDGES, ts)
        eps = ref_signed_epsilon(p, n, mu, EDGES, ts)
        assert q_lp * (1 - 1e-6) <= q_ours <= math.sqrt(len(p) * (1 + mu * mu)) * q_lp * (1 + 1e-6)
        assert q_lp / math.sqrt(6) * (1 - 1e-6) <= eps <= q_lp * (1 + 1e-6)
        checked += 1


def test_frictionless_many_contacts_agree_with_hull() -> None:
    rng = np.random.default_rng(2)
    n_fc = 0
    for _ in range(150):
        p, n, _ = random_grasp(rng, k=int(rng.integers(7, 15)), mu=0.0, kind="box")
        ts = torque_scale(p)
        signed = ref_signed_epsilon(p, n, 0.0, EDGES, ts)
        q = force_closure_quality(p, n, 0.0, edges=EDGES, torque_scale=ts)
        if signed < -1e-9:
            assert q == 0.0
        elif signed > 1e-3:
            assert signed <= q * (1 + 1e-6) <= bound_factor(len(p), 0.0) * signed * (1 + 2e-6)
            n_fc += 1
    assert n_fc >= 5  # boxes give frictionless FC grasps with >= 7 contacts


# ---------------------------------------------------------------------------
# Classic cases
# ---------------------------------------------------------------------------


def test_two_contacts_are_never_force_closure() -> None:
    p, n = sphere([[1, 0, 0], [-1, 0, 0]])
    for mu in (0.0, 0.5, 1.5, 100.0):
        assert force_closure_quality(p, n, mu) == 0.0
        assert not is_force_closure(p, n, mu)
    rng = np.random.default_rng(3)
    for _ in range(50):
        p, n, mu = random_grasp(rng, k=2)
        assert force_closure_quality(p, n, mu) == 0.0


@pytest.mark.parametrize("mu", [0.5, 0.8, 1.0])
def test_spread_contacts_on_a_sphere_are_force_closure(mu: float) -> None:
    tri = [[1, 0, -0.2], [-0.5, 0.866, -0.2], [-0.5, -0.866, -0.2]]
    for dirs in (tri, TETRA):
        p, n = sphere(dirs)
        assert force_closure_quality(p, n, mu) > 0.05
        assert is_force_closure(p, n, mu)
    p, n = sphere(TETRA)
    assert min_subgrasp_quality(p, n, mu) > 0.0
    assert is_force_closure(p, n, mu, subgrasps=True)


def test_frictionless_few_contacts_are_not_force_closure() -> None:
    rng = np.random.default_rng(4)
    for k in range(1, 7):
        for _ in range(10):
            p, n, _ = random_grasp(rng, k=k, mu=0.0)
            assert force_closure_quality(p, n, 0.0) == 0.0
    # on a sphere every normal passes through the centre: never FC without friction
    p, n = sphere(rng.normal(size=(12, 3)))
    assert force_closure_quality(p, n, 0.0, torque_scale=0.04) == 0.0


def test_antipodal_pair_plus_a_third_contact() -> None:
    p, n = sphere([[1, 0, 0], [-1, 0, 0]])
    assert force_closure_quality(p, n, 1.0) == 0.0
    p3, n3 = sphere([[1, 0, 0], [-1, 0, 0], [0, 1, 0]])
    assert force_closure_quality(p3, n3, 1.0) > 0.0
    # the third contact on the pair's axis adds nothing about that axis
    p3[2], n3[2] = p3[0] * 0.5, n3[0]
    assert force_closure_quality(p3, n3, 1.0) == 0.0
    # coplanar-with-axis degenerate: all three on a line (rank < 6)
    pl = np.array([[0.04, 0, 0], [-0.04, 0, 0], [0.0, 0, 0]])
    nl = np.array([[-1.0, 0, 0], [1.0, 0, 0], [0, 0, 1.0]])
    assert force_closure_quality(pl, nl, 1.0) == 0.0


def test_quality_grows_with_friction() -> None:
    p, n = sphere(TETRA)
    qs = [force_closure_quality(p, n, mu) for mu in (0.1, 0.3, 0.6, 1.0, 1.5)]
    assert all(a <= b * (1 + 1e-9) for a, b in itertools.pairwise(qs))


# ---------------------------------------------------------------------------
# Subgrasps and monotonicity
# ---------------------------------------------------------------------------


def test_min_subgrasp_is_min_over_explicit_subgrasps() -> None:
    rng = np.random.default_rng(5)
    n_pos = 0
    for _ in range(100):
        k = int(rng.integers(4, 7))
        p, n, mu = random_grasp(rng, k=k, mu=float(rng.uniform(0.3, 1.5)))
        ts = torque_scale(p)
        subs = [
            force_closure_quality(np.delete(p, i, 0), np.delete(n, i, 0), mu, torque_scale=ts)
            for i in range(k)
        ]
        m = min_subgrasp_quality(p, n, mu, torque_scale=ts)
        full = force_closure_quality(p, n, mu, torque_scale=ts)
        assert m == pytest.approx(min(subs), rel=1e-6, abs=1e-12)
        assert m <= full * (1 + 1e-9)
        n_pos += m > 0
        # the default torque scale is the full grasp's for every subgrasp
        assert min_subgrasp_quality(p, n, mu) == pytest.approx(m, rel=1e-6, abs=1e-12)
    assert n_pos >= 15


def test_adding_a_contact_never_lowers_the_quality() -> None:
    rng = np.random.default_rng(6)
    for _ in range(200):
        p, n, mu = random_grasp(rng, k=int(rng.integers(3, 6)))
        ts = torque_scale(p)
        q_all = force_closure_quality(p, n, mu, torque_scale=ts)
        q_less = force_closure_quality(p[:-1], n[:-1], mu, torque_scale=ts)
        assert q_less <= q_all * (1 + 1e-6) + 1e-12


def test_min_subgrasp_small_grasps() -> None:
    p, n = sphere(TETRA[:3])
    assert min_subgrasp_quality(p, n, 1.0) == 0.0  # 2-contact subgrasps
    assert min_subgrasp_quality(p[:1], n[:1], 1.0) == 0.0


# ---------------------------------------------------------------------------
# Margin fast path, solvers
# ---------------------------------------------------------------------------


def test_margin_decides_like_the_exact_value() -> None:
    rng = np.random.default_rng(7)
    fc = ForceClosure()
    for _ in range(300):
        p, n, mu = random_grasp(rng, k=int(rng.integers(4, 6)), mu=float(rng.uniform(0.2, 1.5)))
        ts = torque_scale(p)
        exact = NNLS.min_subgrasp_quality(p, n, mu, torque_scale=ts)
        for margin in (0.0, 0.5 * exact, exact * 0.999, exact * 1.001, 2 * exact + 1e-3, 0.01):
            r = fc.min_subgrasp_quality(p, n, mu, torque_scale=ts, margin=margin)
            if abs(exact - margin) > 1e-6 * max(exact, 1e-12):
                assert (r > margin) == (exact > margin), (exact, margin, r)
            if r > margin:
                assert r <= exact * (1 + 1e-6)
            else:
                assert r >= exact * (1 - 1e-6)
            cheap = fc.min_subgrasp_quality(p, n, mu, torque_scale=ts, margin=margin, solve=False)
            if cheap > margin:  # solve=False: a "yes" is certified, a "no" may be false
                assert margin < cheap <= exact * (1 + 1e-6)
        assert (exact > 0.0) == is_force_closure(p, n, mu, torque_scale=ts, subgrasps=True)


def test_osqp_and_nnls_pair_solvers_agree() -> None:
    rng = np.random.default_rng(8)
    osqp_fc = ForceClosure(solver="osqp", max_iter=4000)
    for _ in range(100):
        p, n, mu = random_grasp(rng, k=4, mu=float(rng.uniform(0.3, 1.2)))
        a = osqp_fc.min_subgrasp_quality(p, n, mu)
        b = NNLS.min_subgrasp_quality(p, n, mu)
        assert a == pytest.approx(b, rel=1e-6, abs=1e-12)
    assert osqp_fc.stats["pairs_solved"] > 0


# ---------------------------------------------------------------------------
# Invariance
# ---------------------------------------------------------------------------


def cube_rotations():
    """The 24 proper rotations that map the coordinate axes to signed axes."""
    out = []
    for perm in ([0, 1, 2], [1, 2, 0], [2, 0, 1], [0, 2, 1], [2, 1, 0], [1, 0, 2]):
        for signs in np.ndindex(2, 2, 2):
            m = np.zeros((3, 3))
            m[np.arange(3), perm] = np.where(np.array(signs) == 1, -1.0, 1.0)
            if np.linalg.det(m) > 0:
                out.append(m)
    return out


def test_rotating_the_grasp_keeps_the_quality() -> None:
    """Rotations of the grasp inside the object frame.

    A rotation maps the wrench space orthogonally, so the hull epsilon is invariant,
    but the 12 axes of the metric stay put: Q is invariant exactly (up to the turn of
    each pyramid about its normal) for the 24 rotations that permute the signed axes,
    and within the proven factor for any rotation. The pyramid turn is bounded by
    the inscribed / circumscribed cones and vanishes with many edges.
    """
    rng = np.random.default_rng(9)
    rots = cube_rotations()
    assert len(rots) == 24
    worst = {8: 0.0, 64: 0.0}
    for _ in range(40):
        p, n = sphere(TETRA + 0.3 * rng.normal(size=(4, 3)))
        mu = float(rng.uniform(0.4, 1.2))
        ts = 0.04
        rot = rots[int(rng.integers(24))]
        for edges in worst:
            q = force_closure_quality(p, n, mu, edges=edges, torque_scale=ts)
            qr = force_closure_quality(p @ rot.T, n @ rot.T, mu, edges=edges, torque_scale=ts)
            if q > 1e-3:
                worst[edges] = max(worst[edges], abs(qr - q) / q)
    assert worst[8] < 0.1, worst
    assert worst[64] < 0.01, worst
    for _ in range(60):  # any rotation: same verdict, value within the proven bounds
        p, n, mu = random_grasp(rng, k=4, mu=float(rng.uniform(0.3, 1.5)))
        ts = torque_scale(p)
        rot = rotation(rng)
        pr, nr = p @ rot.T, n @ rot.T
        eps = ref_signed_epsilon(p, n, mu, EDGES, ts)
        eps_r = ref_signed_epsilon(pr, nr, mu, EDGES, ts)
        q = force_closure_quality(p, n, mu, torque_scale=ts)
        qr = force_closure_quality(pr, nr, mu, torque_scale=ts)
        if min(eps, eps_r) > 1e-3:
            assert q > 0 and qr > 0
            assert qr <= bound_factor(4, mu) * q * (1 + 1e-6)
            assert q <= bound_factor(4, mu) * qr * (1 + 1e-6)
        elif max(eps, eps_r) < -1e-9:
            assert q == qr == 0.0


def test_same_object_frame_grasp_same_quality() -> None:
    """The pyramid is a function of the object-frame normal alone (no world axes)."""
    p, n = sphere(TETRA)
    a = force_closure_quality(p, n, 0.7)
    b = force_closure_quality(p.copy(), n.copy() * 3.0, 0.7)  # normals are normalized
    assert a == b


# ---------------------------------------------------------------------------
# Cones and wrenches
# ---------------------------------------------------------------------------


def test_cone_edges_and_facets() -> None:
    rng = np.random.default_rng(10)
    n = rng.normal(size=(20, 3))
    n[0] = [0, 0, -1]
    n[1] = [0, 0, 1]
    unit = n / np.linalg.norm(n, axis=1)[:, None]
    for mu in (0.0, 0.3, 1.5):
        e = friction_cone_edges(n, mu, 8)
        assert e.shape == (20, 8, 3)
        np.testing.assert_allclose(np.linalg.norm(e, axis=2), 1.0, atol=1e-12)
        np.testing.assert_allclose(e, ref_edges(n, mu, 8), atol=1e-12)
        cos = np.einsum("ket,kt->ke", e, unit)
        np.testing.assert_allclose(cos, 1.0 / math.sqrt(1 + mu * mu), atol=1e-12)
        f = friction_cone_facets(n, mu, 8)
        # each facet contains its two edges, and the normal is strictly inside
        np.testing.assert_allclose(np.einsum("ket,ket->ke", f, e), 0.0, atol=1e-12)
        np.testing.assert_allclose(
            np.einsum("ket,ket->ke", f, np.roll(e, -1, axis=1)), 0.0, atol=1e-12
        )
        if mu > 0:
            assert np.all(np.einsum("ket,kt->ke", f, unit) < 0)


def test_contact_wrenches() -> None:
    p, n = sphere(TETRA)
    w = contact_wrenches(p, n, 0.5)
    assert w.shape == (32, 6)
    np.testing.assert_allclose(w, ref_wrenches(p, n, 0.5, 8, 0.04), atol=1e-12)
    w2 = contact_wrenches(p, n, 0.5, edges=4, torque_scale=0.1)
    np.testing.assert_allclose(w2, ref_wrenches(p, n, 0.5, 4, 0.1), atol=1e-12)
    # all contacts at the origin: torque scale 1
    w0 = contact_wrenches(np.zeros((3, 3)), n[:3], 0.5)
    np.testing.assert_allclose(w0[:, 3:], 0.0)


# ---------------------------------------------------------------------------
# Bad inputs
# ---------------------------------------------------------------------------

P4, N4 = sphere(TETRA)


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"points": np.zeros((4, 2))}, "points"),
        ({"points": np.zeros(5)}, "points"),
        ({"normals": np.zeros((3, 3)) + 1}, "normals"),
        ({"points": np.full((4, 3), np.nan)}, "points"),
        ({"normals": np.array([[np.inf, 0, 0]] * 4)}, "normals"),
        ({"normals": np.vstack([N4[:3], [0, 0, 0]])}, "normals"),
        ({"mu": -0.1}, "mu"),
        ({"mu": float("nan")}, "mu"),
        ({"mu": "a lot"}, "mu"),
        ({"edges": 2}, "edges"),
        ({"edges": 4.5}, "edges"),
        ({"edges": True}, "edges"),
        ({"torque_scale": 0.0}, "torque_scale"),
        ({"torque_scale": -1.0}, "torque_scale"),
        ({"margin": -1.0}, "margin"),
        ({"points": np.zeros((0, 3)), "normals": np.zeros((0, 3))}, "points"),
    ],
)
def test_bad_inputs(kwargs, needle: str) -> None:
    args = {"points": P4, "normals": N4, "mu": 0.5, "edges": 8, "torque_scale": None}
    args.update(kwargs)
    margin = args.pop("margin", None)
    for fn in (force_closure_quality, min_subgrasp_quality):
        with pytest.raises(InvalidInputError, match=needle):
            fn(
                args["points"],
                args["normals"],
                args["mu"],
                edges=args["edges"],
                torque_scale=args["torque_scale"],
                margin=margin,
            )


def test_bad_inputs_of_cone_helpers() -> None:
    with pytest.raises(InvalidInputError, match="normals_in"):
        friction_cone_edges(np.zeros((2, 3)), 0.5)
    with pytest.raises(InvalidInputError, match="mu"):
        friction_cone_edges(N4, -1.0)
    with pytest.raises(InvalidInputError, match="edges"):
        friction_cone_facets(N4, 0.5, edges=1)
    with pytest.raises(InvalidInputError, match="torque_scale"):
        contact_wrenches(P4, N4, 0.5, torque_scale=float("inf"))
    with pytest.raises(InvalidInputError, match="solver"):
        ForceClosure(solver="simplex")  # type: ignore[arg-type]
