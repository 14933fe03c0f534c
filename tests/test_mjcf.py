"""MJCF hands: Pinocchio's MJCF reader, couplings, effort limits, the [hand] mjcf field."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from cli_contract import assert_bad_input, run_cli

from dexplan.cli import main as cli
from dexplan.core.errors import ModelError
from dexplan.execution.replay.mjcf import build_mjcf
from dexplan.model.hand.hand import Hand
from dexplan.model.hand.mjcf import mjcf_hand
from dexplan.model.hand.packages import python_package_dirs
from dexplan.model.scenario.scenario import load_scenario
from dexplan.model.scenario.spec import HandSpec
from dexplan.planfile.models import hand_from_plan

REPO = Path(__file__).resolve().parent.parent
SHADOW = REPO / "scenarios" / "shadow_sphere.toml"
needs_shadow = pytest.mark.skipif(
    "gymnasium_robotics" not in python_package_dirs(),
    reason="the Shadow hand's MJCF comes with gymnasium-robotics (extra 'hands')",
)

# Two 3-joint fingers on a box palm under a wrist joint; {extra} goes into
# <mujoco> (tendons, equalities), {act3} decides whether j3 is driven.
HAND = """<mujoco model="two_finger">
  <compiler angle="radian"/>
  <default><geom contype="1" conaffinity="1"/></default>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 0.1" pos="0 0 -0.2"/>
    <body name="mount" pos="0.1 0.2 0.3" euler="0.3 0 0.2">
      <joint name="wrist" type="hinge" axis="0 0 1" range="-0.5 0.5"/>
      <geom name="mount" type="box" size="0.01 0.01 0.01"/>
      <body name="palm" pos="0 0 0.02">
        <geom name="palm" type="box" size="0.04 0.02 0.005"/>
        {fingers}
      </body>
    </body>
  </worldbody>
  <actuator>{actuators}</actuator>
  {extra}
</mujoco>
"""
FINGER = """<body name="{f}1" pos="{x} 0 0.01">
  <joint name="{f}_j1" type="hinge" axis="0 1 0" range="-0.8 0.8"/>
  <geom type="capsule" pos="0 0 0.02" size="0.008 0.02"/>
  <body name="{f}2" pos="0 0 0.04">
    <joint name="{f}_j2" type="hinge" axis="1 0 0" range="0 1.5"/>
    <geom type="capsule" pos="0 0 0.015" size="0.008 0.015"/>
    <body name="{f}3" pos="0 0 0.03">
      <joint name="{f}_j3" type="hinge" axis="1 0 0" range="0 1.5"/>
      <geom type="capsule" pos="0 0 0.01" size="0.008 0.01"/>
      <site name="{f}_tip" pos="0 0 0.022"/>
    </body>
  </body>
</body>"""
TENDON = """<tendon><fixed name="couple" range="-0.001 0.001">
  <joint joint="a_j3" coef="0.007"/><joint joint="a_j2" coef="-0.008"/>
