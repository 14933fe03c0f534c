"""Module 1: GSn paths from OMPL planners on the paper scenario; module 2 links."""

import dataclasses
import itertools
import time

import numpy as np
import pytest

import dexplan.planning.roadmap.module2 as rm
from dexplan.core.errors import InvalidInputError
from dexplan.core.pose import quat_angle
from dexplan.model.scenario import builtin_scenario_path, default_scenario, load_scenario
from dexplan.planning.context import build_context
from dexplan.planning.gsn.space import POSE_DIM
from dexplan.planning.gsn.validity import GraspValidity
from dexplan.planning.local.transitions import densify_poses
from dexplan.planning.planner import goal_reached
from dexplan.planning.roadmap.graph import Roadmap, connected_components
from dexplan.planning.roadmap.module1 import explore_gsn
from dexplan.planning.roadmap.module2 import link_query, try_link
from dexplan.planning.roadmap.search import GsnQuery
from dexplan.planning.start import start_state


@pytest.fixture(scope="module")
def scenario():
    return default_scenario()


@pytest.mark.timeout(240)
@pytest.mark.parametrize("planner", ["PRM", "RRTConnect", "KPIECE1"])
def test_gsn_path_to_yaw_180_every_state_valid(scenario, planner: str) -> None:
    ctx = build_context(scenario, seed=2)
    x0 = start_state(ctx)
    assert x0 is not None
    query = GsnQuery(
        x0,
        lambda x: goal_reached(scenario, x[:POSE_DIM]),
        lambda: ctx.sampler.sample_at_pose(scenario.goal.object_pose_xyzquat),
    )
    res = explore_gsn(
        ctx, query, planner, seed=2, deadline=time.perf_counter() + 300.0, module2=False
    )
    assert res.path is not None, res.message
    path = res.path
    np.testing.assert_allclose(path[0], x0, atol=1e-9)
    assert goal_reached(scenario, path[-1][:POSE_DIM])[0]
    for x in path:
        assert ctx.gsn.residual(x) < 1e-4
        assert ctx.validity.check(x).valid
    # the object really turns about 180 degrees
    assert quat_angle(path[0][3:7], path[-1][3:7]) > np.pi - 0.06
    assert res.stats["roadmap_nodes"] >= 2
    assert res.roadmap.n_vertices == res.stats["roadmap_nodes"]
    assert res.stats["module2_attempts"] == 0  # module 1 alone


def test_sampler_states_are_valid_and_on_gsn(scenario) -> None:
    ctx = build_context(scenario, seed=4)
    for _ in range(20):
        x = ctx.sampler.sample()
        assert x is not None
        assert ctx.gsn.residual(x) < 1e-6
        assert ctx.validity.check(x).valid
    st = ctx.sampler.stats
    assert st.valid == 20 and 0 < st.valid_fraction <= 1
    assert sum(ctx.validity.stats.rejected.values()) + ctx.validity.stats.valid == (
        ctx.validity.stats.checked
    )


def test_roadmap_components_and_links() -> None:
    v = np.zeros((5, 19))
    v[:, 6] = 1.0
    rm = Roadmap(v, np.array([[0, 1], [2, 3]]), np.zeros((0, 2), dtype=np.int64), "PRM", "k")
    n, labels = rm.components()
    assert n == 3 and labels[0] == labels[1] and labels[2] == labels[3] != labels[0]
    assert rm.shortest_path(0, [3]) is None
    rm.add_link(1, 2)
    assert rm.components()[0] == 2
    assert rm.shortest_path(0, [3]) == [0, 1, 2, 3]


def test_connected_components_known_graphs():
    labels, sizes = connected_components(5, [[0, 1], [3, 2], [1, 0]])
    np.testing.assert_array_equal(labels, [0, 0, 1, 1, 2])
    np.testing.assert_array_equal(sizes, [2, 2, 1])
    labels, sizes = connected_components(3, np.zeros((0, 2), dtype=int))
    np.testing.assert_array_equal(labels, [0, 1, 2])
    np.testing.assert_array_equal(sizes, [1, 1, 1])
    labels, sizes = connected_components(4, [[3, 2], [2, 1], [1, 0], [0, 0]])
    np.testing.assert_array_equal(labels, [0, 0, 0, 0])
    np.testing.assert_array_equal(sizes, [4])
    labels, sizes = connected_components(0, [])
    assert labels.shape == (0,) and sizes.shape == (0,)
    with pytest.raises(InvalidInputError):
        connected_components(2, [[0, 2]])
    with pytest.raises(InvalidInputError):
        connected_components(2, [[0.0, 1.0]])


