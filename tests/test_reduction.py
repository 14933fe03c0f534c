"""The reduction property edge by edge (bisection) and the planner's reduction choice."""

import copy
import dataclasses
import itertools

import numpy as np
import pytest

from dexplan.core.errors import InvalidInputError
from dexplan.core.pose import inverse_transform_points, quat_angle
from dexplan.model.grasp.rolling import ContactMotion
from dexplan.model.scenario import builtin_scenario_path, default_scenario, load_scenario
from dexplan.planfile import build_plan_document, verify_plan
from dexplan.planning.context import build_context, build_hand
from dexplan.planning.gsn.space import POSE_DIM
from dexplan.planning.local.edge_reduction import reduce_gsn_path
from dexplan.planning.local.gait_choice import GaitSettings
from dexplan.planning.local.grasps import grasp_from_state
from dexplan.planning.local.reduction import ReductionSettings
from dexplan.planning.local.transitions import densify_poses
from dexplan.planning.planner import plan
from dexplan.planning.start import start_state


@pytest.fixture(scope="module")
def scenario():
    """The builtin scenario with the paper's fixed contacts: the edge-by-edge reduction's model."""
    return dataclasses.replace(default_scenario(), contact_motion=ContactMotion.FIXED)


@pytest.fixture(scope="module")
def start_and_goal(scenario):
    """A start state and a valid GSn state at the goal pose (180 degrees away)."""
    ctx = build_context(scenario, seed=1)
    x0 = start_state(ctx, candidates=1)  # the first sampled grasp
    xg = ctx.sampler.sample_at_pose(scenario.goal.object_pose_xyzquat)
    assert x0 is not None and xg is not None
    return x0, xg


def _grasps(ctx, states):
    return [grasp_from_state(ctx.transitions, x[:POSE_DIM], x[POSE_DIM:]) for x in states]


def test_edge_reduction_plan_passes_verify(scenario) -> None:
    result = plan(scenario, seed=1, reduction="edges", time_limit=300.0)
    assert result.solved, (result.status, result.message)
    assert result.stats.reduction_method == "edges"
    kinds = [s.kind for s in result.segments]
    assert "regrasp" in kinds and "transfer" in kinds
    # transfers on one grasp across several GSn edges are merged into one
    assert not any(a == b == "transfer" for a, b in itertools.pairwise(kinds))
    for seg in result.segments:
        if seg.kind == "transfer":  # contacts fixed in the object frame
            first = np.array(seg.waypoints[0].contacts)
            assert all(np.allclose(np.array(w.contacts), first) for w in seg.waypoints)
    doc = build_plan_document(scenario, build_hand(scenario), result)
    report = verify_plan(doc)
    assert report.ok, [str(v) for v in report.violations[:5]]


def test_one_long_edge_needs_bisection(scenario, start_and_goal) -> None:
    """A single 180-degree GSn edge: no transfer/regrasp sequence does it whole."""
    x0, xg = start_and_goal
    poses = np.stack([x0[:POSE_DIM], xg[:POSE_DIM]])
    ctx = build_context(scenario, seed=1)
    grasps = _grasps(ctx, [x0, xg])
    flat = reduce_gsn_path(
        ctx.transitions, poses, grasps, x0[POSE_DIM:], ReductionSettings(max_depth=0)
    )
    assert not flat.success
    assert flat.reached == 0
    assert "resolution limit" in flat.reason and "edge 0 -> 1" in flat.reason
    assert flat.stats["reduction_bisections"] == 0

    ctx = build_context(scenario, seed=1)
    red = reduce_gsn_path(ctx.transitions, poses, grasps, x0[POSE_DIM:])
    assert red.success, red.reason
    assert red.stats["reduction_bisections"] >= 1
    assert red.stats["reduction_regrasps"] >= 1
    end = red.segments[-1].end
    np.testing.assert_allclose(end.object_pose_xyzquat, poses[-1], atol=1e-12)
    # every regrasp moves one finger and keeps the object still
    for seg in red.segments:
        if seg.kind == "regrasp":
            poses_seg = np.array([w.object_pose_xyzquat for w in seg.waypoints])
            assert np.ptp(poses_seg, axis=0).max() == 0.0
            moved = np.ptp(np.array([w.q for w in seg.waypoints]), axis=0) > 0
            assert set(np.flatnonzero(moved)) <= set(ctx.hand.finger_q_index[seg.finger])


