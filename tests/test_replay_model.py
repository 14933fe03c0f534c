"""The replay's MuJoCo model is the plan's hand: kinematics, ranges and effort limits."""

import numpy as np
import pytest

from dexplan.model.hand.builtin import BUILTIN_HANDS
from dexplan.model.hand.hand import Hand

mujoco = pytest.importorskip("mujoco")

from dexplan.execution.replay.mjcf import build_mjcf  # noqa: E402

#: What build_mjcf reads of a plan besides its hand: friction, object, start, obstacles.
_DOC = {
    "mu": 0.8,
    "object": {"shape": "sphere", "radius": 0.03},
    "start": {"object_pose_xyzquat": [0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]},
    "obstacles": [],
}


@pytest.mark.parametrize("name", [str(h) for h in BUILTIN_HANDS])
def test_fingertips_ranges_and_limits_equal_pinocchio(name: str) -> None:
    """At random configurations MuJoCo's fingertip spheres sit at Pinocchio's fingertips."""
    hand = Hand.builtin(name)
    xml, tips = build_mjcf(_DOC, hand, mass=0.1, gravity=np.zeros(3))
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    jq = [m.jnt_qposadr[m.joint(n).id] for n in hand.joint_names]
    lo, hi = np.asarray(hand.lower), np.asarray(hand.upper)
    for k, n in enumerate(hand.joint_names):
        assert np.allclose(m.jnt_range[m.joint(n).id], [lo[k], hi[k]])
    effort = np.asarray(hand.model.effortLimit, dtype=float)
    limited = np.isfinite(effort) & (effort > 0)
    for n in hand.joint_names:
        v = hand.model.joints[hand.model.getJointId(n)].idx_v
        if limited[v]:
            assert np.allclose(m.jnt_actfrcrange[m.joint(n).id], [-effort[v], effort[v]])
    rng = np.random.default_rng(0)
    for _ in range(5):
        q = rng.uniform(lo, hi)
        d.qpos[jq] = q
        mujoco.mj_kinematics(m, d)
        sim = np.array([d.geom_xpos[m.geom(f"hand{k}").id] for k in tips])
        assert np.allclose(sim, hand.fingertip_positions(q), atol=1e-6)


@pytest.mark.parametrize("slope_deg", [20.0, 35.0])
def test_an_object_inside_its_friction_cone_does_not_creep(slope_deg: float) -> None:
    """Coulomb friction holds a box on a slope below the friction angle still, as in a grasp.

    MuJoCo's friction is a soft constraint: without its no-slip pass an object
    loaded inside the cone creeps (this box 0.01-0.02 mm in 2 s; the bean held
    by three fingers up to 0.3 mm/s), which the plan's holds do not model.
    """
    tilt = np.radians(slope_deg)
    assert np.tan(tilt) < _DOC["mu"]  # inside the cone: Coulomb says it stays
    quat = [np.sin(tilt / 2), 0.0, 0.0, np.cos(tilt / 2)]  # about x
    up = np.array([0.0, -np.sin(tilt), np.cos(tilt)])
    slab = np.array([0.5, 0.0, 0.0])  # away from the hand
    doc = dict(
        _DOC,
        object={"shape": "box", "size": [0.04, 0.04, 0.04]},
        start={"object_pose_xyzquat": [*(slab + 0.025 * up), *quat]},
        obstacles=[{"shape": "box", "size": [0.2, 0.2, 0.01], "pose_xyzquat": [*slab, *quat]}],
    )
    xml, _ = build_mjcf(doc, Hand.builtin("paper"), mass=0.1, gravity=np.array([0, 0, -9.81]))
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    body = m.body("object").id
    for _ in range(200):  # settle on the slope
        mujoco.mj_step(m, d)
    p0 = d.xpos[body].copy()
    for _ in range(2000):  # 2 s
        mujoco.mj_step(m, d)
    assert np.linalg.norm(d.xpos[body] - p0) < 1e-6
