"""Edge and vertex contacts on triangle meshes: sharp convex features only."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import trimesh

import dexplan
from dexplan.model.hand.hand import Hand
from dexplan.model.objects import Box, Mesh
from dexplan.model.objects.fingertip import TIP_DISTANCE_TOL, fingertip_contact
from dexplan.model.objects.mesh import BUILTIN_MESH_DIR
from dexplan.model.objects.primitives import EDGE_NORMAL_MIN
from dexplan.model.scenario import load_scenario
from dexplan.planfile.verify import verify_plan
from dexplan.planning.context import build_context
from dexplan.planning.gsn.contact_kinds import face_normals, faces_only_reason
from dexplan.planning.gsn.sampler_settings import (
    SamplerSettings,
    combines_pairwise,
    resolved_settings,
)

A = 0.03  # half side of the cube (m)
R_TIP = 0.0095
CUBE = Mesh(trimesh.creation.box([2 * A, 2 * A, 2 * A]).vertices, trimesh.creation.box().faces)


def _l_prism() -> Mesh:
    """An L-shaped prism, 4 x 4 cm with a 2 x 2 cm notch, 2 cm tall: one concave edge."""
    xy = 0.02 * np.array([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]], dtype=float)
    v = np.vstack([np.c_[xy, np.zeros(6)], np.c_[xy, np.full(6, 0.02)]])
    # fans from the reflex corner (index 3) cover the L; top wound the other way
    bottom = [[3, 2, 1], [3, 1, 0], [3, 0, 5], [3, 5, 4]]
    top = [[9, 6 + b, 6 + c] for _, b, c in ([3, 1, 2], [3, 0, 1], [3, 5, 0], [3, 4, 5])]
    sides = []
    for i in range(6):
        j = (i + 1) % 6
        sides += [[i, j, 6 + j], [i, 6 + j, 6 + i]]
    return Mesh(v, bottom + top + sides)


L_PRISM = _l_prism()


def test_cube_mesh_has_twelve_sharp_edges_and_eight_corners() -> None:
    pts, n_out = CUBE.sample_edges(600, np.random.default_rng(1))
    assert pts.shape == n_out.shape == (600, 3)
    # on an edge: exactly two coordinates at +-A; the normal is perpendicular to it
    on = np.isclose(np.abs(pts), A, atol=1e-12)
    assert np.all(on.sum(axis=1) == 2)
    np.testing.assert_allclose(np.linalg.norm(n_out, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(n_out[~on], 0.0, atol=1e-12)
    # inside the wedge, at least EDGE_NORMAL_MIN from both faces
    assert np.all(n_out[on] * np.sign(pts[on]) >= math.sin(EDGE_NORMAL_MIN) - 1e-12)
    assert len(np.unique(np.round(np.where(on, pts, 0.0), 9), axis=0)) == 12
    v_pts, v_nrm = CUBE.sample_vertices(400, np.random.default_rng(2))
    np.testing.assert_allclose(np.abs(v_pts), A, atol=1e-12)
    assert len(np.unique(np.sign(v_pts), axis=0)) == 8
    assert np.all(v_nrm * np.sign(v_pts) >= math.sin(EDGE_NORMAL_MIN) - 1e-12)


def _edge_and_vertex_contacts(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(4)
    e = mesh.sample_edges(300, rng)
    v = mesh.sample_vertices(100, rng)
    assert len(e[0]) == 300 and len(v[0]) == 100
    return np.vstack([e[0], v[0]]), np.vstack([e[1], v[1]])


def test_fingertip_centre_closest_point_is_the_sampled_contact_on_a_cube() -> None:
    """The planner reads a contact as the closest point to the fingertip centre,
    the verifier through fingertip_contact: both find the sampled point."""
    pts, n_out = _edge_and_vertex_contacts(CUBE)
    tips = pts + R_TIP * n_out
    q, g = CUBE.closest_point(tips)
    np.testing.assert_allclose(q, pts, atol=1e-6)
    np.testing.assert_allclose(g, n_out, atol=1e-6)
    for p, n, tip in zip(pts, n_out, tips, strict=True):
        p_v, n_v, gap = fingertip_contact(CUBE, p, tip, R_TIP)
        np.testing.assert_allclose(p_v, p, atol=1e-6)
        assert gap <= TIP_DISTANCE_TOL
        # near the edge's pseudo-normal the verifier keeps it (within the tolerance)
        assert np.linalg.norm(n_v - n) <= TIP_DISTANCE_TOL / R_TIP + 1e-9


def test_on_a_non_convex_mesh_the_contact_is_closest_unless_the_tip_collides() -> None:
    """Near a concavity a fingertip on a convex edge may reach into another
    wall (as one on a face may): its centre is then closer than its radius to
    the surface, the collision the planner rejects. Every other sampled
    contact is the closest point to its fingertip centre."""
    pts, n_out = _edge_and_vertex_contacts(L_PRISM)
    tips = pts + R_TIP * n_out
    q, g = L_PRISM.closest_point(tips)
    clear = np.asarray(L_PRISM.signed_distance(tips)) >= R_TIP - 1e-9
    assert clear.mean() > 0.8
    np.testing.assert_allclose(q[clear], pts[clear], atol=1e-6)
    np.testing.assert_allclose(g[clear], n_out[clear], atol=1e-6)
    assert np.all(np.linalg.norm(q[~clear] - pts[~clear], axis=1) > 1e-6)


def test_concave_edges_and_vertices_are_not_sampled() -> None:
    pts, _ = L_PRISM.sample_edges(2000, np.random.default_rng(5))
    # the concave edge is the vertical line through (0.02, 0.02)
    assert not np.any(np.all(np.isclose(pts[:, :2], 0.02, atol=1e-9), axis=1))
    v_pts, _ = L_PRISM.sample_vertices(500, np.random.default_rng(6))
    corners = np.unique(np.round(v_pts, 9), axis=0)
    assert len(corners) == 10  # 12 vertices less the two ends of the concave edge
    assert not np.any(np.all(np.isclose(corners[:, :2], 0.02, atol=1e-9), axis=1))


def test_sampling_is_deterministic_and_zero_draws_nothing() -> None:
    a = CUBE.sample_contacts(20, np.random.default_rng(7), 10, 5)
    b = CUBE.sample_contacts(20, np.random.default_rng(7), 10, 5)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    rng = np.random.default_rng(8)
    assert CUBE.sample_edges(0, rng)[0].shape == (0, 3)
    assert CUBE.sample_vertices(0, rng)[0].shape == (0, 3)
    assert rng.random() == np.random.default_rng(8).random()


def test_smooth_meshes_have_no_sharp_features_and_keep_their_stream() -> None:
    bean = Mesh.from_file(BUILTIN_MESH_DIR / "bean.obj", scale=0.001)
    rng = np.random.default_rng(9)
    assert bean.sample_edges(10, rng)[0].shape == (0, 3)
    assert bean.sample_vertices(10, rng)[0].shape == (0, 3)
    assert rng.random() == np.random.default_rng(9).random()
    assert face_normals(bean) is None


def test_gsn_sampler_treats_a_cube_mesh_like_a_box() -> None:
    """Faces alone cannot hold a cube for 3 fingers: the sampler then draws
    edges and corners and combines pairwise, for a mesh cube as for a Box."""
    hand = Hand.builtin("three_finger")
    box = Box((2 * A, 2 * A, 2 * A))
    reason = faces_only_reason(CUBE, hand, 3, 0.8)
    assert reason is not None and reason == faces_only_reason(box, hand, 3, 0.8)
    mesh_normals, box_normals = face_normals(CUBE), face_normals(box)
    assert mesh_normals is not None and box_normals is not None
    np.testing.assert_allclose(mesh_normals, box_normals, atol=1e-9)
    _, _, _, edges = resolved_settings(SamplerSettings(), hand, reason is not None)
    assert edges
    assert combines_pairwise(SamplerSettings(), 3, True, reason is not None)
    # four fingers may hold a cube on faces: no screen, as for a Box
    assert faces_only_reason(CUBE, hand, 4, 0.8) is None


def test_vertices_of_no_face_are_no_corners() -> None:
    box = trimesh.creation.box([2 * A, 2 * A, 2 * A])
    mesh = Mesh(np.vstack([box.vertices, [[1.0, 1.0, 1.0]]]), box.faces)
    pts, _ = mesh.sample_vertices(200, np.random.default_rng(10))
    np.testing.assert_allclose(np.abs(pts), A, atol=1e-12)
    assert len(np.unique(np.sign(pts), axis=0)) == 8


TRIFINGER_YAW = Path("scenarios/trifinger_cube_yaw90.toml")


def _mesh_cube_scenario(tmp_path: Path) -> Path:
    """The TriFinger's cube scenario with the 65 mm cube as a triangle mesh."""
    trimesh.creation.box([0.065, 0.065, 0.065]).export(tmp_path / "cube.obj")
    box = 'shape = "box"\nsize = [0.065, 0.065, 0.065]'
    text = TRIFINGER_YAW.read_text()
    assert box in text
    path = tmp_path / "mesh_cube.toml"
    path.write_text(text.replace(box, 'shape = "mesh"\npath = "cube.obj"'))
    return path


def test_trifinger_sampler_draws_edges_and_corners_on_a_mesh_cube(tmp_path: Path) -> None:
    ctx = build_context(load_scenario(_mesh_cube_scenario(tmp_path)), seed=1)
    sampler = ctx.sampler
    assert sampler.faces_only is not None
    assert sampler._pairwise
    assert sampler._edges[1] > 0 and sampler._vertices[1] > 0


@pytest.mark.slow
def test_trifinger_turns_a_mesh_cube_and_the_plan_verifies(tmp_path: Path) -> None:
    scen = load_scenario(_mesh_cube_scenario(tmp_path))
    plan = dexplan.plan(scen, seed=1, quality="none", time_limit=120.0)
    assert plan.solved, plan.status  # solved means the verifier accepted it
    report = verify_plan(plan.to_document("."))
    assert report.ok, [str(v) for v in report.violations[:5]]
    again = dexplan.plan(scen, seed=1, quality="none", time_limit=120.0)
    assert again.to_document(".")["segments"] == plan.to_document(".")["segments"]