def test_short_edge_is_one_transfer(scenario, start_and_goal) -> None:
    x0, _ = start_and_goal
    ctx = build_context(scenario, seed=1)
    pose1 = x0[:POSE_DIM].copy()
    pose1[2] += 0.004  # lift the object 4 mm: the grasp follows
    g0 = _grasps(ctx, [x0])[0]
    res = reduce_gsn_path(
        ctx.transitions, np.stack([x0[:POSE_DIM], pose1]), [g0, g0], x0[POSE_DIM:]
    )
    assert res.success, res.reason
    assert [s.kind for s in res.segments] == ["transfer"]
    end = res.segments[-1].end
    np.testing.assert_allclose(end.object_pose_xyzquat, pose1, atol=1e-12)
    tips = ctx.hand.fingertip_positions(end.q)
    np.testing.assert_allclose(tips, ctx.transitions.tip_targets(pose1, g0), atol=1e-4)


def test_bisected_edges_reach_the_goal(scenario) -> None:
    """A coarse GSn path (every 4th state): bisection recovers the missing states."""
    ctx = build_context(scenario, seed=3)
    res = plan(scenario, seed=3, reduction="gaits", time_limit=300.0)
    assert res.gsn_path.shape[0] >= 3
    states = res.gsn_path[::4]
    if not np.array_equal(states[-1], res.gsn_path[-1]):
        states = np.vstack([states, res.gsn_path[-1:]])
    poses = states[:, :POSE_DIM].copy()
    poses[:, 3:] /= np.linalg.norm(poses[:, 3:], axis=1, keepdims=True)
    red = reduce_gsn_path(ctx.transitions, poses, _grasps(ctx, states), states[0, POSE_DIM:])
    assert red.success, red.reason
    end = red.segments[-1].end.object_pose_xyzquat
    assert quat_angle(end[3:], poses[-1, 3:]) < 1e-9
    assert np.linalg.norm(end[:3] - poses[-1, :3]) < 1e-12


def test_bad_reduction_name_is_an_input_error(scenario) -> None:
    with pytest.raises(InvalidInputError, match="reduction must be one of"):
        plan(scenario, reduction="magic")


def test_mismatched_contacts_is_an_input_error(scenario, start_and_goal) -> None:
    x0, _ = start_and_goal
    ctx = build_context(scenario, seed=1)
    with pytest.raises(InvalidInputError, match="2 poses but 1 contact sets"):
        reduce_gsn_path(
            ctx.transitions, np.stack([x0[:POSE_DIM]] * 2), _grasps(ctx, [x0]), x0[POSE_DIM:]
        )


def _contacts_off_the_fingertip(hand, ctx, result) -> list[tuple[int, int, int]]:
    """(segment, waypoint, finger) where the stated contact is not under the fingertip."""
    r = hand.fingertip_radius
    out = []
    for si, seg in enumerate(result.segments):
        for wi, w in enumerate(seg.waypoints):
            tips = inverse_transform_points(w.object_pose_xyzquat, hand.fingertip_positions(w.q))
            for i, c in enumerate(w.contacts):
                if c is None:
                    continue
                p, n = ctx.obj.closest_point(np.asarray(c))
                if np.linalg.norm(np.asarray(p) + r * np.asarray(n) - tips[i]) > 1e-3:
                    out.append((si, wi, i))
    return out


