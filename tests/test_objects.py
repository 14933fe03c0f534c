"""Tests of dexplan.model.objects: SDF, gradients, closest points, sampling, meshes, I/O."""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import coal
import numpy as np
import pytest
import trimesh
from scipy import stats

from dexplan.core.errors import DexplanError, InvalidInputError, MeshError
from dexplan.model.objects import (
    BUILTIN_MESH_DIR,
    Box,
    Capsule,
    Cylinder,
    Mesh,
    Shape,
    Sphere,
    file_sha256,
    shape_from_dict,
)

# --------------------------------------------------------------------------- helpers

PRIMITIVES: list[Shape] = [
    Sphere(0.04),
    Box([0.04, 0.06, 0.08]),
    Capsule(0.02, 0.05),
    Cylinder(0.02, 0.05),
]


def _tm_mesh(tm: trimesh.Trimesh) -> Mesh:
    return Mesh(np.asarray(tm.vertices), np.asarray(tm.faces))


@pytest.fixture(scope="module")
def ico() -> Mesh:
    return _tm_mesh(trimesh.creation.icosphere(subdivisions=3, radius=0.05))


@pytest.fixture(scope="module")
def torus() -> Mesh:
    return Mesh.from_file(BUILTIN_MESH_DIR / "torus.obj")


@pytest.fixture(scope="module")
def cup() -> Mesh:
    return Mesh.from_file(BUILTIN_MESH_DIR / "cup.obj")


@pytest.fixture(scope="module")
def box_mesh() -> Mesh:
    return _tm_mesh(trimesh.creation.box(extents=[0.04, 0.06, 0.08]))


@pytest.fixture(scope="module")
def all_shapes(ico: Mesh, torus: Mesh, cup: Mesh, box_mesh: Mesh) -> list[Shape]:
    return [*PRIMITIVES, ico, torus, cup, box_mesh]


