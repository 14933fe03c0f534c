"""Tests of dexplan.planning.ompl_adapter on a point on the unit sphere in R^3.

The obstacle band |z| < 0.1 blocks the sphere except for x <= -0.5, so a path from
the south pole to the north pole must pass through that window.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from dexplan.exceptions import InvalidInputError, PlannerError
from dexplan.planning.ompl_adapter import (
    MULTI_QUERY_PLANNERS,
    PLANNERS,
    UNSUPPORTED_PLANNERS,
    ConstraintSpec,
    GoalSpec,
    PlanningProblem,
    ProjectionSpec,
    available_planners,
    connected_components,
    get_log_level,
    plan_joint_path,
    set_log_level,
)

SOUTH = np.array([0.0, 0.0, -1.0])
NORTH = np.array([0.0, 0.0, 1.0])


def sphere_f(x):
    return np.array([np.sqrt(x @ x) - 1.0])


def sphere_j(x):
    return (x / np.sqrt(x @ x))[None, :]


def is_valid(x):
    return not (abs(x[2]) < 0.1 and x[0] > -0.5)


def make_spec(**kwargs):
    return ConstraintSpec(3, 1, sphere_f, sphere_j, -2.0 * np.ones(3), 2.0 * np.ones(3), **kwargs)


def uniform_sphere_sampler(rng, counter=None):
    def sample():
        if counter is not None:
            counter[0] += 1
        v = rng.normal(size=3)
        v /= np.linalg.norm(v)
        return v if is_valid(v) else None

    return sample


def north_goal(rng, threshold=0.2, with_sampler=True):
    def distance(x):
        return float(np.linalg.norm(x - NORTH))

    def sample():
        v = NORTH + 0.08 * rng.normal(size=3)
        return v / np.linalg.norm(v)

    return GoalSpec(distance, threshold, sample=sample if with_sampler else None)


def check_path(problem, result, start, goal=None, goal_tol=1e-6):
    spec = problem.constraint
    path = result.path
    assert path is not None and path.ndim == 2 and path.shape[1] == 3
    assert result.path_valid
    assert result.invalid_segments == ()
    np.testing.assert_allclose(path[0], start, atol=1e-9)
    if goal is not None:
        assert np.linalg.norm(path[-1] - goal) <= goal_tol
    for x in path:
        assert abs(sphere_f(x)[0]) <= spec.tolerance
        assert is_valid(x)
        assert np.all(x >= spec.lower) and np.all(x <= spec.upper)
    steps = np.linalg.norm(np.diff(path, axis=0), axis=1)
    limit = problem.lambda_ * problem.delta + 1e-9
    assert steps.max() <= limit
    assert result.max_step <= limit


# --------------------------------------------------------------------------- registry


def test_registry_lists_working_planners():
    names = available_planners()
    assert names == sorted(PLANNERS)
    for name in ("PRM", "RRTConnect", "KPIECE1", "RRT", "BKPIECE1"):
        assert name in names
    assert "AORRTC" in UNSUPPORTED_PLANNERS and "AORRTC" not in names
    assert set(names) >= MULTI_QUERY_PLANNERS


def test_unknown_planner_names_the_valid_ones():
    with pytest.raises(PlannerError, match="RRTConnect") as info:
        PlanningProblem(make_spec(), is_valid, planner="NoSuchPlanner")
    assert "NoSuchPlanner" in str(info.value)
    with pytest.raises(PlannerError, match="not supported"):
        PlanningProblem(make_spec(), is_valid, planner="AORRTC")


def test_params_set_by_name():
    problem = PlanningProblem(make_spec(), is_valid, planner="RRTConnect", params={"range": 0.1})
    assert float(problem.parameters()["range"]) == pytest.approx(0.1)
    problem.set_param("intermediate_states", "true")
    assert problem.parameters()["intermediate_states"] == "1"
    problem.set_param("range", "0.25")
    assert float(problem.parameters()["range"]) == pytest.approx(0.25)


def test_unknown_param_names_the_valid_ones():
    problem = PlanningProblem(make_spec(), is_valid, planner="RRTConnect")
    with pytest.raises(PlannerError, match="range") as info:
        problem.set_param("rnage", 0.1)
    assert "intermediate_states" in str(info.value)
    assert "rnage" in str(info.value)
    with pytest.raises(PlannerError, match="max_nearest_neighbors"):
        PlanningProblem(make_spec(), is_valid, planner="PRM", params={"range": 0.1})


@pytest.mark.parametrize(
    ("planner", "name", "value"),
    [
        ("RRTConnect", "range", -1.0),
        ("RRTConnect", "range", "abc"),
        ("RRTConnect", "range", float("nan")),
        ("RRTConnect", "intermediate_states", "maybe"),
        ("RRT", "goal_bias", 2.0),
        ("PRM", "max_nearest_neighbors", 2.5),
        ("BFMT", "balanced", 1),  # declared by OMPL, no setter in the binding
        ("BITstar", "use_strict_queue_ordering", False),  # OMPL ignores it
    ],
)
def test_bad_param_value_raises(planner, name, value):
    problem = PlanningProblem(make_spec(), is_valid, planner=planner)
    with pytest.raises(PlannerError, match=name):
        problem.set_param(name, value)


# --------------------------------------------------------------------------- graphs


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


# --------------------------------------------------------------------------- solving


@pytest.mark.timeout(60)
@pytest.mark.parametrize("planner", ["PRM", "RRTConnect", "KPIECE1"])
def test_toy_problem_solves(planner):
    problem = PlanningProblem(make_spec(), is_valid, planner=planner, seed=11)
    problem.set_start(SOUTH)
    problem.set_goal_state(NORTH)
    result = problem.solve(10.0)
    assert result.status == "exact" and result.solved
    check_path(problem, result, SOUTH, NORTH)
    # the window x <= -0.5 is the only way through the band
    crossing = result.path[np.abs(result.path[:, 2]) < 0.1]
    assert crossing.size and np.all(crossing[:, 0] <= -0.5)
    assert result.waypoints.shape[0] <= result.path.shape[0]


@pytest.mark.timeout(60)
@pytest.mark.parametrize("planner", sorted(PLANNERS))
def test_every_registered_planner_returns_cleanly(planner):
    problem = PlanningProblem(make_spec(), is_valid, planner=planner, seed=5)
    problem.set_start(SOUTH)
    problem.set_goal_state(NORTH, threshold=1e-3)
    result = problem.solve(1.0)
    assert result.time_s < 20.0
    assert result.status in {"exact", "approximate", "timeout", "path_invalid"}
    if result.solved:
        check_path(problem, result, SOUTH, NORTH, goal_tol=1e-3)


@pytest.mark.timeout(60)
def test_planner_data_of_prm():
    problem = PlanningProblem(make_spec(), is_valid, planner="PRM", seed=2)
    problem.set_start(SOUTH)
    problem.set_goal_state(NORTH)
    assert problem.solve(10.0).solved
    data = problem.planner_data()
    assert data.num_vertices > 0
    assert data.vertices.shape == (data.num_vertices, 3)
    assert data.edges.ndim == 2 and data.edges.shape[1] == 2 and data.edges.shape[0] > 0
    assert data.edges.min() >= 0 and data.edges.max() < data.num_vertices
    assert data.start_ids.size >= 1 and data.goal_ids.size >= 1
    np.testing.assert_allclose(data.vertices[data.start_ids[0]], SOUTH, atol=1e-9)
    np.testing.assert_allclose(data.vertices[data.goal_ids[0]], NORTH, atol=1e-9)
    residuals = np.abs(np.linalg.norm(data.vertices, axis=1) - 1.0)
    assert residuals.max() <= problem.constraint.tolerance
    labels, sizes = data.components()
    assert labels.shape == (data.num_vertices,) and sizes.sum() == data.num_vertices
    assert labels[data.start_ids[0]] == labels[data.goal_ids[0]]


@pytest.mark.timeout(60)
def test_custom_valid_sampler_is_called():
    calls = [0]
    rng = np.random.default_rng(0)
    problem = PlanningProblem(
        make_spec(),
        is_valid,
        planner="PRM",
        valid_sampler=uniform_sphere_sampler(rng, calls),
        seed=3,
    )
    assert problem.grow_roadmap(10.0, max_milestones=60) >= 60
    assert calls[0] >= 60
    assert problem.valid_sampler_count() >= 1
    vertices = problem.planner_data().vertices
    assert np.all([is_valid(x) for x in vertices])


@pytest.mark.timeout(60)
@pytest.mark.parametrize("planner", ["PRM", "RRTConnect", "RRT", "KPIECE1", "BKPIECE1"])
def test_goal_region_with_sampling(planner):
    rng = np.random.default_rng(1)
    goal = north_goal(rng)
    problem = PlanningProblem(make_spec(), is_valid, planner=planner, seed=4)
    problem.set_start(SOUTH)
    problem.set_goal(goal)
    result = problem.solve(10.0)
    assert result.solved, result.status
    check_path(problem, result, SOUTH)
    assert goal.distance(result.path[-1]) <= goal.threshold


@pytest.mark.timeout(60)
def test_goal_region_without_sampler():
    rng = np.random.default_rng(1)
    goal = north_goal(rng, threshold=0.3, with_sampler=False)
    problem = PlanningProblem(make_spec(), is_valid, planner="RRT", seed=4)
    problem.set_start(SOUTH)
    problem.set_goal(goal)
    result = problem.solve(10.0)
    assert result.solved, result.status
    assert goal.distance(result.path[-1]) <= 0.3
    # PRM needs a goal state and reports it as a status, without hanging
    prm = PlanningProblem(make_spec(), is_valid, planner="PRM")
    prm.set_start(SOUTH)
    prm.set_goal(goal)
    assert prm.solve(1.0).status == "invalid_goal"


@pytest.mark.timeout(60)
@pytest.mark.parametrize("space", ["atlas", "tangent_bundle"])
@pytest.mark.parametrize("planner", ["PRM", "RRTConnect"])
def test_atlas_and_tangent_bundle_solve(space, planner):
    problem = PlanningProblem(make_spec(space=space), is_valid, planner=planner, seed=6)
    problem.set_start(SOUTH)
    problem.set_goal_state(NORTH)
    result = problem.solve(10.0)
    assert result.solved, result.status
    check_path(problem, result, SOUTH, NORTH)


@pytest.mark.timeout(60)
def test_multi_query_reuses_the_prm_roadmap():
    rng = np.random.default_rng(7)
    problem = PlanningProblem(
        make_spec(), is_valid, planner="PRM", valid_sampler=uniform_sphere_sampler(rng), seed=7
    )
    grown = problem.grow_roadmap(10.0, max_milestones=150)
    assert grown >= 150
    problem.set_start(SOUTH)
    problem.set_goal_state(NORTH)
    first = problem.solve(10.0)
    assert first.solved
    after_first = problem.planner_data().num_vertices
    assert after_first >= grown
    start2, goal2 = np.array([-1.0, 0.0, 0.0]), np.array([0.0, 0.6, 0.8])
    problem.set_start(start2)
    problem.set_goal_state(goal2)
    second = problem.solve(10.0)
    assert second.solved
    check_path(problem, second, start2, goal2)
    data = problem.planner_data()
    assert data.num_vertices >= after_first  # the roadmap was kept
    assert data.start_ids.size == 1 and data.goal_ids.size == 1
    np.testing.assert_allclose(data.vertices[data.start_ids[0]], start2, atol=1e-9)


@pytest.mark.timeout(60)
def test_tree_planner_new_query_restarts():
    problem = PlanningProblem(make_spec(), is_valid, planner="RRTConnect", seed=8)
    problem.set_start(SOUTH)
    problem.set_goal_state(NORTH)
    assert problem.solve(10.0).solved
    problem.set_start(NORTH)
    problem.set_goal_state(SOUTH)
    result = problem.solve(10.0)
    assert result.solved
    check_path(problem, result, NORTH, SOUTH)


# --------------------------------------------------------------------------- determinism


def _waypoints(planner, seed):
    problem = PlanningProblem(make_spec(), is_valid, planner=planner, seed=seed)
    problem.set_start(SOUTH)
    problem.set_goal_state(NORTH)
    result = problem.solve(10.0)
    assert result.solved
    return result.waypoints


@pytest.mark.timeout(60)
@pytest.mark.parametrize("planner", ["RRTConnect", "KPIECE1", "RRT"])
def test_same_seed_same_path(planner):
    a = _waypoints(planner, 21)
    b = _waypoints(planner, 21)
    c = _waypoints(planner, 22)
    assert a.shape == b.shape and np.array_equal(a, b)
    assert a.shape != c.shape or not np.array_equal(a, c)


@pytest.mark.timeout(60)
def test_same_seed_same_prm_roadmap():
    def roadmap(seed):
        rng = np.random.default_rng(seed)
        problem = PlanningProblem(
            make_spec(),
            is_valid,
            planner="PRM",
            valid_sampler=uniform_sphere_sampler(rng),
            seed=seed,
        )
        problem.grow_roadmap(10.0, max_milestones=80)
        return problem.planner_data()

    a, b = roadmap(9), roadmap(9)
    np.testing.assert_array_equal(a.vertices, b.vertices)
    np.testing.assert_array_equal(a.edges, b.edges)


@pytest.mark.timeout(60)
def test_iteration_budget_stops_the_search_deterministically():
    """A search stopped by max_iterations (not the clock) depends on the seed only."""

    def tree(budget):
        problem = PlanningProblem(make_spec(), is_valid, planner="KPIECE1", seed=5)
        problem.set_start(SOUTH)
        # a region no sample falls into: the search runs its budget out
        problem.set_goal(north_goal(np.random.default_rng(0), 1e-12, with_sampler=False))
        result = problem.solve(30.0, max_iterations=budget)
        return result, problem.planner_data()

    (ra, a), (_, b) = tree(40), tree(40)
    assert not ra.solved and ra.time_s < 30.0
    np.testing.assert_array_equal(a.vertices, b.vertices)
    np.testing.assert_array_equal(a.edges, b.edges)
    _, bigger = tree(400)
    assert len(bigger.vertices) > len(a.vertices)

    prm = PlanningProblem(make_spec(), is_valid, planner="PRM", seed=5)
    prm.set_start(SOUTH)
    prm.set_goal_state(NORTH)
    with pytest.raises(PlannerError, match="single-query planners"):
        prm.solve(1.0, max_iterations=10)


# --------------------------------------------------------------------------- options


@pytest.mark.timeout(60)
def test_scaled_coordinates():
    scale = np.array([2.0, 2.0, 4.0])
    problem = PlanningProblem(make_spec(scale=scale, delta=0.1), is_valid, planner="RRTConnect")
    problem.set_start(SOUTH)
    problem.set_goal_state(NORTH)
    result = problem.solve(10.0)
    assert result.solved
    for x in result.path:  # returned in ambient coordinates
        assert abs(np.linalg.norm(x) - 1.0) <= 1e-4
    planning_steps = np.linalg.norm(np.diff(result.path * scale, axis=0), axis=1)
    assert planning_steps.max() <= problem.lambda_ * 0.1 + 1e-9
    assert problem.delta == pytest.approx(0.1)


@pytest.mark.timeout(60)
def test_projection_for_kpiece():
    calls = [0]

    def spherical(x):
        calls[0] += 1
        return np.array([np.arctan2(x[1], x[0]), np.arccos(np.clip(x[2], -1.0, 1.0))])

    projection = ProjectionSpec(
        2, spherical, cell_sizes=[0.1, 0.1], lower=[-np.pi, 0.0], upper=[np.pi, np.pi]
    )
    problem = PlanningProblem(
        make_spec(), is_valid, planner="KPIECE1", projection=projection, seed=1
    )
    problem.set_start(SOUTH)
    problem.set_goal_state(NORTH)
    assert problem.solve(10.0).solved
    assert calls[0] > 0


@pytest.mark.timeout(60)
def test_callback_error_becomes_planner_error():
    count = [0]

    def flaky(x):
        count[0] += 1
        if count[0] > 20:
            raise RuntimeError("boom")
        return is_valid(x)

    problem = PlanningProblem(make_spec(), flaky, planner="RRTConnect")
    problem.set_start(SOUTH)
    problem.set_goal_state(NORTH)
    with pytest.raises(PlannerError, match="boom"):
        problem.solve(10.0)


def test_project_and_check_motion():
    problem = PlanningProblem(make_spec(), is_valid, planner="RRTConnect")
    y = problem.project([0.0, 0.0, -2.0])
    np.testing.assert_allclose(y, SOUTH, atol=1e-4)
    assert problem.check_motion(SOUTH, [-0.6, 0.0, -0.8])
    assert not problem.check_motion([0.8, 0.0, -0.6], [0.8, 0.0, 0.6])  # crosses the band


def test_direction_dependent_segment_is_repaired():
    # Projected geodesics are discretized from their start: a thin invalid band hit
    # by the a -> b states but not by the b -> a states makes the motion asymmetric.
    seen, band = [], [None]

    def recording_valid(x):
        seen.append(np.arctan2(x[2], x[0]))
        return band[0] is None or abs(np.arctan2(x[2], x[0]) - band[0]) > 0.004

    problem = PlanningProblem(make_spec(), recording_valid, planner="RRTConnect")
    angle = 1.23
    a, b = np.array([1.0, 0.0, 0.0]), np.array([np.cos(angle), 0.0, np.sin(angle)])
    seen.clear()
    assert problem.check_motion(a, b)
    forward = np.array(seen)
    seen.clear()
    assert problem.check_motion(b, a)
    backward = np.array(seen)
    gaps = [np.min(np.abs(backward - f)) if 0.02 < f < angle - 0.02 else 0.0 for f in forward]
    assert max(gaps) > 0.008
    band[0] = forward[int(np.argmax(gaps))]
    assert not problem.check_motion(a, b)
    assert problem.check_motion(b, a)
    checked = problem.check_path([a, b])
    assert checked.path_valid
    assert checked.repaired_segments == (0,) and checked.invalid_segments == ()
    np.testing.assert_allclose(checked.path[0], a, atol=1e-12)
    np.testing.assert_allclose(checked.path[-1], b, atol=1e-12)
    assert all(recording_valid(x) for x in checked.path)
    assert checked.max_step <= problem.lambda_ * problem.delta + 1e-9
    # a segment invalid both ways is reported, not repaired
    plain = PlanningProblem(make_spec(), is_valid, planner="RRTConnect")
    blocked = plain.check_path([[0.8, 0.0, -0.6], [0.8, 0.0, 0.6]])
    assert not blocked.path_valid and blocked.invalid_segments == (0,)
    with pytest.raises(InvalidInputError, match="shape"):
        problem.check_path(np.zeros((2, 4)))


def test_invalid_inputs():
    with pytest.raises(InvalidInputError, match="lower"):
        ConstraintSpec(3, 1, sphere_f, sphere_j, np.ones(3), np.ones(3))
    with pytest.raises(InvalidInputError, match="co_dim"):
        ConstraintSpec(3, 3, sphere_f, sphere_j, -np.ones(3), np.ones(3))
    with pytest.raises(InvalidInputError, match="space"):
        make_spec(space="curved")
    with pytest.raises(InvalidInputError, match="lambda_"):
        make_spec(lambda_=0.5)
    with pytest.raises(InvalidInputError, match="scale"):
        make_spec(scale=[1.0, 0.0, 1.0])
    problem = PlanningProblem(make_spec(), is_valid, planner="RRT")
    with pytest.raises(InvalidInputError, match="off the manifold"):
        problem.set_start([0.0, 0.0, -1.5])
    with pytest.raises(InvalidInputError, match="shape"):
        problem.set_start([0.0, -1.0])
    with pytest.raises(PlannerError, match="start"):
        problem.solve(1.0)
    problem.set_start(SOUTH)
    with pytest.raises(PlannerError, match="goal"):
        problem.solve(1.0)
    with pytest.raises(PlannerError, match="multi-query"):
        problem.grow_roadmap(1.0)


def test_log_level_roundtrip():
    assert get_log_level() == "none"
    set_log_level("debug")
    try:
        assert get_log_level() == "debug"
    finally:
        set_log_level("none")
    with pytest.raises(InvalidInputError):
        set_log_level("loud")


# ------------------------------------------------------------ unconstrained paths


def _wall(x):
    """A wall x0 in (-0.2, 0.2) with a gap at x1 < -0.8."""
    return not (abs(x[0]) < 0.2 and x[1] > -0.8)


def test_joint_path_around_a_wall():
    lo, hi = -np.ones(3), np.ones(3)
    a, b = np.array([-0.5, 0.0, 0.0]), np.array([0.5, 0.0, 0.0])
    path = plan_joint_path(a, b, lo, hi, _wall, resolution=0.01, time_limit=5.0, seed=3)
    assert path is not None and path.shape[1] == 3 and len(path) >= 3
    np.testing.assert_allclose(path[0], a)
    np.testing.assert_allclose(path[-1], b)
    # every straight leg is valid when checked finer than the resolution asked for
    for p, q in itertools.pairwise(path):
        k = int(np.ceil(np.max(np.abs(q - p)) / 0.005)) + 1
        assert all(_wall(p + (q - p) * t) for t in np.linspace(0.0, 1.0, k))
        assert np.all(p >= lo) and np.all(p <= hi)
    again = plan_joint_path(a, b, lo, hi, _wall, resolution=0.01, time_limit=5.0, seed=3)
    np.testing.assert_array_equal(path, again)


def test_joint_path_none_when_walled_off_and_errors_named():
    lo, hi = -np.ones(2), np.ones(2)
    a, b = np.array([-0.5, 0.0]), np.array([0.5, 0.0])
    closed = plan_joint_path(
        a, b, lo, hi, lambda x: abs(x[0]) > 0.2, resolution=0.01, time_limit=0.5, max_iterations=200
    )
    assert closed is None
    with pytest.raises(InvalidInputError, match="lower and upper"):
        plan_joint_path(a, b, hi, lo, _wall, resolution=0.01, time_limit=1.0)
    with pytest.raises(InvalidInputError, match="goal must be 2 finite numbers"):
        plan_joint_path(a, [np.nan, 0.0], lo, hi, _wall, resolution=0.01, time_limit=1.0)
    with pytest.raises(InvalidInputError, match="single-query"):
        plan_joint_path(a, b, lo, hi, _wall, resolution=0.01, time_limit=1.0, planner="PRM")

    def boom(x):
        raise RuntimeError("bad checker")

    with pytest.raises(PlannerError, match="bad checker"):
        plan_joint_path(a, b, lo, hi, boom, resolution=0.01, time_limit=1.0)