</fixed></tendon>"""


def write_hand(tmp_path: Path, extra: str = "", act3: bool = False) -> Path:
    fingers = "\n".join(FINGER.format(f=f, x=x) for f, x in (("a", 0.025), ("b", -0.025)))
    joints = [f"{f}_j{k}" for f in "ab" for k in (1, 2, 3) if k < 3 or act3]
    actuators = "".join(
        f'<position joint="{j}" kp="1" forcerange="-0.5 0.5" gear="2"/>' for j in joints
    )
    path = tmp_path / "two_finger.xml"
    path.write_text(HAND.format(fingers=fingers, actuators=actuators, extra=extra))
    return path


def build(path: Path, locked: dict[str, float] | None = None) -> Hand:
    m = mjcf_hand(path, ["a_tip", "b_tip"], locked, name="two_finger")
    return Hand(m.urdf_xml, ["a_tip", "b_tip"], 0.008, collision_exclude=m.collision_exclude)


# ---------------------------------------------------------------- loading
def test_joints_limits_efforts_and_palm_frame(tmp_path) -> None:
    hand = build(write_hand(tmp_path, act3=True))
    # the wrist (above the palm, shared by both fingers) is locked
    assert hand.joint_names == ("a_j1", "a_j2", "a_j3", "b_j1", "b_j2", "b_j3")
    np.testing.assert_allclose(hand.lower, [-0.8, 0, 0] * 2)
    np.testing.assert_allclose(hand.upper, [0.8, 1.5, 1.5] * 2)
    # |gear| * max|forcerange|
    np.testing.assert_allclose(hand.model.effortLimit, 1.0)
    # the palm's frame is the world frame: finger a's tip straight up from (0.025, 0, 0.01)
    np.testing.assert_allclose(
        hand.fingertip_positions(np.zeros(6))[0],
        [0.025, 0.0, 0.01 + 0.04 + 0.03 + 0.022],
        atol=1e-12,
    )


def test_fingertip_positions_match_mujoco(tmp_path) -> None:
    mujoco = pytest.importorskip("mujoco")
    path = write_hand(tmp_path, act3=True)
    hand = build(path)
    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    rng = np.random.default_rng(0)
    palm = m.body("palm").id
    for _ in range(5):
        q = rng.uniform(hand.lower, hand.upper)
        d.qpos[:] = 0.0
        for k, name in enumerate(hand.joint_names):
            d.qpos[m.joint(name).qposadr] = q[k]
        mujoco.mj_kinematics(m, d)
        R, p = d.xmat[palm].reshape(3, 3), d.xpos[palm]
        tips = [R.T @ (d.site_xpos[m.site(t).id] - p) for t in ("a_tip", "b_tip")]
        np.testing.assert_allclose(hand.fingertip_positions(q), tips, atol=1e-12)


def test_collision_geoms_and_filters(tmp_path) -> None:
    hand = build(write_hand(tmp_path, act3=True))
    # capsules of the 6 finger links, the palm and the mount box; no floor; two tip spheres
    names = [go.name for go in hand.geom_model.geometryObjects]
    assert len(names) == 10 and not any("floor" in n for n in names)


def test_fingertips_on_bodies_and_spheres_read_from_the_mjcf(tmp_path) -> None:
    path = write_hand(tmp_path, act3=True)
    m = mjcf_hand(path, ["a3", "b3"])  # bodies as fingertip frames
    hand = Hand(m.urdf_xml, ["a3", "b3"], 0.008, collision_exclude=m.collision_exclude)
    np.testing.assert_allclose(
        hand.fingertip_positions(np.zeros(6))[1], [-0.025, 0.0, 0.08], atol=1e-12
    )
    # a sphere geom centred on the tip site is the fingertip: its radius is read
    text = path.read_text().replace(
        '<site name="a_tip"', '<geom type="sphere" size="0.009" pos="0 0 0.022"/><site name="a_tip"'
    )
    text = text.replace(
        '<site name="b_tip"', '<geom type="sphere" size="0.009" pos="0 0 0.022"/><site name="b_tip"'
    )
    path.write_text(text)
    m = mjcf_hand(path, ["a_tip", "b_tip"])
    hand = Hand(m.urdf_xml, ["a_tip", "b_tip"], None, collision_exclude=m.collision_exclude)
    assert hand.fingertip_radius == pytest.approx(0.009)
    with pytest.raises(ModelError, match="disagrees"):
        Hand(m.urdf_xml, ["a_tip", "b_tip"], 0.01, collision_exclude=m.collision_exclude)


def test_effort_limits_override_the_actuators(tmp_path) -> None:
    path = write_hand(tmp_path, act3=True)
    spec = HandSpec(
        builtin=None,
        mjcf=path,
        fingertip_frames=("a_tip", "b_tip"),
        fingertip_radius=0.008,
        effort_limits={"a_j1": 0.25},
    )
    hand = Hand.from_spec(spec)
    assert hand.model.effortLimit[0] == pytest.approx(0.25)
    assert hand.model.effortLimit[1] == pytest.approx(1.0)  # the actuator's


# --------------------------------------------------------------- couplings
def test_a_passive_joint_tendon_coupled_to_a_driven_one_follows_it(tmp_path) -> None:
    hand = build(write_hand(tmp_path, TENDON))
    assert "a_j3" not in hand.joint_names and hand.nq == 5
    mim = hand.mimic_joints["a_j3"]
    assert mim.primary == "a_j2" and mim.multiplier == pytest.approx(0.008 / 0.007)
    # the driven joint's range keeps the follower within its own (1.5 / 1.143)
    assert hand.upper[hand.joint_names.index("a_j2")] == pytest.approx(1.5 * 0.007 / 0.008)
    # one value moves both joints: the tip is where the two angles put it
    q = np.zeros(5)
    q[1] = 0.4  # a_j2
    a2, a3 = 0.4, 0.4 * 0.008 / 0.007
    expected = (
        np.array([0.025, 0.0, 0.05])
        + np.array([0.0, -np.sin(a2), np.cos(a2)]) * 0.03
        + np.array([0.0, -np.sin(a2 + a3), np.cos(a2 + a3)]) * 0.022
    )
    np.testing.assert_allclose(hand.fingertip_positions(q)[0], expected, atol=1e-12)


def test_the_vectorised_chain_of_a_coupled_finger_matches_pinocchio(tmp_path) -> None:
    hand = build(write_hand(tmp_path, TENDON))
    chain = hand.finger_chain(0)
    assert chain is not None and chain.coupled and (chain.m, chain.n_joints) == (2, 3)
    q = np.random.default_rng(0).uniform(hand.lower, hand.upper, size=(4, hand.nq))
    tips, jac = chain.jacobian(q[:, hand.finger_q_index[0]])
    for k in range(4):
        p, J = hand.fingertip_jacobians(q[k])
        np.testing.assert_allclose(tips[k], p[0], atol=1e-12)
        np.testing.assert_allclose(jac[k], J[0], atol=1e-12)
    # every IK solution of the coupled finger puts the tip on its target
    q_ik, ok = hand.finger_ik_candidates(0, tips)
    assert ok.any(axis=1).all()
    np.testing.assert_allclose(chain.tips(q_ik[ok]), np.repeat(tips, ok.sum(axis=1), 0), atol=1e-6)


def test_a_coupling_of_two_driven_joints_is_refused_naming_it(tmp_path) -> None:
    with pytest.raises(ModelError, match=r"fixed tendon 'couple'.*locked_joints") as err:
        build(write_hand(tmp_path, TENDON, act3=True))
    assert "\n" not in str(err.value)


def test_locking_one_joint_narrows_the_other(tmp_path) -> None:
    hand = build(write_hand(tmp_path, TENDON, act3=True), {"a_j3": 0.7})
    assert "a_j3" not in hand.joint_names
    k = hand.joint_names.index("a_j2")
    # 0.007 * 0.7 - 0.008 q in [-0.001, 0.001]
    assert hand.lower[k] == pytest.approx((0.0049 - 0.001) / 0.008)
    assert hand.upper[k] == pytest.approx((0.0049 + 0.001) / 0.008)


def test_joint_equality_is_one_degree_of_freedom(tmp_path) -> None:
    eq = '<equality><joint joint1="b_j3" joint2="b_j2" polycoef="0.1 0.5 0 0 0"/></equality>'
    hand = build(write_hand(tmp_path, eq, act3=True))
    mim = hand.mimic_joints["b_j3"]
    assert (mim.primary, mim.multiplier, mim.offset) == ("b_j2", 0.5, 0.1)
    nonlinear = eq.replace("0.1 0.5 0 0 0", "0 0.5 0.2 0 0")
    with pytest.raises(ModelError, match="joint equality"):
        build(write_hand(tmp_path, nonlinear, act3=True))


def test_closed_loops_and_bad_locks_are_refused(tmp_path) -> None:
    loop = '<equality><connect body1="a3" body2="b3" anchor="0 0 0"/></equality>'
    with pytest.raises(ModelError, match="connect"):
        build(write_hand(tmp_path, loop, act3=True))
    path = write_hand(tmp_path, act3=True)
    with pytest.raises(ModelError, match="unknown joint 'a_j9'"):
        build(path, {"a_j9": 0.0})
    with pytest.raises(ModelError, match=r"locked_joints\['a_j2'\] = 3.0 is outside"):
        build(path, {"a_j2": 3.0})
    with pytest.raises(ModelError, match="unknown fingertip frame 'c_tip'"):
        mjcf_hand(path, ["a_tip", "c_tip"])


# ------------------------------------------------------------- the scenario
MJCF_SCENARIO = """
[hand]
mjcf = "two_finger.xml"
fingertip_frames = ["a_tip", "b_tip"]
fingertip_radius = 0.008
{extra}
[object]
shape = "sphere"
radius = 0.02
[start]
object_pose_xyzquat = [0.0, -0.03, 0.1, 0.0, 0.0, 0.0, 1.0]
[goal]
object_pose_xyzquat = [0.0, -0.03, 0.1, 0.0, 0.0, 0.0, 1.0]
"""


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ('mjcf = "missing.xml"', "hand.mjcf file not found"),
        ('urdf = "x.urdf"', "hand.urdf (= 'x.urdf') and hand.mjcf"),
        ('package_dirs = ["."]', "hand.package_dirs (= ['.']) is only used with hand.urdf"),
        ("locked_joint = {}", "did you mean 'locked_joints'"),
        ('locked_joints = { a_j1 = "x" }', "hand.locked_joints.a_j1"),
        ("locked_joints = { a_j1 = 9.0 }", "locked_joints['a_j1'] = 9.0 is outside"),
    ],
)
def test_bad_fields_are_one_line_errors_exit_2(tmp_path, capfd, extra, message) -> None:
    write_hand(tmp_path, act3=True)
    text = MJCF_SCENARIO.format(extra=extra)
    if extra.startswith("mjcf"):
        text = text.replace('mjcf = "two_finger.xml"\n', "")
    (tmp_path / "s.toml").write_text(text)
    code, _, err = run_cli(capfd, "plan", str(tmp_path / "s.toml"), "-o", str(tmp_path / "p"))
    assert_bad_input(code, err, names=[message], outputs=[tmp_path / "p"])


def test_a_missing_package_names_the_extra(tmp_path) -> None:
    (tmp_path / "s.toml").write_text(
        MJCF_SCENARIO.format(extra="").replace(
            '"two_finger.xml"', '"package://no_such_package/hand.xml"'
        )
    )
    with pytest.raises(Exception, match=r"'package://no_such_package/hand\.xml' not found"):
        load_scenario(tmp_path / "s.toml")


# ---------------------------------------------------------- the Shadow hand
@needs_shadow
def test_shadow_hand_loads_as_the_mjcf_says() -> None:
    mujoco = pytest.importorskip("mujoco")
    scenario = load_scenario(SHADOW)
    hand = Hand.from_spec(scenario.hand)
    fingers = ("FF", "RF")
    own = [f"robot0:{f}J{k}" for f in fingers for k in (3, 2, 1)]
    own += [f"robot0:THJ{k}" for k in (4, 3, 2, 1, 0)]
    assert hand.joint_names == tuple(own)
    m = mujoco.MjModel.from_xml_path(str(scenario.hand.mjcf))
    for k, name in enumerate(hand.joint_names):
        lo, hi = m.jnt_range[m.joint(name).id]
        if name.endswith("J1") and not name.startswith("robot0:TH"):
            hi = 1.571 * 0.00705 / 0.00805  # the distal joint follows it within its range
        assert (hand.lower[k], hand.upper[k]) == pytest.approx((lo, hi)), name
        act = m.actuator(f"robot0:A_{name.split(':')[1]}")
        assert hand.model.effortLimit[k] == pytest.approx(act.forcerange[1]), name
    # visual meshes for the viewer, every mesh named by its wheel's package:// URI
    assert "<visual>" in hand.urdf_xml and "package://gymnasium_robotics/" in hand.urdf_xml
    assert "/site-packages/" not in hand.urdf_xml
    for f in fingers:
        mim = hand.mimic_joints[f"robot0:{f}J0"]
        assert mim.primary == f"robot0:{f}J1"
        assert mim.multiplier == pytest.approx(0.00805 / 0.00705)
    # tip sites where MuJoCo puts them, the distal joint at its coupled value
    d = mujoco.MjData(m)
    q = np.random.default_rng(1).uniform(hand.lower, hand.upper)
    for k, name in enumerate(hand.joint_names):
        d.qpos[m.joint(name).qposadr] = q[k]
    for name, mim in hand.mimic_joints.items():
        d.qpos[m.joint(name).qposadr] = mim.multiplier * q[hand.joint_names.index(mim.primary)]
    mujoco.mj_kinematics(m, d)
    palm = m.body("robot0:palm").id
    R, p = d.xmat[palm].reshape(3, 3), d.xpos[palm]
    tips = [R.T @ (d.site_xpos[m.site(t).id] - p) for t in hand.fingertip_frames]
    np.testing.assert_allclose(hand.fingertip_positions(q), tips, atol=1e-12)


@pytest.fixture(scope="module")
def shadow_plan(tmp_path_factory) -> Path:
    plan = tmp_path_factory.mktemp("shadow") / "plan.json"
    assert cli.run(["plan", str(SHADOW), "--seed", "1", "-o", str(plan), "-q"]) == 0
    return plan


@needs_shadow
def test_shadow_plan_verifies_from_the_file_alone(shadow_plan, capfd) -> None:
    doc = json.loads(shadow_plan.read_text())
    # the plan carries the exported URDF, its coupled joints as <mimic> joints
    assert "<mimic" in doc["hand"]["urdf_xml"] and "robot0:FFJ0" not in doc["hand"]["joint_names"]
    code, out, err = run_cli(capfd, "verify", str(shadow_plan))
    assert code == 0 and "0 violations" in out, out + err


@needs_shadow
@pytest.mark.slow
def test_shadow_plan_exports_and_replays_coupled(shadow_plan, tmp_path, capfd) -> None:
    code, out, err = run_cli(capfd, "export", str(shadow_plan), "-o", str(tmp_path / "t.json"))
    assert code == 0 and "limits check: OK" in out, out + err
    # the replay's MuJoCo model couples the two joints of each coupled finger
    mujoco = pytest.importorskip("mujoco")
    doc = json.loads(shadow_plan.read_text())
    hand = hand_from_plan(doc["hand"])
    xml, _ = build_mjcf(doc, hand, mass=0.1, gravity=np.zeros(3), base_dir=tmp_path)
    m = mujoco.MjModel.from_xml_string(xml)
    assert m.neq == len(hand.mimic_joints) == 2
