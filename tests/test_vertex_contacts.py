"""Vertex (corner) contacts on boxes and the pairwise combination of three fingers' pools."""

import math

import numpy as np
import pytest

from dexplan.model.grasp.batch import min_subgrasp_quality_batch
from dexplan.model.objects import Box, Sphere
from dexplan.model.objects.fingertip import fingertip_contact
from dexplan.model.objects.primitives import EDGE_NORMAL_MIN
from dexplan.model.scenario import load_scenario
from dexplan.planning.context import build_context
from dexplan.planning.gsn.combinations import combine_pools_pairwise
from dexplan.planning.gsn.sampler import SamplerSettings
from dexplan.planning.gsn.space import POSE_DIM

CUBE = Box([0.065, 0.065, 0.065])
R_TIP = 0.0095
TRIFINGER_YAW = "scenarios/trifinger_cube_yaw90.toml"


def test_box_vertices_lie_at_corners_with_normals_inside_the_corner_cone() -> None:
    pts, n_out = CUBE.sample_vertices(400, np.random.default_rng(1))
    np.testing.assert_allclose(np.abs(pts), 0.0325, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(n_out, axis=1), 1.0, atol=1e-12)
    # same octant as the corner, at least EDGE_NORMAL_MIN from every face plane
    assert np.all(n_out * np.sign(pts) >= math.sin(EDGE_NORMAL_MIN) - 1e-12)
    # all 8 corners drawn
    assert len(np.unique(np.sign(pts), axis=0)) == 8


def test_shapes_without_vertices_draw_none_and_keep_the_stream() -> None:
    rng = np.random.default_rng(3)
    pts, _ = Sphere(0.03).sample_vertices(10, rng)
    assert pts.shape == (0, 3)
    assert rng.random() == np.random.default_rng(3).random()


def test_contacts_without_vertices_are_those_drawn_before() -> None:
    a = CUBE.sample_contacts(20, np.random.default_rng(5), 10)
    b = CUBE.sample_contacts(20, np.random.default_rng(5), 10, 0)
    np.testing.assert_array_equal(a[0], b[0])
    pts, _ = CUBE.sample_contacts(20, np.random.default_rng(5), 10, 7)
    assert len(pts) == 37


def test_planner_and_verifier_read_the_same_vertex_normal() -> None:
    """The planner reads a contact from the fingertip centre (closest point),
    the verifier from the stated contact and the centre: at a corner both
    give the direction from the corner to the centre, which force closure
    then uses as the contact's normal."""
    pts, n_out = CUBE.sample_vertices(200, np.random.default_rng(2))
    tips = pts + R_TIP * n_out
    c_planner, n_planner = CUBE.closest_point(tips)
    np.testing.assert_allclose(c_planner, pts, atol=1e-12)
    np.testing.assert_allclose(n_planner, n_out, atol=1e-12)
    for p, n, tip in zip(pts, n_out, tips, strict=True):
        p_v, n_v, gap = fingertip_contact(CUBE, p, tip, R_TIP)
        np.testing.assert_allclose(p_v, p, atol=1e-12)
        np.testing.assert_allclose(n_v, n, atol=1e-12)
        assert gap < 1e-9


