"""Rolling contact kinematics (dexplan.model.grasp.rolling): no slip, tangency, both contacts."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from dexplan.core.errors import InvalidInputError
from dexplan.core.pose import quat_to_matrix
from dexplan.model.grasp.contact_jacobians import point_jacobian
from dexplan.model.grasp.rolling import FingertipRolling, RollSettings
from dexplan.model.scenario.scenario import load_scenario
from dexplan.planning.context import build_context
from dexplan.planning.gsn.space import POSE_DIM
from dexplan.planning.local.grasps import grasp_from_state

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"


def _grasp(name: str, seed: int = 3):
    """A valid sampled grasp at the scenario's start: (roll model, q, pose, contacts (n, 3))."""
    ctx = build_context(load_scenario(SCENARIOS / f"{name}.toml"), seed)
    pose = ctx.scenario.start.object_pose_xyzquat
    x = ctx.sampler.sample_at_pose(pose)
    assert x is not None
    q = x[POSE_DIM:]
    contacts = grasp_from_state(ctx.transitions, pose, q).points
    return FingertipRolling(ctx.hand, ctx.obj), q, np.asarray(pose, dtype=float), contacts


def _turned(pose: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """``pose`` turned by ``angle`` (rad) about a world axis through its centre."""
    R = pin.exp3(axis / np.linalg.norm(axis) * angle) @ quat_to_matrix(pose[3:])
    q = pin.Quaternion(R)
    return np.concatenate([pose[:3], [q.x, q.y, q.z, q.w]])


@pytest.fixture(scope="module")
def paper_grasp():
    return _grasp("paper_sphere")


def test_point_jacobian_matches_finite_differences(paper_grasp) -> None:
    roll, q, _, _ = paper_grasp
    hand = roll.hand
    rng = np.random.default_rng(0)
    for f in range(hand.n_fingers):
        R_t, c, J6 = roll.tip_frame(f, q)
        s_tip = rng.normal(size=3) * 0.01  # a point fixed on the tip link, tip frame
        J = point_jacobian(J6, c + R_t @ s_tip, c)
        idx = hand.finger_q_index[f]
        h = 1e-6
        for k, j in enumerate(idx):
            qp, qm = q.copy(), q.copy()
            qp[j] += h
            qm[j] -= h
            Rp, cp, _ = roll.tip_frame(f, qp)
            Rm, cm, _ = roll.tip_frame(f, qm)
            fd = ((cp + Rp @ s_tip) - (cm + Rm @ s_tip)) / (2 * h)
            np.testing.assert_allclose(J[:, k], fd, atol=1e-6)


def test_material_points_in_contact_move_together(paper_grasp) -> None:
    """No slip, judged by forward kinematics alone: over a small turn the tip's material
    point at the contact moves with the object's (to second order in the step)."""
    roll, q, pose, contacts = paper_grasp
    step = np.radians(0.2)
    b = _turned(pose, np.array([0.0, 0.0, 1.0]), step)
    R_a, R_b = quat_to_matrix(pose[3:]), quat_to_matrix(b[3:])
    for f in range(roll.hand.n_fingers):
        s_tip = roll.tip_point(f, q, pose, contacts[f])  # the tip's material point, tip frame
        r = roll.roll(f, q, pose, b, contacts[f])
        R_t, c, _ = roll.tip_frame(f, r.q)
        moved_tip = c + R_t @ s_tip
        moved_obj = b[:3] + R_b @ contacts[f]
        d_obj = np.linalg.norm(moved_obj - (pose[:3] + R_a @ contacts[f]))
        assert d_obj > 1e-5  # the contact point really moves
        assert np.linalg.norm(moved_tip - moved_obj) < 0.02 * d_obj


@pytest.mark.parametrize("axis", [(0.0, 0.0, 1.0), (1.0, 0.0, 0.0)])
def test_a_rolled_tip_stays_tangent_and_rolls_equal_arcs(paper_grasp, axis) -> None:
    roll, q, pose, contacts = paper_grasp
    b = _turned(pose, np.array(axis), np.radians(4.0))
    R_b = quat_to_matrix(b[3:])
    for f in range(roll.hand.n_fingers):
        r = roll.roll(f, q, pose, b, contacts[f])
        _, c, _ = roll.tip_frame(f, r.q)
        gap = roll.obj.signed_distance(R_b.T @ (c - b[:3])) - roll.radius
        assert abs(gap) < 1e-9
        # the two contacts are the same world point, on the object and on the tip sphere
        R_t, _, _ = roll.tip_frame(f, r.q)
        np.testing.assert_allclose(b[:3] + R_b @ r.p_obj, c + R_t @ r.p_tip, atol=1e-9)
        assert abs(np.linalg.norm(r.p_tip) - roll.radius) < 1e-9
        assert r.slip < 1e-7  # a 3-joint finger is determined by the object's motion
        assert r.arc_obj > 1e-4  # the contact moves: the fixed contact would slide
        assert abs(r.arc_tip - r.arc_obj) <= 0.005 * r.arc_obj
        # the joints are not those of the fixed contact
        assert np.linalg.norm(r.p_obj - contacts[f]) > 1e-4


def test_finer_substeps_converge(paper_grasp) -> None:
    roll, q, pose, contacts = paper_grasp
    b = _turned(pose, np.array([0.0, 0.0, 1.0]), np.radians(4.0))
    coarse = roll.roll(1, q, pose, b, contacts[1])
    fine = FingertipRolling(roll.hand, roll.obj, RollSettings(max_substep_rad=5e-4)).roll(
        1, q, pose, b, contacts[1]
    )
    assert abs(fine.arc_tip - fine.arc_obj) < abs(coarse.arc_tip - coarse.arc_obj) + 1e-9
    assert np.linalg.norm(fine.p_obj - coarse.p_obj) < 1e-4


def test_a_redundant_finger_rolls_with_the_least_joint_motion() -> None:
    roll, q, pose, contacts = _grasp("allegro_sphere", seed=2)
    b = _turned(pose, np.array([0.0, 0.0, 1.0]), np.radians(2.0))
    r = roll.roll(0, q, pose, b, contacts[0])
    assert len(roll.hand.finger_q_index[0]) == 4
    assert r.slip < 1e-7
    assert abs(r.arc_tip - r.arc_obj) <= 0.005 * r.arc_obj


def test_rolling_on_a_mesh_reads_the_contact_on_the_surface() -> None:
    roll, q, pose, contacts = _grasp("allegro_mesh", seed=1)
    b = _turned(pose, np.array([0.0, 0.0, 1.0]), np.radians(2.0))
    R_b = quat_to_matrix(b[3:])
    for f in range(roll.hand.n_fingers):
        r = roll.roll(f, q, pose, b, contacts[f])
        assert abs(roll.obj.signed_distance(r.p_obj)) < 1e-6
        _, c, _ = roll.tip_frame(f, r.q)
        assert abs(roll.obj.signed_distance(R_b.T @ (c - b[:3])) - roll.radius) < 1e-6


@pytest.mark.parametrize("name", ["paper_sphere", "allegro_mesh"])
def test_fingers_rolled_together_roll_as_each_alone(name: str) -> None:
    """The fingers are independent chains: rolling them in one pass changes nothing."""
    roll, q, pose, contacts = _grasp(name, seed=1)
    b = _turned(pose, np.array([0.3, 0.2, 1.0]), np.radians(3.0))
    fingers = list(range(roll.hand.n_fingers))
    together = roll.roll_fingers(fingers, q, pose, b, contacts)
    for f, r in zip(fingers, together, strict=True):
        alone = roll.roll(f, q, pose, b, contacts[f])
        idx = roll.hand.finger_q_index[f]
        np.testing.assert_allclose(r.q[idx], alone.q[idx], rtol=0.0, atol=1e-12)
        np.testing.assert_allclose(r.p_obj, alone.p_obj, rtol=0.0, atol=1e-12)
        np.testing.assert_allclose(r.p_tip, alone.p_tip, rtol=0.0, atol=1e-12)
        assert abs(r.arc_obj - alone.arc_obj) < 1e-12 and abs(r.arc_tip - alone.arc_tip) < 1e-12
    with pytest.raises(InvalidInputError, match="must not repeat"):
        roll.roll_fingers([0, 0], q, pose, b, contacts[[0, 0]])


def test_bad_inputs_raise_clear_errors(paper_grasp) -> None:
    roll, q, pose, contacts = paper_grasp
    n = contacts[0] / np.linalg.norm(contacts[0])  # the ball is centred on its frame
    t = np.cross(n, [0.0, 0.0, 1.0])
    off = contacts[0] + 0.008 * t / np.linalg.norm(t)  # 8 mm along the surface
    with pytest.raises(InvalidInputError, match="does not touch"):
        roll.roll(0, q, pose, pose, off)
    with pytest.raises(InvalidInputError, match="finger must be"):
        roll.roll(7, q, pose, pose, contacts[0])
    with pytest.raises(InvalidInputError, match="max_substep_rad"):
        RollSettings(max_substep_rad=0.0)


def test_a_redundant_finger_keeps_away_from_its_joint_limits_while_it_rolls() -> None:
    """The null-space step moves the joints towards mid-range and leaves the rolling exact."""
    roll, q0, pose, contacts = _grasp("allegro_sphere", seed=2)
    plain = FingertipRolling(roll.hand, roll.obj, RollSettings(limit_gain=0.0))
    lo, hi = roll.hand.lower, roll.hand.upper
    gained = []
    for f in range(roll.hand.n_fingers):
        idx = roll.hand.finger_q_index[f]
        worst = []
        for model in (roll, plain):
            q, p, a = q0.copy(), contacts[f], pose
            for k in range(1, 11):  # 20 degrees about the palm normal, in 2 degree steps
                b = _turned(pose, np.array([0.0, 0.0, 1.0]), np.radians(2.0 * k))
                r = model.roll(f, q, a, b, p)
                assert r.slip < 1e-6
                assert abs(r.arc_tip - r.arc_obj) <= 0.005 * r.arc_obj + 1e-7
                q, p, a = r.q, r.p_obj, b
            offset = np.abs(q[idx] - 0.5 * (lo[idx] + hi[idx])) / (0.5 * (hi[idx] - lo[idx]))
            worst.append(float(np.max(offset)))
        assert worst[0] <= worst[1] + 1e-9
        gained.append(worst[1] - worst[0])
    assert max(gained) > 0.01


def test_stacked_contact_jacobians_are_each_fingers_own_bit_for_bit() -> None:
    """Stacked point Jacobians, rotations and damped steps: each row as computed alone."""
    from dexplan.model.grasp.contact_jacobians import (
        damped_step,
        damped_steps,
        point_jacobian,
        point_jacobians,
        rotate_rows,
    )

    rng = np.random.default_rng(11)
    for m in (2, 3, 4):
        J6 = rng.normal(size=(4, 6, m))
        p, c = rng.normal(size=(4, 3)), rng.normal(size=(4, 3))
        J = point_jacobians(J6, p, c)
        for i in range(4):
            assert np.array_equal(J[i], point_jacobian(J6[i], p[i], c[i]))
        rhs = rng.normal(size=(4, 3))
        steps = damped_steps(J, rhs, 1e-9)
        for i in range(4):
            assert np.array_equal(steps[i], damped_step(J[i], rhs[i], 1e-9))
            # the step solves the point's motion (least squares for fewer than 3 joints)
            if m >= 3:
                np.testing.assert_allclose(J[i] @ steps[i], rhs[i], atol=1e-6)
    R, v = rng.normal(size=(3, 3)), rng.normal(size=(5, 3))
    assert np.array_equal(rotate_rows(R, v), np.array([R @ x for x in v]))
    Rs = rng.normal(size=(5, 3, 3))
    assert np.array_equal(rotate_rows(Rs, v), np.array([Rs[i] @ v[i] for i in range(5)]))
