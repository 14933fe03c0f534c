"""Collision checks on the Allegro hand do not depend on the pair's earlier queries."""

import tomllib
from pathlib import Path

import numpy as np
import pinocchio as pin

from dexplan.model.scenario import parse_scenario
from dexplan.planning.context import build_context

# the index finger's middle phalanx (link_2.0, a box) 2.2 mm inside a 5 cm cube,
# the only index link in it (link_1.0's box 2.5 mm and the distal capsule 1.9 mm
# outside): a box-box pair that coal without contacts (enable_contact = False)
# stopped seeing after it had been queried at other index postures
SCENARIO = """
name = "allegro_box_pair"
[hand]
builtin = "allegro"
[object]
shape = "box"
size = [0.05, 0.05, 0.05]
[start]
object_pose_xyzquat = [-0.01, 0.0, 0.065, 0.0, 0.0, 0.0, 1.0]
[goal]
object_pose_xyzquat = [-0.01, 0.0, 0.065, 0.0, 0.0, 0.0, 1.0]
"""
Q = [-0.0907, 1.3498, 0.4444, 0.8023, 0.971125, 1.12588583, 0.43277299,
     1.54342082, -0.14321378, 0.87593329, 0.65880432, 1.387375, 0.04635972, 1.38010191,
     1.21605445, 0.23425]  # fmt: skip


def test_penetrating_link_is_seen_after_other_queries() -> None:
    ctx = build_context(parse_scenario(tomllib.loads(SCENARIO), Path(".")), seed=1)
    world, hand = ctx.world, ctx.hand
    gm, gd = world.geom_model, world.geom_data
    pose = np.array([-0.01, 0.0, 0.065, 0.0, 0.0, 0.0, 1.0])
    q = np.array(Q)
    mask = (True,) * hand.n_fingers
    idx = hand.finger_q_index[0]

    def hits(q_hand: np.ndarray) -> set[int]:
        """Finger-0 link / object pairs in collision at ``q_hand`` (every pair queried)."""
        world.check(q_hand, pose, mask, first_only=False)
        return {k for k in pairs if gd.collisionResults[k].isCollision()}

    pairs = [
        k
        for k, cp in enumerate(gm.collisionPairs)
        if world.object_geom in (cp.first, cp.second)
        and world.finger_of(world.geometry_name(cp.first)) == 0
        and cp.first not in world.tip_geoms
    ]
    want = hits(q)
    assert {world.geometry_name(gm.collisionPairs[k].first) for k in want} == {"link_2.0"}
    rng = np.random.default_rng(0)
    for _ in range(400):
        other = q.copy()
        other[idx] = rng.uniform(hand.lower[idx], hand.upper[idx])
        world.check(other, pose, mask)  # places the geometries there
        for k in pairs:
            pin.computeCollision(gm, gd, k)
        assert hits(q) == want
