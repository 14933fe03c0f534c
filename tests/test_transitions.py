"""Local planners: the free finger's capped OMPL fallback in its joint space."""

import itertools

import numpy as np

from dexplan.planning.context import build_context
from dexplan.planning.transitions import TransitionSettings
from dexplan.scenario import default_scenario


def test_blocked_free_finger_move_falls_back_to_ompl() -> None:
    """No via points: moves the straight line cannot make are planned by RRTConnect."""
    scenario = default_scenario()
    ctx = build_context(scenario, seed=3, transition_settings=TransitionSettings(via_points=0))
    x = ctx.sampler.sample_at_pose(scenario.start.object_pose_xyzquat)
    assert x is not None
    pose, q0 = x[:7], x[7:]
    tr, hand = ctx.transitions, ctx.hand
    finger, idx = 0, hand.finger_q_index[0]
    mask = (False, True, True, True)
    rng = np.random.default_rng(0)
    free = []
    while len(free) < 12:
        q = q0.copy()
        q[idx] = rng.uniform(hand.lower[idx], hand.upper[idx])
        if ctx.world.is_free(q, pose, mask):
            free.append(q)
    pairs = itertools.combinations(free, 2)
    blocked = [(a, b) for a, b in pairs if tr._segment_free(a, b, pose, mask) is None][:4]
    assert blocked, "expected free configurations the straight line cannot join"
    found = 0
    for qa, qb in blocked:
        path = tr._joint_move(finger, qa, qb, pose, mask)
        if path is None:
            continue
        found += 1
        np.testing.assert_array_equal(path[0], qa)
        np.testing.assert_array_equal(path[-1], qb)
        qs = np.array(path)
        others = np.setdiff1d(np.arange(hand.nq), idx)
        assert np.all(qs[:, others] == q0[others])  # only the free finger moves
        assert np.max(np.abs(np.diff(qs, axis=0))) <= tr.settings.max_step_rad + 1e-12
        assert all(ctx.world.is_free(q, pose, mask) for q in qs)
        assert np.all(qs >= hand.lower - 1e-12) and np.all(qs <= hand.upper + 1e-12)
    assert found >= 1
    assert tr.stats["transit_planned"] == len(blocked)
    assert tr.stats["transit_planned_found"] == found
