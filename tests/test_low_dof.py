"""Fingers with fewer than 3 joints: hands cut out of robots, contacts on the contact curve."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import dexplan
from dexplan.core.errors import ModelError, ScenarioError
from dexplan.core.pose import quat_to_matrix, slerp
from dexplan.model.grasp.rolling import ContactMotion
from dexplan.model.hand.extract import extract_hand
from dexplan.model.hand.hand import Hand
from dexplan.model.objects import shape_from_dict
from dexplan.model.scenario.identity import scenario_description, scenario_hash
from dexplan.model.scenario.scenario import load_scenario
from dexplan.planfile.verify import verify_plan
from dexplan.planning.context import build_context
from dexplan.planning.gsn.contact_curve import contact_curve_samples, low_dof
from dexplan.planning.gsn.sampler import SamplerSettings
from dexplan.planning.local.transitions.contacts import GraspContacts
from dexplan.planning.local.transitions.transfer import TransferStop, densify_poses

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"

_LINK = (
    '<link name="{0}"><collision><geometry><box size="0.01 0.01 0.01"/></geometry>'
    "</collision></link>"
)
_JOINT = (
    '<joint name="{0}" type="{1}"><parent link="{2}"/><child link="{3}"/>'
    '<origin xyz="{4} 0 0"/><axis xyz="0 0 1"/>'
    '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
)


def _robot(finger_joints: int = 2) -> str:
    """A torso with an arm ending in a 2-finger hand (``palm``), and a leg."""
    links = ["torso", "arm", "palm", "leg"]
    joints = [
        _JOINT.format("shoulder", "revolute", "torso", "arm", 0.1),
        _JOINT.format("wrist", "fixed", "arm", "palm", 0.1),
        _JOINT.format("hip", "revolute", "torso", "leg", -0.1),
    ]
    for f in ("a", "b"):
        parent = "palm"
        for k in range(finger_joints):
            links.append(f"{f}{k}")
            joints.append(_JOINT.format(f"{f}_j{k}", "revolute", parent, f"{f}{k}", 0.03))
            parent = f"{f}{k}"
        links.append(f"{f}_tip")
        joints.append(_JOINT.format(f"{f}_tip_joint", "fixed", parent, f"{f}_tip", 0.03))
    body = "".join(_LINK.format(n) for n in links) + "".join(joints)
    return f'<robot name="bot"><material name="grey"/>{body}</robot>'


def test_extract_keeps_the_subtree_below_the_root_link() -> None:
    hand_xml = extract_hand(_robot(), "palm")
    assert "torso" not in hand_xml and "shoulder" not in hand_xml and "hip" not in hand_xml
    hand = Hand(hand_xml, ["a_tip", "b_tip"], 0.005)
    assert hand.joint_names == ("a_j0", "a_j1", "b_j0", "b_j1")
    assert [len(i) for i in hand.finger_q_index] == [2, 2]
    assert '<material name="grey"' in hand_xml  # links may refer to it


def test_extract_refuses_an_unknown_root_link_with_a_hint() -> None:
    with pytest.raises(ModelError, match=r"hand.root_link 'plam' .*did you mean 'palm'"):
        extract_hand(_robot(), "plam")


def test_extract_refuses_a_root_link_without_movable_joints() -> None:
    with pytest.raises(ModelError, match="no movable joint below it"):
        extract_hand(_robot(), "a_tip")


def _robot_scenario(tmp_path: Path, finger_joints: int = 2) -> str:
    (tmp_path / "bot.urdf").write_text(_robot(finger_joints))
    return (
        '[hand]\nurdf = "bot.urdf"\nroot_link = "palm"\n'
        'fingertip_frames = ["a_tip", "b_tip"]\nfingertip_radius = 0.005\n'
        '[object]\nshape = "sphere"\nradius = 0.02\n'
        "[start]\nobject_pose_xyzquat = [0.05, 0, 0.05, 0, 0, 0, 1]\n"
        "[goal]\nobject_pose_xyzquat = [0.05, 0, 0.05, 0, 0, 0, 1]\n"
        '[contact]\nmodel = "soft"\ntorsion = 0.005\n'
    )


def test_planning_refuses_a_one_joint_finger_with_a_clear_message(tmp_path: Path) -> None:
    (tmp_path / "s.toml").write_text(_robot_scenario(tmp_path, finger_joints=1))
    scen = load_scenario(tmp_path / "s.toml")
    hand = Hand.from_spec(scen.hand)  # a hand may have one (its plans can be checked)
    assert [len(i) for i in hand.finger_q_index] == [1, 1]
    with pytest.raises(ScenarioError, match=r"'a_tip' .* moved by 1 joint: dexplan plans for"):
        build_context(scen, hand=hand)


def test_scenario_root_link_extracts_the_hand(tmp_path: Path) -> None:
    text = _robot_scenario(tmp_path)
    (tmp_path / "s.toml").write_text(text)
    scen = load_scenario(tmp_path / "s.toml")
    assert scen.hand.root_link == "palm"
    hand = Hand.from_spec(scen.hand)
    assert hand.nq == 4 and "hip" not in hand.urdf_xml
    (tmp_path / "bad.toml").write_text(text.replace('root_link = "palm"', "root_link = 3"))
    with pytest.raises(ScenarioError, match=r"hand.root_link must be a non-empty string.*got 3"):
        load_scenario(tmp_path / "bad.toml")


@pytest.fixture(scope="module")
def dex3() -> Hand:
    pytest.importorskip("pinocchio")
    try:
        return Hand.builtin("dex3")
    except dexplan.DexplanError as exc:  # example-robot-data not installed
        pytest.skip(str(exc))


def test_dex3_is_the_g1_right_hand_with_two_joint_fingers(dex3: Hand) -> None:
    assert [len(i) for i in dex3.finger_q_index] == [3, 2, 2]
    assert not low_dof(dex3, 0) and low_dof(dex3, 1) and low_dof(dex3, 2)
    assert all(name.startswith("right_hand_") for name in dex3.joint_names)
    assert "left_hand" not in dex3.urdf_xml and "pelvis" not in dex3.urdf_xml


@pytest.mark.parametrize(
    "shape",
    [{"shape": "sphere", "radius": 0.022}, {"shape": "box", "size": [0.05, 0.04, 0.045]}],
)
def test_contact_curve_samples_touch_the_surface_tangentially(dex3: Hand, shape: dict) -> None:
    obj = shape_from_dict(shape)
    pose = np.array([0.09, 0.0, 0.08, 0.0, 0.2588190451, 0.0, 0.9659258263])
    R = quat_to_matrix(pose[3:])
    r = dex3.fingertip_radius
    for finger in (1, 2):
        c = contact_curve_samples(dex3, obj, finger, R, pose[:3], 200, np.random.default_rng(5))
        assert len(c.q) >= 20  # the finger reaches the object along a curve
        idx = dex3.finger_q_index[finger]
        assert np.all((c.q >= dex3.lower[idx]) & (c.q <= dex3.upper[idx]))
        chain = dex3.finger_chain(finger)
        assert chain is not None
        assert np.abs(chain.tips(c.q) - c.tips).max() < 1e-12  # the tips are the joints'
        tip_obj = (c.tips - pose[:3]) @ R
        # distance to the surface is the fingertip radius ...
        sd = np.asarray(obj.signed_distance(tip_obj))
        assert np.abs(sd - r).max() < 1e-6
        # ... and the sphere is tangent there: centre = contact + r * outward normal
        assert np.linalg.norm(tip_obj - (c.points + r * c.normals_out), axis=1).max() < 1e-6
        assert np.abs(np.asarray(obj.signed_distance(c.points))).max() < 1e-6
        # a 2-joint planar finger: the contacts lie in its flexion plane, on a curve
        assert np.ptp(c.tips[:, 1]) < 1e-9


@pytest.fixture(scope="module")
def dex3_context(dex3: Hand):  # type: ignore[no-untyped-def]
    scen = load_scenario(SCENARIOS / "dex3_sphere.toml")
    return scen, build_context(scen, seed=3, hand=dex3)


def test_sampled_grasps_lie_on_gsn(dex3_context) -> None:  # type: ignore[no-untyped-def]
    scen, ctx = dex3_context
    pose = scen.start.object_pose_xyzquat
    states = ctx.sampler.samples_at_pose(pose, 3)
    assert states, ctx.sampler.stats
    for x in states:
        assert ctx.gsn.residual(x) < 1e-6
        assert ctx.validity.is_valid(x)


def test_landings_of_a_two_joint_finger_are_reached(dex3_context) -> None:  # type: ignore[no-untyped-def]
    scen, ctx = dex3_context
    hand, obj = ctx.hand, ctx.obj
    pose = scen.start.object_pose_xyzquat
    future = np.repeat(pose[None], 4, axis=0)
    pool = ctx.transitions.landing_pool(1, pose, future)
    assert pool is not None
    points, normals, _ = pool
    assert len(points) >= 5
    R = quat_to_matrix(pose[3:])
    assert np.abs(np.asarray(obj.signed_distance(points))).max() < 1e-6
    tips = (points + hand.fingertip_radius * normals) @ R.T + pose[:3]
    q, ok = hand.finger_ik_batch(1, tips)
    assert ok.all()
    chain = hand.finger_chain(1)
    assert chain is not None
    assert np.abs(chain.tips(q) - tips).max() < 1e-6


def test_dex3_turns_a_small_sphere_and_the_plan_verifies() -> None:
    scen = load_scenario(SCENARIOS / "dex3_sphere.toml")
    try:
        plan = dexplan.plan(scen, seed=1, quality="none", time_limit=120.0)
    except dexplan.DexplanError as exc:  # example-robot-data not installed
        pytest.skip(str(exc))
    assert plan.solved, plan.status  # solved means the verifier accepted it
    report = verify_plan(plan.to_document("."))
    assert report.ok, [str(v) for v in report.violations[:5]]


def test_gsn_jacobian_and_projection_with_two_joint_fingers(dex3_context) -> None:  # type: ignore[no-untyped-def]
    """One distance row per contact finger holds for any number of joints."""
    scen, ctx = dex3_context
    gsn = ctx.gsn
    x = ctx.sampler.samples_at_pose(scen.start.object_pose_xyzquat, 1)[0]
    J = gsn.jacobian(x)
    assert J.shape == (4, 14)  # 3 distance rows + the quaternion norm; 7 pose + 7 joints
    eps = 1e-7
    fd = np.column_stack(
        [(gsn.function(x + eps * e) - gsn.function(x - eps * e)) / (2 * eps) for e in np.eye(14)]
    )
    np.testing.assert_allclose(J, fd, atol=2e-6, rtol=1e-5)
    # Newton projection of least norm (what OMPL's projected space does) lands on GSn
    y = x + np.random.default_rng(0).normal(0.0, 2e-3, 14)
    for _ in range(20):
        y = y - np.linalg.pinv(gsn.jacobian(y)) @ gsn.function(y)
    assert gsn.residual(y) < 1e-9


@pytest.mark.parametrize("motion", ["fixed", "rolling"])
def test_two_joint_fingers_hold_through_turns_about_their_flexion_axis_only(
    dex3: Hand, motion: str
) -> None:
    """Fixed or rolling, a 2-joint finger follows the object only where its tip can."""
    scen = load_scenario(SCENARIOS / "dex3_sphere.toml")
    scen = dataclasses.replace(scen, contact_motion=ContactMotion(motion))
    ctx = build_context(scen, seed=2, hand=dex3)
    start = scen.start.object_pose_xyzquat
    x = ctx.sampler.samples_at_pose(start, 1)[0]
    q = x[7:]
    R = quat_to_matrix(start[3:])
    points, normals = ctx.obj.closest_point((dex3.fingertip_positions(q) - start[:3]) @ R)
    grasp = GraspContacts(points, normals)

    def turned(axis: list[float], angle: float) -> np.ndarray:
        half = 0.5 * angle
        quat = np.concatenate([np.sin(half) * np.asarray(axis), [np.cos(half)]])
        poses = [np.concatenate([start[:3], slerp(start[3:], quat, s)]) for s in (0, 0.5, 1)]
        return densify_poses(np.array(poses), 0.002, 0.01)

    # a few degrees about the flexion axis (world y): every finger follows
    about_y = ctx.transitions.transfer(turned([0.0, 1.0, 0.0], 0.05), 0, q, grasp)
    assert about_y.reason is None
    # about the vertical: the index or the middle finger cannot follow
    about_z = ctx.transitions.transfer(turned([0.0, 0.0, 1.0], 0.05), 0, q, grasp)
    assert about_z.reason == TransferStop.IK and about_z.blocking in (1, 2)


def test_the_plain_rlg_sampler_places_two_joint_fingers_too(dex3: Hand) -> None:
    scen = load_scenario(SCENARIOS / "dex3_sphere.toml")
    ctx = build_context(scen, seed=4, hand=dex3, sampler_settings=SamplerSettings(per_finger=False))
    # the plain sampler's whole-hand draws rarely place every finger at once
    # (about one valid grasp in 50 draws here): a few rounds of its attempts
    x = None
    for _ in range(4):
        x = x if x is not None else ctx.sampler.sample_at_pose(scen.start.object_pose_xyzquat)
    assert x is not None, ctx.sampler.stats
    assert ctx.gsn.residual(x) < 1e-6 and ctx.validity.is_valid(x)


def test_two_joint_planar_fingers_have_both_elbows_in_closed_form(dex3: Hand) -> None:
    for finger in (1, 2):
        assert dex3.has_closed_form_ik(finger)
        idx = dex3.finger_q_index[finger]
        q_true = np.random.default_rng(7).uniform(dex3.lower[idx], dex3.upper[idx], (300, 2))
        chain = dex3.finger_chain(finger)
        assert chain is not None
        tips = chain.tips(q_true)
        q, ok = dex3.finger_ik_candidates(finger, tips)
        assert q.shape == (300, 2, 2) and ok.any(axis=1).all()
        err = np.linalg.norm(chain.tips(q[ok]) - np.repeat(tips, 2, axis=0)[ok.ravel()], axis=1)
        assert err.max() < 1e-9
        # the posture the target came from is one of the two
        d = np.abs(q - q_true[:, None, :]).max(axis=2)
        assert (np.where(ok, d, np.inf).min(axis=1) < 1e-9).all()
        # a target off the fingertip's plane is not reached, by a little or a lot
        off = tips + np.array([0.0, 1e-6, 0.0])  # the planes are normal to world y
        assert not dex3.finger_ik_candidates(finger, off)[1].any()
        assert dex3.finger_ik_fast(finger, off[0], dex3.neutral) is None


def test_a_two_joint_finger_regrasps_within_its_plane(dex3: Hand) -> None:
    """Lift, move and land a 2-joint finger: only it moves, its tip stays in its plane."""
    scen = load_scenario(SCENARIOS / "dex3_sphere.toml")
    ctx = build_context(scen, seed=1, hand=dex3)
    pose = scen.start.object_pose_xyzquat
    R = quat_to_matrix(pose[3:])
    trans, r = ctx.transitions, dex3.fingertip_radius
    segments = []
    for x in ctx.sampler.samples_at_pose(pose, 2):
        q = x[7:]
        points, normals = ctx.obj.closest_point((dex3.fingertip_positions(q) - pose[:3]) @ R)
        grasp = GraspContacts(points, normals)
        for finger in (1, 2):
            if not trans.can_release(finger, pose, q, grasp):
                continue
            for p, n, _ in trans.landing_candidates(finger, pose, q, grasp, pose[None]):
                seg = trans.regrasp(pose, q, grasp, finger, p, n)
                if seg is not None:
                    segments.append((finger, q, seg, p))
                    break
    assert segments
    for finger, q0, seg, p_new in segments:
        idx = dex3.finger_q_index[finger]
        others = np.setdiff1d(np.arange(dex3.nq), idx)
        qs = np.array([w.q for w in seg.waypoints])
        assert np.abs(qs[:, others] - q0[others]).max() == 0.0  # only the free finger moves
        assert all(np.array_equal(w.object_pose_xyzquat, pose) for w in seg.waypoints)
        tips = np.array([dex3.fingertip_positions(qk)[finger] for qk in qs])
        assert np.ptp(tips[:, 1]) < 1e-9  # in its plane throughout
        sd = np.asarray(ctx.obj.signed_distance((tips - pose[:3]) @ R)) - r
        assert abs(sd[0]) < 1e-6 and abs(sd[-1]) < 1e-6 and sd[1:-1].min() > 0.0
        assert np.allclose(seg.waypoints[-1].contacts[finger], p_new)


@pytest.mark.slow
def test_dex3_turns_the_ball_90_degrees_with_gaits_of_its_two_joint_fingers() -> None:
    scen = load_scenario(SCENARIOS / "dex3_sphere.toml")
    half = np.sqrt(0.5)
    goal = dataclasses.replace(
        scen.goal, object_pose_xyzquat=np.array([0.09, 0.0, 0.08, 0.0, half, 0.0, half])
    )
    scen = dataclasses.replace(scen, goal=goal)
    try:
        plan = dexplan.plan(scen, seed=1, quality="none", time_limit=120.0)
    except dexplan.DexplanError as exc:  # example-robot-data not installed
        pytest.skip(str(exc))
    assert plan.solved, plan.status
    doc = plan.to_document(".")
    report = verify_plan(doc)
    assert report.ok, [str(v) for v in report.violations[:5]]
    moved = {s["finger"] for s in doc["segments"] if s["kind"] == "regrasp"}
    assert moved & {1, 2}  # the index or the middle finger walks


def test_root_link_enters_the_scenario_identity_only_when_given(tmp_path: Path) -> None:
    text = _robot_scenario(tmp_path)
    (tmp_path / "a.toml").write_text(text)
    (tmp_path / "b.toml").write_text(text.replace('root_link = "palm"\n', ""))
    with_root, without = load_scenario(tmp_path / "a.toml"), load_scenario(tmp_path / "b.toml")
    assert scenario_hash(with_root) != scenario_hash(without)
    assert "root_link" not in scenario_description(without)["hand"]