def query_points(shape: Shape, rng: np.random.Generator, n: int = 400) -> np.ndarray:
    """Points inside, outside, near the surface and far away."""
    r = shape.bounding_radius
    s, nrm = shape.sample_surface(n, rng)
    near = s + rng.uniform(-0.05, 0.05, (n, 1)) * r * nrm
    blob = rng.normal(size=(n, 3)) * 0.7 * r
    far = rng.normal(size=(n // 4, 3)) * 5 * r
    return np.concatenate([near, blob, far])


def box_reference(size: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance and gradient of a box from the closest-point definition."""
    h = np.asarray(size) / 2
    c = np.clip(p, -h, h)
    out = np.linalg.norm(p - c, axis=1)
    inside = out == 0
    gap = h - np.abs(p)  # distance to each face pair from inside
    k = np.argmin(gap, axis=1)
    d = np.where(inside, -gap[np.arange(len(p)), k], out)
    g = np.zeros_like(p)
    safe = np.where(inside, 1.0, out)[:, None]
    g[~inside] = ((p - c) / safe)[~inside]
    rows = np.flatnonzero(inside)
    g[rows, k[rows]] = np.where(p[rows, k[rows]] >= 0, 1.0, -1.0)
    return d, g


def winding_number(v: np.ndarray, f: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Generalized winding number (van Oosterom-Strackee solid angles): 1 inside, 0 outside."""
    a = v[f[:, 0]][None] - p[:, None]
    b = v[f[:, 1]][None] - p[:, None]
    c = v[f[:, 2]][None] - p[:, None]
    la, lb, lc = (np.linalg.norm(x, axis=2) for x in (a, b, c))
    det = np.einsum("nfi,nfi->nf", a, np.cross(b, c))
    dot = lambda x, y: np.einsum("nfi,nfi->nf", x, y)  # noqa: E731
    den = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb
    return (2 * np.arctan2(det, den)).sum(axis=1) / (4 * math.pi)


def brute_force_distance(mesh: Mesh, p: np.ndarray) -> np.ndarray:
    """Unsigned distance by testing every triangle (trimesh at unit scale)."""
    s = 1.0 / mesh.bounding_radius  # trimesh's closest_point uses absolute tolerances
    tris = mesh.vertices[mesh.faces] * s
    out = np.empty(len(p))
    for i, q in enumerate(p * s):
        cp = trimesh.triangles.closest_point(tris, np.repeat(q[None], len(tris), 0))
        out[i] = np.linalg.norm(cp - q, axis=1).min()
    return out / s


def fd_gradient(shape: Shape, p: np.ndarray, h: float) -> np.ndarray:
    g = np.empty_like(p)
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        g[:, k] = (shape.signed_distance(p + e) - shape.signed_distance(p - e)) / (2 * h)
    return g


# ------------------------------------------------------------------ primitives: values


def test_sphere_analytic() -> None:
    s = Sphere(0.04)
    p = np.random.default_rng(0).normal(size=(500, 3)) * 0.05
    d, g = s.signed_distance_and_gradient(p)
    n = np.linalg.norm(p, axis=1)
    np.testing.assert_allclose(d, n - 0.04, atol=1e-15)
    np.testing.assert_allclose(g, p / n[:, None], atol=1e-15)


def test_box_analytic_including_edges_and_corners() -> None:
    size = np.array([0.04, 0.06, 0.08])
    b = Box(size)
    rng = np.random.default_rng(1)
    h = size / 2
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h
    edge_mid = np.array([[0, 1, 1], [1, 0, 1], [1, 1, 0], [0, -1, 1], [-1, 0, -1]]) * h
    base = np.concatenate([np.repeat(corners, 60, 0), np.repeat(edge_mid, 60, 0)])
    near = base + rng.normal(size=base.shape) * 1e-3
    p = np.concatenate([near, rng.normal(size=(600, 3)) * 0.04, rng.uniform(-h, h, (300, 3))])
    d, g = b.signed_distance_and_gradient(p)
    d_ref, g_ref = box_reference(size, p)
    np.testing.assert_allclose(d, d_ref, atol=1e-15)
    np.testing.assert_allclose(g, g_ref, atol=1e-12)
    assert np.sum(d < 0) > 300 and np.sum(d > 0) > 300


def test_capsule_and_cylinder_analytic() -> None:
    rng = np.random.default_rng(2)
    p = rng.normal(size=(1000, 3)) * 0.04
    r, length = 0.02, 0.05
    a = length / 2
    cap = Capsule(r, length)
    axis = np.zeros_like(p)
    axis[:, 2] = np.clip(p[:, 2], -a, a)
    np.testing.assert_allclose(
        cap.signed_distance(p), np.linalg.norm(p - axis, axis=1) - r, atol=1e-15
    )
    cyl = Cylinder(r, length)
    rho, z = np.hypot(p[:, 0], p[:, 1]), np.abs(p[:, 2])
    outside = np.hypot(np.maximum(rho - r, 0), np.maximum(z - a, 0))
    inside = -np.minimum(r - rho, a - z)
    ref = np.where((rho > r) | (z > a), outside, inside)
    np.testing.assert_allclose(cyl.signed_distance(p), ref, atol=1e-15)


@pytest.mark.parametrize("shape", PRIMITIVES, ids=lambda s: s.kind)
def test_primitives_match_coal_distance_outside(shape: Shape) -> None:
    """coal's own distance to to_coal() agrees: same size conventions (e.g. capsule length)."""
    rng = np.random.default_rng(3)
    p = rng.normal(size=(300, 3)) * 0.06
    d = shape.signed_distance(p)
    geom, point = shape.to_coal(), coal.Sphere(0.0)
    ident, tf = coal.Transform3s(), coal.Transform3s()
    req, res = coal.DistanceRequest(), coal.DistanceResult()
    for q, dq in zip(p[d > 1e-6], d[d > 1e-6], strict=True):
        tf.setTranslation(q)
        res.clear()
        assert coal.distance(geom, ident, point, tf, req, res) == pytest.approx(dq, abs=1e-12)


def test_to_coal_types_and_dimensions(ico: Mesh) -> None:
    s = Sphere(0.04).to_coal()
    assert isinstance(s, coal.Sphere) and s.radius == 0.04
    b = Box([0.04, 0.06, 0.08]).to_coal()
    assert isinstance(b, coal.Box)
    np.testing.assert_allclose(b.halfSide, [0.02, 0.03, 0.04])
    c = Capsule(0.02, 0.05).to_coal()
    assert isinstance(c, coal.Capsule) and c.radius == 0.02 and c.halfLength == 0.025
    y = Cylinder(0.02, 0.05).to_coal()
    assert isinstance(y, coal.Cylinder) and y.radius == 0.02 and y.halfLength == 0.025
    m = ico.to_coal()
    assert isinstance(m, coal.BVHModelOBBRSS) and m.num_tris == len(ico.faces)
    assert ico.to_coal() is m  # cached


def test_sizes_and_characteristic_lengths() -> None:
    assert Sphere(0.04).characteristic_length == 0.04
    assert Box([0.04, 0.06, 0.08]).bounding_radius == pytest.approx(
        0.5 * math.sqrt(0.04**2 + 0.06**2 + 0.08**2)
    )
    assert Capsule(0.02, 0.05).bounding_radius == pytest.approx(0.045)
    assert Cylinder(0.02, 0.05).bounding_radius == pytest.approx(math.hypot(0.02, 0.025))
    for s in PRIMITIVES:
        assert s.characteristic_length == s.bounding_radius
        pts, _ = s.sample_surface(2000, np.random.default_rng(0))
        assert np.linalg.norm(pts, axis=1).max() <= s.bounding_radius + 1e-15
    tm = trimesh.creation.capsule(height=0.05, radius=0.02, count=[64, 64])
    assert Capsule(0.02, 0.05).volume == pytest.approx(tm.volume, rel=2e-3)
    assert Capsule(0.02, 0.05).surface_area == pytest.approx(tm.area, rel=2e-3)


# --------------------------------------------------------- all shapes: shared properties


def test_gradient_matches_finite_differences(all_shapes: list[Shape]) -> None:
    rng = np.random.default_rng(4)
    for shape in all_shapes:
        p = query_points(shape, rng, 200)
        _, g = shape.signed_distance_and_gradient(p)
        h = 1e-6 * shape.bounding_radius
        fd1, fd2 = fd_gradient(shape, p, h), fd_gradient(shape, p, h / 8)
        smooth = np.linalg.norm(fd1 - fd2, axis=1) < 1e-6  # away from kinks (medial axis)
        assert smooth.mean() > 0.8, shape
        err = np.linalg.norm(g[smooth] - fd1[smooth], axis=1)
        assert err.max() < 1e-5, (shape, err.max())
        np.testing.assert_allclose(np.linalg.norm(g, axis=1), 1.0, atol=1e-12)


def test_closest_point_on_surface_and_normal(all_shapes: list[Shape]) -> None:
    rng = np.random.default_rng(5)
    for shape in all_shapes:
        p = query_points(shape, rng, 200)
        c, n = shape.closest_point(p)
        d, g = shape.signed_distance_and_gradient(p)
        assert np.abs(shape.signed_distance(c)).max() < 1e-12, shape
        np.testing.assert_allclose(np.linalg.norm(p - c, axis=1), np.abs(d), atol=1e-12)
        np.testing.assert_allclose(n, g, atol=1e-12)
        np.testing.assert_allclose(p - c, d[:, None] * n, atol=1e-12)
        # moving along the normal from the closest point gives the distance back
        step = 1e-4 * shape.bounding_radius
        assert np.all(shape.signed_distance(c + step * n) > 0), shape


def test_single_point_small_and_large_batches_agree(all_shapes: list[Shape]) -> None:
    rng = np.random.default_rng(6)
    for shape in all_shapes:
        p = query_points(shape, rng, 40)
        d, g = shape.signed_distance_and_gradient(p)  # vectorized (N > 16)
        assert len(p) > 16
        small_d, small_g = shape.signed_distance_and_gradient(p[:5])  # scalar loop
        np.testing.assert_allclose(small_d, d[:5], atol=1e-14)
        np.testing.assert_allclose(small_g, g[:5], atol=1e-12)
        c, n = shape.closest_point(p)
        for i in range(0, len(p), 7):
            di, gi = shape.signed_distance_and_gradient(p[i])
            assert isinstance(di, float) and gi.shape == (3,)
            assert di == pytest.approx(d[i], abs=1e-14)
            np.testing.assert_allclose(gi, g[i], atol=1e-12)
            assert shape.signed_distance(p[i]) == pytest.approx(d[i], abs=1e-14)
            assert shape.signed_distance(list(p[i])) == pytest.approx(d[i], abs=1e-14)
            ci, ni = shape.closest_point(p[i])
            np.testing.assert_allclose(ci, c[i], atol=1e-14)
            np.testing.assert_allclose(ni, n[i], atol=1e-12)
        np.testing.assert_allclose(shape.signed_distance(p), d, atol=1e-14)


def test_surface_samples_on_surface(all_shapes: list[Shape]) -> None:
    rng = np.random.default_rng(7)
    for shape in all_shapes:
        pts, nrm = shape.sample_surface(2000, rng)
        assert pts.shape == (2000, 3) and nrm.shape == (2000, 3)
        d, g = shape.signed_distance_and_gradient(pts)
        assert np.abs(d).max() < 1e-9, shape
        np.testing.assert_allclose(np.linalg.norm(nrm, axis=1), 1.0, atol=1e-12)
        # normals agree with the gradient except on measure-zero edges
        assert np.mean(np.einsum("ij,ij->i", nrm, g) > 1 - 1e-9) > 0.999, shape
        empty_p, empty_n = shape.sample_surface(0, rng)
        assert empty_p.shape == (0, 3) and empty_n.shape == (0, 3)


def test_sampling_is_deterministic_given_rng() -> None:
    for shape in PRIMITIVES:
        a = shape.sample_surface(50, np.random.default_rng(9))
        b = shape.sample_surface(50, np.random.default_rng(9))
        np.testing.assert_array_equal(a[0], b[0])


# ------------------------------------------------------------- area-uniform sampling


def _chi2_ok(counts: np.ndarray, probs: np.ndarray) -> bool:
    expected = probs / probs.sum() * counts.sum()
    chi2 = float(((counts - expected) ** 2 / expected).sum())
    return stats.chi2.sf(chi2, len(counts) - 1) > 1e-4


def test_box_sampling_area_uniform() -> None:
    size = np.array([0.02, 0.05, 0.11])
    pts, nrm = Box(size).sample_surface(60000, np.random.default_rng(10))
    face = np.argmax(np.abs(nrm), axis=1) * 2 + (np.sum(nrm, axis=1) < 0)
    counts = np.bincount(face, minlength=6)
    sx, sy, sz = size
    area = np.repeat([sy * sz, sx * sz, sx * sy], 2)
    assert _chi2_ok(counts, area)
    # uniform within the +z face
    top = pts[face == 4]
    assert stats.kstest(top[:, 0], stats.uniform(-sx / 2, sx).cdf).pvalue > 1e-4
    assert stats.kstest(top[:, 1], stats.uniform(-sy / 2, sy).cdf).pvalue > 1e-4


def test_contact_samples_touch_where_the_fingertip_centre_says() -> None:
    # the fingertip centre p + r n lies r from the surface and its closest point is p
    # (convex shapes: in a concavity tighter than the fingertip it does not fit)
    rng = np.random.default_rng(12)
    r = 0.012
    for shape in PRIMITIVES:
        pts, nrm = shape.sample_contacts(3000, rng, 500)
        assert len(pts) == (3500 if isinstance(shape, Box) else 3000), shape
        np.testing.assert_allclose(np.linalg.norm(nrm, axis=1), 1.0, atol=1e-12)
        tips = pts + r * nrm
        assert np.abs(shape.signed_distance(tips) - r).max() < 1e-9, shape
        c, n = shape.closest_point(tips)
        assert np.abs(c - pts).max() < 1e-9, shape
        np.testing.assert_allclose(n, nrm, atol=1e-9)


def test_box_contacts_mix_faces_and_edges_in_random_order() -> None:
    size = np.array([0.03, 0.05, 0.07])
    pts, _ = Box(size).sample_contacts(3000, np.random.default_rng(13), 1000)
    on_limit = np.isclose(np.abs(pts), size / 2, rtol=0.0, atol=1e-12).sum(axis=1)
    assert (on_limit == 1).sum() == 3000 and (on_limit == 2).sum() == 1000
    # shuffled: edge points are spread over the whole list, not appended
    edge_at = np.flatnonzero(on_limit == 2)
    assert edge_at.min() < 100 and edge_at.max() > 3900
    # shapes without edges: exactly sample_surface's stream
    a = Sphere(0.03).sample_contacts(50, np.random.default_rng(1), 20)
    b = Sphere(0.03).sample_surface(50, np.random.default_rng(1))
    np.testing.assert_array_equal(a[0], b[0])


def test_sphere_capsule_cylinder_sampling_area_uniform() -> None:
    rng = np.random.default_rng(11)
    # Archimedes: z is uniform on a sphere
    pts, _ = Sphere(0.03).sample_surface(20000, rng)
    assert stats.kstest(pts[:, 2], stats.uniform(-0.03, 0.06).cdf).pvalue > 1e-4
    r, length = 0.02, 0.05
    for shape, cap_area in ((Capsule(r, length), 4 * math.pi * r * r), (Cylinder(r, length), 0)):
        pts, nrm = shape.sample_surface(40000, rng)
        side = np.abs(nrm[:, 2]) < 1e-12
        side_area = 2 * math.pi * r * length
        caps = cap_area if cap_area else 2 * math.pi * r * r
        assert _chi2_ok(np.array([side.sum(), (~side).sum()]), np.array([side_area, caps]))
        assert stats.kstest(pts[side, 2], stats.uniform(-length / 2, length).cdf).pvalue > 1e-4
        angle = np.arctan2(pts[:, 1], pts[:, 0])
        assert stats.kstest(angle, stats.uniform(-math.pi, 2 * math.pi).cdf).pvalue > 1e-4
        if isinstance(shape, Cylinder):  # caps: rho^2 uniform
            rho2 = np.hypot(pts[~side, 0], pts[~side, 1]) ** 2
            assert stats.kstest(rho2, stats.uniform(0, r * r).cdf).pvalue > 1e-4


def test_mesh_sampling_area_weighted(box_mesh: Mesh) -> None:
    tri, u, v = box_mesh.sample_surface_params(60000, np.random.default_rng(12))
    assert _chi2_ok(np.bincount(tri, minlength=len(box_mesh.faces)), box_mesh.face_areas)
    assert np.all((u >= 0) & (v >= 0) & (u + v <= 1))
    # uniform in a triangle: the marginal of u has density 2 (1 - u)
    assert stats.kstest(u, stats.beta(1, 2).cdf).pvalue > 1e-4
    assert stats.kstest(v, stats.beta(1, 2).cdf).pvalue > 1e-4


# ---------------------------------------------------------------------- mesh queries


def test_mesh_box_equals_box_primitive(box_mesh: Mesh) -> None:
    """A box mesh and the Box primitive are the same set: identical exact SDFs."""
    prim = Box([0.04, 0.06, 0.08])
    rng = np.random.default_rng(13)
    p = query_points(prim, rng, 500)
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    p = np.concatenate(
        [p, np.repeat(corners * [0.02, 0.03, 0.04], 20, 0) + 1e-3 * rng.normal(size=(160, 3))]
    )
    d, g = box_mesh.signed_distance_and_gradient(p)
    dp, gp = prim.signed_distance_and_gradient(p)
    np.testing.assert_allclose(d, dp, atol=1e-14)
    # gradients agree wherever the inside closest face is unambiguous
    q = np.sort(np.abs(p) - [0.02, 0.03, 0.04], axis=1)
    clear = (dp > 0) | (q[:, 2] - q[:, 1] > 1e-9)
    np.testing.assert_allclose(g[clear], gp[clear], atol=1e-12)


def test_mesh_sdf_matches_trimesh() -> None:
    """Against trimesh.proximity.signed_distance (positive inside) at unit scale.

    trimesh's point-triangle routine uses absolute tolerances and misses the
    closest point on millimetre-size triangles, so the comparison is done on
    metre-size meshes.
    """
    rng = np.random.default_rng(14)
    for tm in (
        trimesh.creation.icosphere(subdivisions=3, radius=1.0),
        trimesh.creation.box(extents=[1.0, 2.0, 1.5]),
    ):
        mesh = _tm_mesh(tm)
        p = query_points(mesh, rng, 60)
        ref = -trimesh.proximity.signed_distance(tm, p)
        np.testing.assert_allclose(mesh.signed_distance(p), ref, atol=1e-9)


def test_mesh_approximates_sphere_within_tessellation_error() -> None:
    radius = 0.05
    tm = trimesh.creation.icosphere(subdivisions=4, radius=radius)
    mesh = _tm_mesh(tm)
    # the polytope lies between the inscribed ball (radius = least face-plane
    # distance from the centre) and the sphere, so |sdf - sdf_sphere| <= sagitta
    inner = np.min(np.einsum("ij,ij->i", mesh.face_normals, mesh.vertices[mesh.faces[:, 0]]))
    sagitta = radius - inner
    assert 0 < sagitta < 1e-3 * radius * 2
    rng = np.random.default_rng(15)
    p = query_points(Sphere(radius), rng, 300)
    p = p[np.linalg.norm(p, axis=1) > 0.2 * radius]  # deep centre is slow to query
    d, g = mesh.signed_distance_and_gradient(p)
    ds = np.linalg.norm(p, axis=1) - radius
    assert np.all(d >= ds - 1e-15) and np.all(d <= ds + sagitta + 1e-15)
    gs = p / np.linalg.norm(p, axis=1, keepdims=True)
    assert np.einsum("ij,ij->i", g, gs).min() > math.cos(0.1)


def test_mesh_distance_and_sign_on_nonconvex_meshes(torus: Mesh, cup: Mesh) -> None:
    rng = np.random.default_rng(16)
    for mesh in (torus, cup):
        p = query_points(mesh, rng, 100)
        d = mesh.signed_distance(p)
        np.testing.assert_allclose(np.abs(d), brute_force_distance(mesh, p), atol=1e-12)
        w = winding_number(mesh.vertices, mesh.faces, p)
        clear = np.abs(d) > 1e-9
        np.testing.assert_array_equal((d < 0)[clear], (w > 0.5)[clear])
        assert np.sum(d < 0) > 30 and np.sum(d > 0) > 30


def test_mesh_on_surface_features(ico: Mesh) -> None:
    """Vertices, edge midpoints and face centroids: distance 0, unit gradient outward."""
    v, f = ico.vertices, ico.faces
    pts = np.concatenate([v[:40], (v[f[:40, 0]] + v[f[:40, 1]]) / 2, v[f[:40]].mean(axis=1)])
    d, g = ico.signed_distance_and_gradient(pts)
    assert np.abs(d).max() < 1e-15
    np.testing.assert_allclose(np.linalg.norm(g, axis=1), 1.0, atol=1e-12)
    assert np.einsum("ij,ij->i", g, pts / np.linalg.norm(pts, axis=1, keepdims=True)).min() > 0.9
    c, _ = ico.closest_point(pts)
    np.testing.assert_allclose(c, pts, atol=1e-15)


def test_mesh_contact_params_round_trip(torus: Mesh) -> None:
    rng = np.random.default_rng(17)
    tri, u, v = torus.sample_surface_params(500, rng)
    p = torus.contact_points(tri, u, v)
    assert p.shape == (500, 3)
    assert np.abs(torus.signed_distance(p)).max() < 1e-15
    tri2, u2, v2 = torus.contact_params(p)
    assert tri2.dtype.kind == "i" and np.mean(tri2 == tri) > 0.99  # ties only on edges
    np.testing.assert_allclose(torus.contact_points(tri2, u2, v2), p, atol=1e-15)
    assert np.all((u2 >= 0) & (v2 >= 0) & (u2 + v2 <= 1 + 1e-15))
    # p = (1 - u - v) A + u B + v C
    a, b, c = (torus.vertices[torus.faces[tri, k]] for k in range(3))
    np.testing.assert_allclose(p, (1 - u - v)[:, None] * a + u[:, None] * b + v[:, None] * c)
    np.testing.assert_array_equal(torus.contact_normals(tri), torus.face_normals[tri])
    # off-surface points map to their closest points
    off = p + 1e-3 * torus.face_normals[tri]
    t3, u3, v3 = torus.contact_params(off)
    np.testing.assert_allclose(torus.contact_points(t3, u3, v3), torus.closest_point(off)[0])
    # scalar forms
    ts, us, vs = torus.contact_params(p[0])
    assert isinstance(ts, int) and isinstance(us, float)
    assert torus.contact_points(ts, us, vs).shape == (3,)
    assert torus.contact_normals(ts).shape == (3,)
    np.testing.assert_allclose(torus.contact_points(ts, us, vs), p[0], atol=1e-15)
    with pytest.raises(InvalidInputError, match="tri"):
        torus.contact_points([len(torus.faces)], [0.1], [0.1])
    with pytest.raises(InvalidInputError, match="u, v"):
        torus.contact_points([0], [0.8], [0.8])
    with pytest.raises(InvalidInputError, match="same length"):
        torus.contact_points([0, 1], [0.1], [0.1])


def test_mesh_face_normals_outward(torus: Mesh, cup: Mesh) -> None:
    for mesh in (torus, cup):
        centroids = mesh.vertices[mesh.faces].mean(axis=1)
        step = 1e-4 * mesh.bounding_radius
        assert np.all(mesh.signed_distance(centroids + step * mesh.face_normals) > 0)
        assert np.all(mesh.signed_distance(centroids - step * mesh.face_normals) < 0)
        assert mesh.volume > 0


def test_inverted_mesh_is_flipped() -> None:
    tm = trimesh.creation.icosphere(subdivisions=2, radius=0.05)
    mesh = Mesh(tm.vertices, tm.faces[:, ::-1])
    assert mesh.volume == pytest.approx(tm.volume)
    assert mesh.signed_distance(np.zeros(3)) < 0


def test_mesh_bounding_radius_keeps_file_origin(tmp_path: Path) -> None:
    tm = trimesh.creation.box(extents=[0.02, 0.02, 0.02])
    tm.apply_translation([0.1, 0, 0])
    path = tmp_path / "shifted.stl"
    tm.export(path)
    mesh = Mesh.from_file(path, scale=2.0)
    assert mesh.bounding_radius == pytest.approx(2 * math.sqrt(0.11**2 + 2 * 0.01**2))
    assert mesh.signed_distance(np.array([0.2, 0.0, 0.0])) == pytest.approx(-0.02)
    assert mesh.signed_distance(np.zeros(3)) == pytest.approx(0.18)


@pytest.mark.parametrize("ext", ["obj", "stl", "ply"])
def test_mesh_file_formats(tmp_path: Path, ext: str) -> None:
    tm = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    path = tmp_path / f"ball.{ext}"
    tm.export(path)
    mesh = Mesh.from_file(path, scale=0.05)
    assert len(mesh.faces) == len(tm.faces)
    assert mesh.volume == pytest.approx(tm.volume * 0.05**3, rel=1e-6)
    assert mesh.sha256 == hashlib.sha256(path.read_bytes()).hexdigest()


def test_builtin_meshes_load() -> None:
    files = sorted(BUILTIN_MESH_DIR.glob("*.obj"))
    assert {f.stem for f in files} >= {"ellipsoid", "torus", "peanut", "cup"}
    for f in files:
        assert f.stat().st_size < 200_000
        mesh = Mesh.from_file(f)
        assert mesh.volume > 0 and 0.02 < mesh.bounding_radius < 0.1


# ---------------------------------------------------------- serialisation round trip


def test_dict_round_trip(tmp_path: Path) -> None:
    for shape in PRIMITIVES:
        d = shape.to_dict()
        json.dumps(d)
        assert shape_from_dict(d) == shape
        assert shape_from_dict(json.loads(json.dumps(d))) == shape
    assert Sphere(0.04).to_dict() == {"shape": "sphere", "radius": 0.04}
    assert Box([1, 2, 3]).to_dict() == {"shape": "box", "size": [1.0, 2.0, 3.0]}
    assert Capsule(0.1, 0.2).to_dict() == {"shape": "capsule", "radius": 0.1, "length": 0.2}

    (tmp_path / "meshes").mkdir()
    path = tmp_path / "meshes" / "torus.obj"
    path.write_bytes((BUILTIN_MESH_DIR / "torus.obj").read_bytes())
    mesh = Mesh.from_file(path, scale=0.5)
    d = mesh.to_dict(base_dir=tmp_path)
    assert d == {
        "shape": "mesh",
        "path": "meshes/torus.obj",
        "scale": 0.5,
        "sha256": file_sha256(path),
    }
    back = shape_from_dict(json.loads(json.dumps(d)), base_dir=tmp_path)
    assert isinstance(back, Mesh) and back == mesh and back.scale == 0.5
    absolute = mesh.to_dict()
    assert Path(absolute["path"]).is_absolute()
    assert shape_from_dict(absolute) == mesh
    # sha256 and scale are optional
    assert shape_from_dict({"shape": "mesh", "path": str(path)}).scale == 1.0
    assert shape_from_dict({"shape": "box", "size": [1, 1, 1]}, field="obstacles[0]") == Box(
        [1, 1, 1]
    )


@pytest.mark.parametrize(
    ("d", "needles"),
    [
        ({"shape": "sphere", "radiuss": 0.05}, ["object.radiuss", "0.05", "'radius'"]),
        ({"shape": "sphere", "raduis": 0.05}, ["object.raduis", "'radius'"]),
        (
            {"shape": "box", "size": [1, 1, 1], "radius": 1},
            ["object.radius", "allowed: shape, size"],
        ),
        (
            {"shape": "capsule", "radius": 1, "length": 1, "lenght": 2},
            ["object.lenght", "'length'"],
        ),
        ({"shape": "mesh", "path": "x.obj", "sha": "ab"}, ["object.sha", "sha256"]),
        # an obstacle's own keys are the caller's to strip
        ({"shape": "box", "size": [1, 1, 1], "pose_xyzquat": [0] * 7}, ["object.pose_xyzquat"]),
        # a typo of "shape" itself is reported as the typo
        ({"shap": "sphere", "radius": 1}, ["object.shap", "'shape'"]),
        ({"shape": "sphere", "radius": 1, "a\nb": 1}, ["'a\\nb'"]),
    ],
)
def test_unknown_shape_fields_rejected(d: dict, needles: list[str]) -> None:
    with pytest.raises(InvalidInputError, match="unknown field") as info:
        shape_from_dict(d)
    msg = str(info.value)
    assert "\n" not in msg
    for needle in needles:
        assert needle in msg, (needle, msg)


def test_mesh_sha256_field_accepted(tmp_path: Path) -> None:
    path = tmp_path / "torus.obj"
    path.write_bytes((BUILTIN_MESH_DIR / "torus.obj").read_bytes())
    d = {"shape": "mesh", "path": "torus.obj", "scale": 2.0, "sha256": file_sha256(path)}
    assert shape_from_dict(d, base_dir=tmp_path).scale == 2.0


def test_sha256_mismatch(tmp_path: Path) -> None:
    path = tmp_path / "cup.obj"
    path.write_bytes((BUILTIN_MESH_DIR / "cup.obj").read_bytes())
    d = Mesh.from_file(path).to_dict(base_dir=tmp_path)
    path.write_bytes(path.read_bytes() + b"\n# edited\n")
    with pytest.raises(MeshError, match=r"object\.sha256 mismatch"):
        shape_from_dict(d, base_dir=tmp_path)


def test_mesh_from_arrays_has_no_dict(ico: Mesh) -> None:
    assert ico.path is None and ico.sha256 is None
    with pytest.raises(InvalidInputError, match="no file"):
        ico.to_dict()


# -------------------------------------------------------------------------- errors


@pytest.mark.parametrize(
    ("d", "match"),
    [
        ({"shape": "sphere", "radius": -1.0}, r"object\.radius must be finite and > 0, got -1\.0"),
        ({"shape": "sphere", "radius": float("nan")}, r"object\.radius must be finite"),
        ({"shape": "sphere", "radius": "big"}, r"object\.radius must be a number, got 'big'"),
        ({"shape": "sphere", "radius": True}, r"object\.radius must be a number"),
        ({"shape": "sphere"}, r"object\.radius is missing"),
        ({"shape": "cone", "radius": 1.0}, r"object\.shape must be one of .*got 'cone'"),
        ({"radius": 1.0}, r"object\.shape is missing"),
        ({"shape": "box", "size": [1, 2]}, r"object\.size must be 3 finite numbers > 0"),
        ({"shape": "box", "size": [1, 0, 2]}, r"object\.size must be 3 finite numbers > 0"),
        ({"shape": "capsule", "radius": 0.1}, r"object\.length is missing"),
        ({"shape": "cylinder", "radius": 0.1, "length": 0}, r"object\.length must be finite"),
        ({"shape": "mesh"}, r"object\.path is missing"),
        ({"shape": "mesh", "path": 3}, r"object\.path must be a non-empty string"),
        ({"shape": "mesh", "path": "x.obj", "scale": -2}, r"object\.scale must be finite"),
        ({"shape": "mesh", "path": "x\0.obj"}, r"object\.path must be a non-empty string"),
        (
            {"shape": "sphere", "radius": 10**400},
            r"object\.radius must be finite and > 0, got 1000",
        ),
        ({"shape": "box", "size": [1, 10**400, 1]}, r"object\.size must be 3 finite numbers"),
        ({"shape": ["sphere"], "radius": 1.0}, r"object\.shape must be one of"),
    ],
)
def test_shape_from_dict_errors(d: dict, match: str) -> None:
    with pytest.raises(InvalidInputError, match=match):
        shape_from_dict(d)


def test_field_name_in_errors() -> None:
    with pytest.raises(InvalidInputError, match=r"obstacles\[2\]\.radius"):
        shape_from_dict({"shape": "sphere", "radius": 0}, field="obstacles[2]")
    with pytest.raises(InvalidInputError, match="must be a table"):
        shape_from_dict(["sphere"])  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: Sphere(-1.0), r"radius must be finite and > 0, got -1\.0"),
        (lambda: Sphere(float("inf")), r"radius must be finite"),
        (lambda: Box([0.1, -0.1, 0.1]), r"size must be finite and > 0"),
        (lambda: Box([0.1, 0.1]), r"size must have shape \(3,\)"),
        (lambda: Capsule(0.1, 0.0), r"length must be finite and > 0, got 0\.0"),
        (lambda: Cylinder(float("nan"), 0.1), r"radius must be finite"),
    ],
)
def test_bad_primitive_parameters(make, match: str) -> None:
    with pytest.raises(InvalidInputError, match=match):
        make()