def test_fingertips_on_box_edges_are_verified_contacts() -> None:
    """GSn lets a fingertip roll over a box edge; such plans verify, a moved contact not.

    The first of seeds 1-12 whose edge-by-edge plan has a fingertip on a box
    edge is checked (seed 1 today: the search stops there); none having one
    fails the test.
    """
    scenario = load_scenario(builtin_scenario_path("cube_obstacle"))
    hand = build_hand(scenario)
    ctx = build_context(scenario)
    outcomes = []
    for seed in range(1, 13):
        result = plan(scenario, planner="KPIECE1", seed=seed, reduction="edges", time_limit=300.0)
        on_edge = _contacts_off_the_fingertip(hand, ctx, result) if result.solved else []
        outcomes.append((seed, result.status, len(on_edge)))
        if on_edge:
            break
    assert on_edge, f"expected a solved plan with a fingertip on a box edge: {outcomes}"
    doc = build_plan_document(scenario, hand, result)
    report = verify_plan(doc)
    assert report.ok, [str(v) for v in report.violations[:5]]
    si, wi, i = on_edge[0]
    bad = copy.deepcopy(doc)
    c = bad["segments"][si]["waypoints"][wi]["contacts"][i]
    c[2] += 0.004  # move the stated contact 4 mm
    rules = {v.rule for v in verify_plan(bad).violations}
    assert "contact_matches_fingertip" in rules


@pytest.mark.parametrize(("retries", "backtracks"), [(0, 0), (2, 0), (2, 3)])
def test_failed_regrasp_search_is_retried_before_giving_up(
    scenario, start_and_goal, monkeypatch, retries: int, backtracks: int
) -> None:
    """A regrasp search that finds nothing runs again ``regrasp_retries`` times, then the
    gaits go back ``backtracks`` times (to the latest checkpoint: ``backtrack_steps`` 0)."""
    from dexplan.planning.local import reduction
    from dexplan.planning.local.transitions import densify_poses

    x0, xg = start_and_goal
    ctx = build_context(scenario, seed=1)
    calls: list[int] = []

    def nothing(*args, **kwargs):
        calls.append(1)
        return None

    monkeypatch.setattr(reduction, "_regrasp_one", nothing)
    s = ctx.transitions.settings
    dense = densify_poses(np.stack([x0[:POSE_DIM], xg[:POSE_DIM]]), s.max_step_m, s.max_step_rad)
    grasp = grasp_from_state(ctx.transitions, x0[:POSE_DIM], x0[POSE_DIM:])
    red = reduction.reduce_object_path(
        ctx.transitions,
        dense,
        x0[POSE_DIM:],
        grasp,
        # backtrack_steps=0: go back even when stuck within the first steps
        ReductionSettings(
            regrasp_retries=retries,
            backtracks=backtracks,
            backtrack_steps=0,
            gaits=GaitSettings(beam_width=0),  # the one-regrasp-at-a-time reduction
        ),
    )
    assert not red.success
    assert red.reason is not None and red.reason.startswith("no feasible regrasp")
    assert len(calls) == (1 + retries) * (1 + backtracks)
    assert red.stats["backtracks"] == backtracks


def test_blocked_finger_without_landing_moves_a_neighbour_that_gives_it_one(
    monkeypatch,
) -> None:
    """The look-ahead: with no landing of its own, the blocking finger waits for a
    neighbour's move after which it has one (``can_land``), before any move at all."""
    from dexplan.planning.local import reduction

    scenario = load_scenario(builtin_scenario_path("cube_obstacle"))
    ctx = build_context(scenario, seed=1)
    trans = ctx.transitions
    x0 = start_state(ctx)
    assert x0 is not None
    pose0 = x0[:POSE_DIM]
    grasp = grasp_from_state(trans, pose0, x0[POSE_DIM:])
    goal = scenario.goal.object_pose_xyzquat
    poses = densify_poses(np.stack([pose0, goal]), 0.008, 0.04)
    blocking = 0
    landings = trans.landing_candidates

    def none_for_the_blocking_finger(finger, *args, **kwargs):
        if finger == blocking:
            return iter(())
        return landings(finger, *args, **kwargs)

    verdicts: list[tuple[bytes, bool]] = []
    can_land = trans.can_land

    def recorded(finger, q, g, pool, future, **kwargs):
        ok = can_land(finger, q, g, pool, future, **kwargs)
        verdicts.append((g.points.tobytes(), ok))
        return ok

    monkeypatch.setattr(trans, "landing_candidates", none_for_the_blocking_finger)
    monkeypatch.setattr(trans, "can_land", recorded)
    # no neighbour could follow further on another contact: only the look-ahead moves one
    monkeypatch.setattr(reduction, "current_follow", lambda *a: len(poses) + 10)
    found = reduction._regrasp_one(
        trans, poses, 0, x0[POSE_DIM:], grasp, blocking, None, reduction.GaitSettings()
    )
    assert verdicts, "the look-ahead was not consulted"
    assert found is not None
    seg, new, mode, _ = found
    assert mode == "enable"
    assert seg.finger != blocking
    approved = {key for key, ok in verdicts if ok}
    # the moved neighbour is one the look-ahead approved (this start grasp has one)
    assert new.points.tobytes() in approved, (len(verdicts), len(approved))


