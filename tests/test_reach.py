"""Reach voxels (dexplan.model.hand.reach): reachable fingertip centres inside, far ones out."""

import numpy as np
import pytest

from dexplan.model.hand.hand import Hand


@pytest.mark.parametrize("name", ["paper", "allegro", "three_finger", "trifinger"])
def test_reach_voxels_hold_the_reachable_and_only_near_it(name: str) -> None:
    hand = Hand.builtin(name)
    rng = np.random.default_rng(5)
    for i in range(hand.n_fingers):
        idx = hand.finger_q_index[i]
        voxels = hand.reach_voxels(i)
        assert voxels is hand.reach_voxels(i)  # built once
        # fresh configurations (another seed than the voxels' own), by Pinocchio
        q = np.tile(hand.neutral, (300, 1))
        q[:, idx] = rng.uniform(hand.lower[idx] + 0.02, hand.upper[idx] - 0.02, (300, len(idx)))
        tips = np.array([hand.fingertip_positions(qk)[i] for qk in q])
        assert voxels.contains(tips).mean() >= 0.99
        # farther than any fingertip from the finger's base joint: never inside
        base = hand.joint_origin(int(idx[0]), hand.neutral)
        reach = np.max(np.linalg.norm(tips - base, axis=1))
        d = rng.normal(size=(300, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        far = base + d * (reach + 0.05)
        assert not voxels.contains(far).any()
        assert not voxels.contains(np.array([[10.0, 0.0, 0.0]])).any()


def test_large_workspace_voxels_grow_until_they_hold_fresh_tips() -> None:
    """The TriFinger's lower link turns a full circle: 20,000 samples in 4 mm
    voxels missed half its reachable fingertip centres; grown, the voxels
    miss at most REACH_MISSES of REACH_CHECK fresh ones, the small hands'
    voxels stay 4 mm."""
    from dexplan.model.hand.reach import REACH_VOXEL

    tri = Hand.builtin("trifinger")
    rng = np.random.default_rng(11)
    for i in range(tri.n_fingers):
        idx = tri.finger_q_index[i]
        q = np.tile(tri.neutral, (1000, 1))
        q[:, idx] = rng.uniform(tri.lower[idx] + 0.02, tri.upper[idx] - 0.02, (1000, len(idx)))
        tips = np.array([tri.fingertip_positions(qk)[i] for qk in q])
        assert tri.reach_voxels(i).contains(tips).mean() >= 0.999
        assert tri.reach_voxels(i).size > REACH_VOXEL
    assert Hand.builtin("paper").reach_voxels(0).size == REACH_VOXEL