def test_missing_and_unreadable_files(tmp_path: Path) -> None:
    missing = tmp_path / "nope.obj"
    with pytest.raises(MeshError, match=r"nope\.obj"):
        Mesh.from_file(missing)
    with pytest.raises(MeshError, match=r"object\.path.*nope\.obj"):
        shape_from_dict({"shape": "mesh", "path": "nope.obj"}, base_dir=tmp_path)
    garbage = tmp_path / "garbage.obj"
    garbage.write_bytes(b"this is not a mesh\n\x00\x01\x02")
    with pytest.raises(MeshError, match=r"garbage\.obj"):
        Mesh.from_file(garbage)
    empty = tmp_path / "empty.stl"
    empty.write_bytes(b"")
    with pytest.raises(MeshError, match=r"empty\.stl"):
        Mesh.from_file(empty)
    odd = tmp_path / "mesh.xyz123"
    odd.write_text("1 2 3\n")
    with pytest.raises(MeshError, match=r"mesh\.xyz123"):
        Mesh.from_file(odd)
    with pytest.raises(InvalidInputError, match="scale"):
        Mesh.from_file(BUILTIN_MESH_DIR / "cup.obj", scale=0)


def test_open_mesh_rejected(tmp_path: Path) -> None:
    tm = trimesh.creation.icosphere(subdivisions=2, radius=0.05)
    open_tm = trimesh.Trimesh(tm.vertices, tm.faces[1:], process=False)
    with pytest.raises(MeshError, match="not watertight"):
        _tm_mesh(open_tm)
    path = tmp_path / "open.obj"
    open_tm.export(path)
    with pytest.raises(MeshError, match=r"open\.obj.*not watertight"):
        Mesh.from_file(path)


