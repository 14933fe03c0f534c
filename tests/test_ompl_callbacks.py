"""Tests of dexplan.planning.ompl.callbacks on the unit-sphere toy problem.

The valid-state sampler, goal regions with and without a sampler, and callback
errors.
"""

from __future__ import annotations

import numpy as np
import pytest
from toy_sphere import (
    NORTH,
    SOUTH,
    check_path,
    is_valid,
    make_spec,
    north_goal,
    uniform_sphere_sampler,
)

from dexplan.core.errors import PlannerError
from dexplan.planning.ompl import PlanningProblem


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