def test_module2_link_turns_the_object(scenario) -> None:
    ctx = build_context(scenario, seed=5)
    x0 = start_state(ctx)
    target = scenario.start.object_pose_xyzquat.copy()
    target[3:] = [0.0, 0.0, np.sin(np.pi / 8), np.cos(np.pi / 8)]  # 45 degrees about z
    assert try_link(ctx, x0, target)


def test_gsn_state_space_properties(scenario) -> None:
    """In the spirit of OMPL's StateSpaceTest, on GSn itself."""
    from dexplan.planning.ompl import PlanningProblem
    from dexplan.planning.roadmap.problems import constraint_spec

    ctx = build_context(scenario, seed=6)
    problem = PlanningProblem(
        constraint_spec(ctx, "projected"), ctx.validity.is_valid, planner="PRM"
    )
    xs = [ctx.sampler.sample() for _ in range(8)]
    for a, b in itertools.pairwise(xs):
        assert ctx.gsn.residual(a) < 1e-6
        assert problem.distance(a, a) == 0.0
        assert problem.distance(a, b) == pytest.approx(problem.distance(b, a), rel=1e-12)
        assert problem.distance(a, b) > 0.0
        for t in (0.25, 0.5, 0.75):
            m = problem.interpolate(a, b, t)
            assert ctx.gsn.residual(m) < 1e-4  # interpolated states stay on GSn
        np.testing.assert_allclose(problem.round_trip(a), a, atol=1e-12)


def test_validity_keeps_the_object_clear_of_obstacles(scenario) -> None:
    """GSn states closer than object_clearance to an obstacle are invalid (no tunnelling)."""
    ctx = build_context(scenario, seed=6)
    x = start_state(ctx)
    assert x is not None and ctx.validity.is_valid(x)
    table_top = -0.02 + 0.005  # the scenario's table: 1 cm thick at z = -0.02
    clearance = ctx.world.object_clearance(x[:POSE_DIM])
    assert clearance == pytest.approx(x[2] - 0.04 - table_top, abs=1e-6)
    strict = dataclasses.replace(ctx.validity.settings, object_clearance=clearance + 1e-4)
    verdict = GraspValidity(ctx.gsn, ctx.world, strict).check(x)
    assert not verdict.valid and verdict.reason == "collision"


def test_roadmap_key_depends_on_the_contact_model():
    import dataclasses

    from dexplan.model.scenario import default_scenario
    from dexplan.planning.context import build_context
    from dexplan.planning.roadmap.graph import scenario_key

    point = default_scenario()
    soft = dataclasses.replace(point, contact_model="soft", torsion=0.005)
    assert scenario_key(build_context(point)) != scenario_key(build_context(soft))


