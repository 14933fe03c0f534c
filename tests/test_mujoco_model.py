"""The replay's MuJoCo model is the planner's hand: same fingertips, same joint ranges.

For every builtin hand, the MJCF that ``dexplan replay`` builds from a plan
file's ``hand`` table is compared with the Pinocchio model the planner used, at
random configurations within the joint limits.
"""

from __future__ import annotations

import numpy as np
import pytest

from dexplan.model.hand.builtin import BUILTIN_HANDS
from dexplan.model.hand.hand import Hand
from dexplan.model.objects.fingertip import TIP_DISTANCE_TOL
from dexplan.planfile.models import hand_from_plan, hand_table

mujoco = pytest.importorskip("mujoco")

from dexplan.execution.replay.mjcf import build_mjcf  # noqa: E402

#: A plan's fields the model needs besides its hand (the paper's sphere, no obstacle).
DOC = {
    "object": {"shape": "sphere", "radius": 0.04},
    "obstacles": [],
    "mu": 0.8,
    "contact_model": "point",
    "start": {"object_pose_xyzquat": [0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0]},
}


def _builtin(name: str) -> Hand:
    try:
        return Hand.builtin(name)
    except Exception as exc:  # the Allegro needs example-robot-data (the `allegro` extra)
        pytest.skip(f"builtin hand {name!r} is not available here: {exc}")


@pytest.mark.parametrize("name", [str(h) for h in BUILTIN_HANDS])
def test_mujoco_fingertips_and_joint_ranges_equal_pinocchios(name: str) -> None:
    planner_hand = _builtin(name)
    plan_hand = hand_from_plan(hand_table(planner_hand))  # what replay reads from the file
    xml, tips = build_mjcf(
        {**DOC, "hand": hand_table(planner_hand)},
        plan_hand,
        mass=0.1,
        gravity=np.array([0.0, 0.0, -9.81]),
    )
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    assert len(tips) == planner_hand.n_fingers

    joints = [m.joint(n) for n in planner_hand.joint_names]
    ranges = np.array([j.range for j in joints])
    np.testing.assert_allclose(ranges[:, 0], planner_hand.lower, atol=1e-9)
    np.testing.assert_allclose(ranges[:, 1], planner_hand.upper, atol=1e-9)
    assert all(j.limited[0] for j in joints)
    ctrl = np.array([m.actuator(f"a_{n}").ctrlrange for n in planner_hand.joint_names])
    np.testing.assert_allclose(ctrl, ranges, atol=1e-9)

    rng = np.random.default_rng(7)
    for _ in range(20):
        q = rng.uniform(planner_hand.lower, planner_hand.upper)
        d.qpos[:] = m.qpos0
        for j, v in zip(joints, q, strict=True):
            d.qpos[j.qposadr[0]] = v
        mujoco.mj_kinematics(m, d)
        p_tip_world = planner_hand.fingertip_positions(q)  # (n, 3) Pinocchio
        for i, g in enumerate(tips):
            p_mj = d.geom(f"hand{g}").xpos  # (3,) the MuJoCo fingertip sphere's centre
            assert np.linalg.norm(p_mj - p_tip_world[i]) < 0.01 * TIP_DISTANCE_TOL, (name, i, q)
            radius = m.geom(f"hand{g}").size[0]
            assert radius == pytest.approx(planner_hand.fingertip_radius, abs=1e-9)