@pytest.mark.parametrize("mode", ["any", "gain"])
def test_moves_that_give_the_blocking_finger_nothing_end_the_attempt(
    scenario, start_and_goal, monkeypatch, mode: str
) -> None:
    """``max_blind`` moves of other fingers without a landing for the blocking one
    end the attempt (the planner retries afresh); other regrasps count towards
    ``max_stall`` only."""
    from dexplan.core.segments import Segment, Waypoint
    from dexplan.planning.local import reduction

    x0, xg = start_and_goal
    ctx = build_context(scenario, seed=1)
    calls: list[int] = []

    def idle(trans, poses, idx, q, grasp, *args):
        # a regrasp that changes nothing: the transfer stays blocked where it was
        calls.append(idx)
        w = Waypoint(poses[idx].copy(), q.copy(), grasp.as_tuple())
        return Segment("regrasp", 1, (w, w)), grasp, mode, None

    monkeypatch.setattr(reduction, "_regrasp_retrying", idle)
    s = ctx.transitions.settings
    dense = densify_poses(np.stack([x0[:POSE_DIM], xg[:POSE_DIM]]), s.max_step_m, s.max_step_rad)
    grasp = grasp_from_state(ctx.transitions, x0[:POSE_DIM], x0[POSE_DIM:])
    settings = ReductionSettings(
        max_blind=3, max_stall=7, backtracks=0, gaits=GaitSettings(beam_width=0)
    )
    red = reduction.reduce_object_path(ctx.transitions, dense, x0[POSE_DIM:], grasp, settings)
    assert not red.success and red.reason is not None
    assert len(set(calls)) == 1  # all at the step the transfer was blocked at
    if mode == "any":
        assert red.reason.startswith("no landing for finger") and len(calls) == 4
    else:
        assert red.reason.startswith("no progress after") and len(calls) == 8
    # with backtracks, each run of them starts again from the last checkpoint
    calls.clear()
    settings = ReductionSettings(
        max_blind=3, max_stall=7, backtracks=2, backtrack_steps=0, gaits=GaitSettings(beam_width=0)
    )
    red = reduction.reduce_object_path(ctx.transitions, dense, x0[POSE_DIM:], grasp, settings)
    assert not red.success and red.stats["backtracks"] == 2
    assert len(calls) == 3 * (4 if mode == "any" else 8)


def test_reduction_schedule_retries_gaits_until_no_trajectory_is_left() -> None:
    """After the fixed attempts, gaits again (fresh landings) while some
    trajectory is not hopeless; the planner stops the schedule at its deadline."""
    from dexplan.planning.planner import _reduction_schedule

    assert list(_reduction_schedule("edges", set())) == [("edges", "gsn")]
    hopeless: set[str] = set()
    schedule = _reduction_schedule("auto", hopeless)
    fixed = list(itertools.islice(schedule, 5))
    assert fixed[4] == ("edges", "gsn")
    assert {m for m, _ in fixed[:4]} == {"gaits"}
    more = list(itertools.islice(schedule, 40))
    assert len(more) == 40 and set(more) == {("gaits", "shortcut"), ("gaits", "raw")}
    hopeless.add("raw")
    assert next(schedule) in {("gaits", "shortcut"), ("gaits", "raw")}
    hopeless.add("shortcut")
    assert len(list(itertools.islice(schedule, 3))) <= 1  # ends with the pair under way