def test_module2_starts_no_attempt_after_its_share_and_never_cuts_one(
    scenario, monkeypatch
) -> None:
    """Attempts start within MODULE2_SHARE of the time left; each runs with the
    query's own deadline (a fake clock: each attempt takes 10 s of 100)."""
    from dexplan.planning.roadmap import module2 as rm

    ctx = build_context(scenario, seed=1)
    x0 = start_state(ctx)
    goal = scenario.goal.object_pose_xyzquat
    goals = [ctx.sampler.sample_at_pose(goal) for _ in range(5)]
    assert x0 is not None and all(g is not None for g in goals)
    roadmap = Roadmap(
        np.stack([x0, *goals]), np.zeros((0, 2), int), np.zeros((0, 2), int), "P", "k"
    )
    query = GsnQuery(x0, lambda x: goal_reached(scenario, x[:POSE_DIM]), lambda: None)
    clock = [1000.0]
    ctx.deadline.at = 1100.0  # the query's
    seen: list[tuple[float, float]] = []

    def slow_failure(ctx_, a, b_pose, via=()):
        seen.append((clock[0], ctx_.transitions.deadline.at))
        clock[0] += 10.0
        return rm.LinkReduction(
            np.zeros((1, 7)), a[POSE_DIM:], rm.ReductionResult(False, (), 0, "x")
        )

    monkeypatch.setattr(rm, "link_reduction", slow_failure)
    monkeypatch.setattr(rm.time, "perf_counter", lambda: clock[0])
    stats = {"module2_attempts": 0, "module2_links": 0, "module2_time_s": 0.0}
    res = rm._module2_pass(ctx, roadmap, query, 0, 1100.0, stats, None, [])
    assert res.path is None
    # the share ends at 1000 + 0.3 * 100 = 1030: attempts at 1000, 1010, 1020 only
    assert [t for t, _ in seen] == [1000.0, 1010.0, 1020.0]
    assert all(at == 1100.0 for _, at in seen)  # none ran with a cut deadline

    # an attempt that ends after the share with a link into the goal region: the path
    def slow_success(ctx_, a, b_pose, via=()):
        clock[0] += 40.0
        return rm.LinkReduction(
            np.zeros((1, 7)), a[POSE_DIM:], rm.ReductionResult(True, (), 0, None)
        )

    monkeypatch.setattr(rm, "link_reduction", slow_success)
    clock[0] = 1000.0
    res = rm._module2_pass(ctx, roadmap, query, 0, 1100.0, stats, None, [])
    assert res.path is not None and len(res.links) == 1
    np.testing.assert_array_equal(res.path[0], x0)


def _link_once(scenario, x0, g):
    """Module 2 on a two-vertex roadmap (start, a goal-region state), as the planner runs it."""
    ctx = build_context(scenario, seed=1)
    roadmap = Roadmap(np.stack([x0, g]), np.zeros((0, 2), int), np.zeros((0, 2), int), "PRM", "k")
    query = GsnQuery(
        x0,
        lambda x: goal_reached(scenario, x[:POSE_DIM]),
        lambda: None,
        goal_pose=scenario.goal.object_pose_xyzquat,
    )
    stats = {"module2_attempts": 0, "module2_links": 0, "module2_time_s": 0.0}
    return ctx, link_query(ctx, roadmap, query, 0, time.perf_counter() + 300.0, stats)


def test_a_link_into_the_goal_region_ends_on_the_goal_pose_and_is_kept(scenario) -> None:
    ctx = build_context(scenario, seed=1)
    x0 = start_state(ctx)
    goal = scenario.goal.object_pose_xyzquat
    near_goal = goal + np.array([0.001, 0, 0, 0, 0, 0, 0])
    g = ctx.sampler.sample_at_pose(near_goal)
    assert x0 is not None and g is not None and goal_reached(scenario, g[:POSE_DIM])[0]
    ctx, res = _link_once(scenario, x0, g)
    assert res.path is not None and len(res.links) == 1
    link = res.links[0]
    assert link.result.success
    # it ends on the goal pose itself, not on the sampled goal state's
    end = link.result.segments[-1].end.object_pose_xyzquat
    np.testing.assert_allclose(end[:3], goal[:3], atol=1e-9)
    assert quat_angle(end[3:], goal[3:]) < 1e-6
    assert np.linalg.norm(g[:3] - goal[:3]) > 1e-4  # (which differs)
    # the planner's reduction trajectory (start pose to goal pose) is the link's own
    s = ctx.transitions.settings
    dense = densify_poses(np.stack([x0[:POSE_DIM], goal]), s.max_step_m, s.max_step_rad)
    assert link.matches(dense, x0[POSE_DIM:])
    assert not link.matches(dense[:-1], x0[POSE_DIM:])
    other = x0[POSE_DIM:].copy()
    other[0] += 1e-3
    assert not link.matches(dense, other)
    # an attempt's stream is its own: the same link again, regrasp for regrasp
    _, again = _link_once(scenario, x0, g)
    assert [(a.kind, a.finger) for a in again.links[0].result.segments] == [
        (a.kind, a.finger) for a in link.result.segments
    ]


