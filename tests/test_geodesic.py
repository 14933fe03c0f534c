"""Tests of dexplan.model.objects.geodesic: surface geodesics on meshes (potpourri3d)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from dexplan.core.errors import DexplanError, GeodesicError, MeshError
from dexplan.model.objects import BUILTIN_MESH_DIR, Mesh
from dexplan.model.objects.geodesic import MeshGeodesics, SurfacePath, surface_geodesics

RADIUS = 0.04


def _icosphere(subdivisions: int) -> Mesh:
    tm = trimesh.creation.icosphere(subdivisions=subdivisions, radius=RADIUS)
    return Mesh(np.asarray(tm.vertices), np.asarray(tm.faces))


def _edge_length(mesh: Mesh) -> float:
    """Longest edge of the mesh (m): the resolution the tolerances scale with."""
    t = mesh.vertices[mesh.faces]
    return float(np.linalg.norm(t - np.roll(t, 1, axis=1), axis=2).max())


def _great_circle(a: np.ndarray, b: np.ndarray) -> float:
    ua, ub = a / np.linalg.norm(a), b / np.linalg.norm(b)
    return RADIUS * math.acos(float(np.clip(ua @ ub, -1.0, 1.0)))


@pytest.mark.parametrize("subdivisions", [2, 3, 4])
def test_length_matches_great_circle_within_mesh_resolution(subdivisions: int) -> None:
    mesh = _icosphere(subdivisions)
    geo = surface_geodesics(mesh)
    h = _edge_length(mesh)
    rng = np.random.default_rng(subdivisions)
    errors = []
    for _ in range(25):
        tri, u, v = mesh.sample_surface_params(2, rng)
        a, b = mesh.contact_points(tri, u, v)
        errors.append(geo.path(a, b).length - _great_circle(a, b))
    errors = np.abs(errors)
    # the stitched ends add at most 2 corner distances (< 2 h); measured < 0.6 h
    assert errors.max() <= h, (errors.max(), h)


def test_error_shrinks_with_resolution() -> None:
    rng = np.random.default_rng(7)
    a_b = [(_icosphere(2), []), (_icosphere(4), [])]
    pairs = [rng.normal(size=(2, 3)) for _ in range(20)]
    for mesh, errs in a_b:
        geo = surface_geodesics(mesh)
        for pair in pairs:
            a, b = mesh.closest_point(pair * 1.0)[0]
            errs.append(abs(geo.path(a, b).length - _great_circle(a, b)))
    assert np.mean(a_b[1][1]) < 0.5 * np.mean(a_b[0][1])


def test_path_on_surface_and_continuous() -> None:
    mesh = Mesh.from_file(BUILTIN_MESH_DIR / "bean.obj")
    geo = surface_geodesics(mesh)
    h = _edge_length(mesh)
    rng = np.random.default_rng(3)
    for _ in range(10):
        tri, u, v = mesh.sample_surface_params(2, rng)
        a, b = mesh.contact_points(tri, u, v)
        path = geo.path(a, b)
        assert isinstance(path, SurfacePath)
        # ends are the given surface points
        np.testing.assert_allclose(path.points[0], a, atol=1e-12)
        np.testing.assert_allclose(path.points[-1], b, atol=1e-12)
        # every point and every segment's samples lie on the surface (SDF ~ 0)
        dense = path.resample(h / 4)
        assert np.max(np.abs(mesh.signed_distance(dense))) < 1e-9
        assert np.max(np.abs(mesh.signed_distance(path.points))) < 1e-9
        # continuity: no jump longer than a triangle
        steps = np.linalg.norm(np.diff(path.points, axis=0), axis=1)
        assert steps.max() <= h + 1e-12
        # never shorter than the straight chord, never absurdly longer
        chord = float(np.linalg.norm(b - a))
        assert chord - 1e-12 <= path.length <= 3.0 * chord + 2 * h
        # each point's triangle holds its outgoing segment; normals are face normals
        for i in range(len(path.points) - 1):
            mid = 0.5 * (path.points[i] + path.points[i + 1])
            t = mesh.vertices[mesh.faces[path.triangles[i]]]
            n = mesh.face_normals[path.triangles[i]]
            assert abs(float((mid - t[0]) @ n)) < 1e-9
        np.testing.assert_allclose(path.normals_out, mesh.face_normals[path.triangles])


def test_at_walks_the_arc_length() -> None:
    mesh = _icosphere(3)
    geo = surface_geodesics(mesh)
    a = mesh.closest_point(np.array([1.0, 0.0, 0.2]))[0]
    b = mesh.closest_point(np.array([-0.3, 1.0, -0.1]))[0]
    path = geo.path(a, b)
    p0, _, _ = path.at(0.0)
    p1, _, _ = path.at(1.0)
    np.testing.assert_allclose(p0, a, atol=1e-12)
    np.testing.assert_allclose(p1, b, atol=1e-12)
    # the midpoint splits the path into two equal halves
    pm, tri, n = path.at(0.5)
    assert abs(mesh.signed_distance(pm)) < 1e-9
    np.testing.assert_allclose(n, mesh.face_normals[tri])
    d_a = geo.path(a, pm).length
    d_b = geo.path(pm, b).length
    h = _edge_length(mesh)
    assert abs(d_a - 0.5 * path.length) < h
    assert abs(d_b - 0.5 * path.length) < h


def test_same_triangle_is_the_straight_segment() -> None:
    mesh = _icosphere(2)
    geo = surface_geodesics(mesh)
    a = mesh.contact_points(5, 0.2, 0.2)
    b = mesh.contact_points(5, 0.6, 0.1)
    path = geo.path(a, b)
    assert len(path.points) == 2
    assert path.length == pytest.approx(float(np.linalg.norm(b - a)), abs=1e-15)
    same = geo.path(a, a)
    assert same.length == 0.0
    np.testing.assert_allclose(same.at(0.5)[0], a)


def test_symmetric_and_deterministic() -> None:
    mesh = Mesh.from_file(BUILTIN_MESH_DIR / "egg.obj")
    geo = surface_geodesics(mesh)
    rng = np.random.default_rng(11)
    tri, u, v = mesh.sample_surface_params(6, rng)
    pts = mesh.contact_points(tri, u, v)
    first = geo.path(pts[0], pts[1]).points.copy()
    for k in range(2, 5):  # other queries in between change nothing
        geo.path(pts[k], pts[k + 1])
    np.testing.assert_array_equal(geo.path(pts[0], pts[1]).points, first)
    back = geo.path(pts[1], pts[0])
    assert back.length == pytest.approx(geo.path(pts[0], pts[1]).length, rel=1e-9)


def test_solver_cached_per_mesh() -> None:
    mesh = _icosphere(2)
    assert surface_geodesics(mesh) is surface_geodesics(mesh)
    other = _icosphere(2)
    assert surface_geodesics(other) is not surface_geodesics(mesh)


def _bowtie() -> Mesh:
    """Two cubes touching at one vertex: every edge manifold, one vertex not."""
    a = trimesh.creation.box(extents=[1.0, 1.0, 1.0])
    b = a.copy()
    b.apply_translation([1.0, 1.0, 1.0])
    v = np.vstack([a.vertices, b.vertices])
    f = np.vstack([a.faces, b.faces + len(a.vertices)])
    tm = trimesh.Trimesh(v, f, process=True)  # merges the shared corner
    assert len(tm.vertices) == 15
    return Mesh(np.asarray(tm.vertices), np.asarray(tm.faces))


def test_non_manifold_vertex_raises_naming_the_mesh() -> None:
    mesh = _bowtie()  # dexplan's own checks accept it
    with pytest.raises(GeodesicError, match="cannot compute geodesics on mesh") as info:
        surface_geodesics(mesh)
    assert isinstance(info.value, MeshError) and isinstance(info.value, DexplanError)
    assert "manifold" in str(info.value)
    with pytest.raises(GeodesicError):  # the failure is cached, raised again
        surface_geodesics(mesh)


def test_disconnected_shells_raise() -> None:
    a = trimesh.creation.icosphere(subdivisions=1, radius=0.02)
    b = a.copy()
    b.apply_translation([0.1, 0.0, 0.0])
    mesh = Mesh(np.vstack([a.vertices, b.vertices]), np.vstack([a.faces, b.faces + 42]))
    geo = MeshGeodesics(mesh)
    with pytest.raises(GeodesicError, match="disconnected"):
        geo.path(np.array([0.0, 0.0, 0.02]), np.array([0.1, 0.0, 0.02]))


def test_resample_rejects_bad_step() -> None:
    mesh = _icosphere(1)
    path = surface_geodesics(mesh).path(mesh.vertices[0], mesh.vertices[5])
    with pytest.raises(GeodesicError):
        path.resample(0.0)