def test_stuck_gaits_go_back_to_an_earlier_transfer_and_carry_on(
    scenario, start_and_goal, monkeypatch
) -> None:
    """A regrasp search that finds nothing once: the gaits resume from an earlier checkpoint."""
    from dexplan.planning.local import reduction as red_mod
    from dexplan.planning.local.reduction import reduce_object_path

    x0, _ = start_and_goal
    ctx = build_context(scenario, seed=1)
    s = ctx.transitions.settings
    poses = densify_poses(
        np.stack([x0[:POSE_DIM], scenario.goal.object_pose_xyzquat]), s.max_step_m, s.max_step_rad
    )
    grasp = grasp_from_state(ctx.transitions, x0[:POSE_DIM], x0[POSE_DIM:])
    real = red_mod._regrasp_retrying
    blocked: list[int] = []

    def fails_once_past_step_10(trans, poses, idx, *args):
        if idx >= 10 and not blocked:
            blocked.append(idx)
            return None
        return real(trans, poses, idx, *args)

    monkeypatch.setattr(red_mod, "_regrasp_retrying", fails_once_past_step_10)
    greedy = GaitSettings(beam_width=0)  # the one-regrasp-at-a-time reduction
    settings = ReductionSettings(backtracks=0, gaits=greedy)
    gave_up = reduce_object_path(ctx.transitions, poses, x0[POSE_DIM:], grasp, settings)
    assert blocked and not gave_up.success
    assert gave_up.reason.startswith(f"no feasible regrasp at trajectory step {blocked[0]}")

    blocked.clear()
    ctx = build_context(scenario, seed=1)
    res = reduce_object_path(
        ctx.transitions, poses, x0[POSE_DIM:], grasp, ReductionSettings(gaits=greedy)
    )
    assert blocked and res.success, res.reason
    assert res.stats["backtracks"] == 1
    # the kept segments chain: each starts where the one before ended
    assert np.allclose(res.segments[0].start.q, x0[POSE_DIM:])
    for a, b in itertools.pairwise(res.segments):
        np.testing.assert_allclose(b.start.q, a.end.q, atol=1e-12)
        np.testing.assert_allclose(
            b.start.object_pose_xyzquat, a.end.object_pose_xyzquat, atol=1e-12
        )
    assert quat_angle(res.segments[-1].end.object_pose_xyzquat[3:], poses[-1][3:]) < 1e-9


def test_densified_quaternions_keep_their_sign() -> None:
    """A pose given with the other quaternion sign comes out negated, not jumped to.

    Consecutive output quaternions never point into opposite hemispheres, so
    a transfer ends on the sign the next segment starts from (the plan
    verifier compares poses as written: a regrasp at ``-q`` after a transfer
    ending at ``q`` broke continuity in an edge-by-edge plan).
    """
    from dexplan.core.pose import quat_from_axis_angle

    q1 = quat_from_axis_angle(np.array([0.0, 0.0, 1.0]), 0.6)
    q2 = quat_from_axis_angle(np.array([0.0, 1.0, 0.0]), 0.9)
    poses = np.array(
        [
            [0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0],
            [0.0, 0.0, 0.1, *(-q1)],  # the same rotation as q1, other sign
            [0.01, 0.0, 0.1, *q2],
        ]
    )
    dense = densify_poses(poses, 0.008, 0.04)
    dots = np.einsum("ij,ij->i", dense[:-1, 3:], dense[1:, 3:])
    assert np.all(dots > 0.99)
    assert quat_angle(dense[-1, 3:], q2) < 1e-9