def test_a_link_via_another_start_grasp_regrasps_onto_it_first(scenario) -> None:
    """Module 2's second try from the start: regrasps (object fixed) onto another
    start grasp, then the gaits from there, one reduction from the start's joints."""
    from dexplan.planning.local.grasps import grasp_from_state
    from dexplan.planning.roadmap.module2 import link_reduction

    ctx = build_context(scenario, seed=1)
    x0 = start_state(ctx)
    assert x0 is not None
    pose0, n = x0[:POSE_DIM], ctx.hand.n_fingers
    tr = ctx.transitions
    grasp0 = grasp_from_state(tr, pose0, x0[POSE_DIM:])
    alts = ctx.sampler.samples_at_pose(pose0, 8, np.random.default_rng(7))
    far = [
        via
        for via in alts
        if np.all(
            np.linalg.norm(
                grasp_from_state(tr, pose0, via[POSE_DIM:]).points - grasp0.points, axis=1
            )
            > 0.005
        )
    ]
    assert far  # a grasp on which every finger has to move
    via = far[0]
    target = grasp_from_state(tr, pose0, via[POSE_DIM:])
    link = link_reduction(ctx, x0, scenario.goal.object_pose_xyzquat, [via])
    assert link.result.success, link.result.reason
    segs = link.result.segments
    np.testing.assert_allclose(segs[0].start.q, x0[POSE_DIM:], atol=1e-12)
    moves = segs[:n]
    assert all(g.kind == "regrasp" for g in moves)
    assert sorted(g.finger for g in moves) == list(range(n))
    for g in moves:  # the object stays at the start pose while they regrasp
        for w in g.waypoints:
            np.testing.assert_allclose(w.object_pose_xyzquat, pose0, atol=1e-12)
    # then the fingertips touch the other grasp's contacts
    reached = grasp_from_state(tr, pose0, moves[-1].end.q)
    np.testing.assert_allclose(reached.points, target.points, atol=1e-6)
    for a, b in itertools.pairwise(segs):
        np.testing.assert_allclose(b.start.q, a.end.q, atol=1e-12)


@pytest.mark.timeout(300)
def test_module2_goes_round_an_obstacle_through_waypoints() -> None:
    """cube_post with a roadmap of the start alone (as BFMT leaves it): the
    straight turn hits the post, so without waypoints module 2 tries nothing;
    with them it adds RLG states once and links through their poses."""
    scen = load_scenario(builtin_scenario_path("suite/cube_post"))
    results = {}
    for waypoints in (0, rm.MODULE2_WAYPOINTS):
        ctx = build_context(scen, seed=2)
        x0 = start_state(ctx)
        assert x0 is not None
        roadmap = Roadmap(x0[None, :], np.zeros((0, 2), int), np.zeros((0, 2), int), "BFMT", "k")
        query = GsnQuery(
            x0,
            lambda x: goal_reached(scen, x[:POSE_DIM]),
            lambda ctx=ctx: ctx.sampler.sample_at_pose(scen.goal.object_pose_xyzquat),
            goal_pose=scen.goal.object_pose_xyzquat,
        )
        assert not rm.object_move_free(ctx, x0, np.r_[scen.goal.object_pose_xyzquat, x0[7:]])
        stats = {"module2_attempts": 0, "module2_links": 0, "module2_time_s": 0.0}
        res = link_query(
            ctx, roadmap, query, 0, time.perf_counter() + 300.0, stats, waypoints=waypoints
        )
        results[waypoints] = (res, stats)
    res, stats = results[0]
    assert res.path is None and stats["module2_attempts"] == 0
    assert "module2_waypoints" not in stats
    res, stats = results[rm.MODULE2_WAYPOINTS]
    assert 0 < stats["module2_waypoints"] <= rm.MODULE2_WAYPOINTS
    assert stats["module2_attempts"] >= 2 and stats["module2_links"] >= 2
    assert res.path is not None  # seed 2: round the post in two links or more
    assert goal_reached(scen, res.path[-1][:POSE_DIM])[0]