def _pools_near_a_valid_grasp(rng: np.random.Generator, size: int):
    """Three pools of cube contacts around the TriFinger's grasp (a face, two
    vertical edges), and random faces, edges and corners: fingertip centres outside."""
    a = 0.0325
    z = rng.uniform(-0.01, 0.01, (3, size))
    face = np.stack([np.full(size, -a), rng.uniform(-0.01, 0.01, size), z[0]], 1)
    face_n = np.tile([-1.0, 0.0, 0.0], (size, 1))
    near = [(face, face_n)]
    for f, sy in ((1, -1.0), (2, 1.0)):
        ang = rng.uniform(0.05, math.pi / 2 - 0.05, size)  # outward, between +x and sy y
        pts = np.stack([np.full(size, a), np.full(size, sy * a), z[f]], 1)
        near.append((pts, np.stack([np.cos(ang), sy * np.sin(ang), np.zeros(size)], 1)))
    pools = {}
    for f in range(3):
        p, n = CUBE.sample_contacts(size // 2, rng, size // 2, size // 4)
        p, n = np.vstack([near[f][0], p]), np.vstack([near[f][1], n])
        pools[f] = (p + R_TIP * n, n, np.zeros((len(p), 3)))
    return pools


class _Hand:
    """The few hand attributes the combination reads: 3 fingers of 3 joints."""

    def __init__(self) -> None:
        self.fingertip_radius = R_TIP
        self.lower = np.full(9, -1.0)
        self.upper = np.full(9, 1.0)
        self.finger_q_index = [np.arange(3 * f, 3 * f + 3) for f in range(3)]


def test_pairwise_combination_never_drops_a_force_closure_grasp() -> None:
    """Every triple whose 2-finger subgrasps are all force closure (the
    planner's own quality, soft contacts) passes the pairwise screen."""
    rng = np.random.default_rng(7)
    pools = _pools_near_a_valid_grasp(rng, 16)
    pose = np.array([0, 0, 0, 0, 0, 0, 1.0])
    kept = combine_pools_pairwise(pose, pools, _Hand(), rng, mu=0.8, tip_clearance=0.0, count=10**6)
    kept_keys = {tuple(np.round(p.ravel(), 9)) for p in kept.points_obj}
    idx = np.stack(np.meshgrid(*[np.arange(len(pools[f][0])) for f in range(3)]), -1)
    idx = idx.reshape(-1, 3)
    pts = np.stack([pools[f][0][idx[:, f]] - R_TIP * pools[f][1][idx[:, f]] for f in range(3)], 1)
    nin = np.stack([-pools[f][1][idx[:, f]] for f in range(3)], 1)
    tips = np.stack([pools[f][0][idx[:, f]] for f in range(3)], 1)
    apart = np.all(
        [
            np.linalg.norm(tips[:, a] - tips[:, b], axis=1) >= 2 * R_TIP
            for a, b in ((0, 1), (0, 2), (1, 2))
        ],
        axis=0,
    )
    q = min_subgrasp_quality_batch(
        pts[apart],
        nin[apart],
        0.8,
        torque_scale=0.05,
        margin=0.0,
        contact_model="soft",
        torsion=0.005,
    )
    fc = pts[apart][q > 0]
    assert len(fc) >= 5  # the test has cases to check
    for p in fc:
        assert tuple(np.round(p.ravel(), 9)) in kept_keys
    # and the screen does drop most triples
    assert len(kept) < 0.5 * apart.sum()


@pytest.fixture(scope="module")
def trifinger_cube():
    return build_context(load_scenario(TRIFINGER_YAW), seed=1)


def test_trifinger_cube_sampler_draws_edges_and_corners_and_combines_pairwise(
    trifinger_cube,
) -> None:
    sampler = trifinger_cube.sampler
    assert sampler.faces_only is not None
    assert sampler._pairwise
    assert sampler._edges[1] > 0 and sampler._vertices[1] > 0


def test_trifinger_cube_start_grasps_are_valid_and_reproducible() -> None:
    def grasps(seed: int) -> list[np.ndarray]:
        ctx = build_context(load_scenario(TRIFINGER_YAW), seed=seed)
        pose = ctx.scenario.start.object_pose_xyzquat
        return ctx.sampler.samples_at_pose(pose, 3), ctx

    got, ctx = grasps(2)
    assert len(got) == 3
    for x in got:
        assert ctx.validity.is_valid(x)
        np.testing.assert_array_equal(x[:POSE_DIM], ctx.scenario.start.object_pose_xyzquat)
    again, _ = grasps(2)
    for a, b in zip(got, again, strict=True):
        np.testing.assert_array_equal(a, b)


def test_vertex_and_pairwise_switches_turn_off() -> None:
    ctx = build_context(
        load_scenario(TRIFINGER_YAW),
        seed=1,
        sampler_settings=SamplerSettings(vertex_contacts=False, pairwise=False),
    )
    assert not ctx.sampler._pairwise and ctx.sampler._vertices == (0, 0)