def test_degenerate_meshes_rejected() -> None:
    tm = trimesh.creation.icosphere(subdivisions=1, radius=0.05)
    v = np.asarray(tm.vertices)
    f = np.asarray(tm.faces)
    collapsed = v.copy()
    collapsed[f[0, 1]] = v[f[0, 0]]  # collapse an edge: zero-area faces
    with pytest.raises(MeshError, match="zero-area"):
        Mesh(collapsed, f)
    # a double-sided square: closed, but encloses nothing
    sq = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    faces = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]])
    with pytest.raises(MeshError, match="zero volume"):
        Mesh(sq, faces)
    # a duplicated face: its edges are used three times
    with pytest.raises(MeshError, match=r"non-manifold|inconsistently"):
        Mesh(v, np.concatenate([f, f[:1]]))
    with pytest.raises(MeshError, match="at least 4 faces"):
        Mesh(v, f[:3])
    with pytest.raises(InvalidInputError, match="faces"):
        Mesh(v, f[:, :2])
    with pytest.raises(InvalidInputError, match="index vertices"):
        Mesh(v, f + len(v))
    with pytest.raises(InvalidInputError, match="vertices must be finite"):
        Mesh(np.where(v > 0, np.nan, v), f)


def test_bad_query_inputs(ico: Mesh) -> None:
    for shape in (*PRIMITIVES, ico):
        with pytest.raises(InvalidInputError, match="p_obj"):
            shape.signed_distance(np.array([0.0, np.nan, 0.0]))
        with pytest.raises(InvalidInputError, match="p_obj"):
            shape.signed_distance_and_gradient(np.array([0.0, np.inf, 0.0]))
        with pytest.raises(InvalidInputError, match="p_obj"):
            shape.closest_point(np.zeros((4, 2)))
        with pytest.raises(InvalidInputError, match="n must be"):
            shape.sample_surface(-1, np.random.default_rng(0))
        with pytest.raises(InvalidInputError, match="rng"):
            shape.sample_surface(3, None)  # type: ignore[arg-type]
    # integer input takes the general path
    assert Sphere(1.0).signed_distance(np.array([0, 0, 2])) == 1.0
    assert issubclass(MeshError, DexplanError) and issubclass(InvalidInputError, DexplanError)


