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