def test_medial_axis_choices_are_unit_vectors() -> None:
    for shape in PRIMITIVES:
        d, g = shape.signed_distance_and_gradient(np.zeros(3))
        assert d < 0 and np.linalg.norm(g) == pytest.approx(1.0)
        _, g2 = shape.signed_distance_and_gradient(np.zeros((20, 3)))
        np.testing.assert_allclose(g2, np.repeat(g[None], 20, 0))


# ---------------------------------------------------------------------- performance


def test_bvh_query_exact_on_finer_mesh() -> None:
    """coal's BVH finds the closest triangle exactly (vs testing all 20480)."""
    mesh = _tm_mesh(trimesh.creation.icosphere(subdivisions=5, radius=0.05))
    p = query_points(mesh, np.random.default_rng(19), 16)
    p = p[np.linalg.norm(p, axis=1) > 0.01]
    np.testing.assert_allclose(
        np.abs(mesh.signed_distance(p)), brute_force_distance(mesh, p), atol=1e-13
    )


@pytest.mark.slow
def test_large_mesh_matches_brute_force() -> None:
    """81920 triangles: exact distances and gradients (its speed is a benchmark's, not a test's)."""
    tm = trimesh.creation.icosphere(subdivisions=6, radius=0.05)  # 81920 triangles
    mesh = _tm_mesh(tm)
    rng = np.random.default_rng(18)
    p = query_points(mesh, rng, 20)
    p = p[np.linalg.norm(p, axis=1) > 0.01]
    np.testing.assert_allclose(
        np.abs(mesh.signed_distance(p)), brute_force_distance(mesh, p), atol=1e-13
    )
    near = mesh.sample_surface(50, rng)[0] * 1.01
    for q in near:
        d, g = mesh.signed_distance_and_gradient(q)
        assert d == pytest.approx(float(mesh.signed_distance(q[None])[0]), abs=1e-12)
        assert np.linalg.norm(g) == pytest.approx(1.0, abs=1e-9)


def test_box_edge_samples_lie_on_edges_with_normals_in_their_cone() -> None:
    from dexplan.model.objects.primitives import EDGE_NORMAL_MIN
    from dexplan.planfile.verify import TIP_DISTANCE_TOL

    box = Box([0.06, 0.04, 0.045])
    pts, normals = box.sample_edges(3000, np.random.default_rng(4))
    assert pts.shape == normals.shape == (3000, 3)
    half = box.size / 2
    # on an edge: exactly two coordinates at a face, the third inside
    at_face = np.isclose(np.abs(pts), half, atol=1e-12)
    assert np.all(at_face.sum(axis=1) == 2)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-12)
    # the normal lies between the two faces' normals, EDGE_NORMAL_MIN from each
    assert np.all(normals[~at_face] == 0.0)
    assert np.all(normals[at_face] * np.sign(pts[at_face]) >= math.sin(EDGE_NORMAL_MIN) - 1e-12)
    # every edge of the 12 is sampled
    assert len({tuple(np.sign(p) * f) for p, f in zip(pts, at_face, strict=True)}) == 12
    # a fingertip centred on that normal touches the edge point, pushing along it,
    # and lies farther than the verifier's tolerance from either face's reading
    for r in (0.006, 0.012):
        p, n = box.closest_point(pts + r * normals)
        np.testing.assert_allclose(p, pts, atol=1e-12)
        np.testing.assert_allclose(n, normals, atol=1e-12)
        assert 2 * r * math.sin(EDGE_NORMAL_MIN / 2) > TIP_DISTANCE_TOL


@pytest.mark.parametrize("shape", [Sphere(0.04), Capsule(0.02, 0.05), Cylinder(0.02, 0.05)])
def test_other_shapes_give_no_edge_samples_and_leave_the_stream(shape: Shape) -> None:
    rng = np.random.default_rng(7)
    pts, normals = shape.sample_edges(100, rng)
    assert pts.shape == normals.shape == (0, 3)
    assert rng.random() == np.random.default_rng(7).random()
