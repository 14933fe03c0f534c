"""Tests of dexplan.planning.ompl.spaces on the unit-sphere toy problem.

Atlas and tangent-bundle spaces, scaled coordinates, KPIECE projections,
projection and motion checks.
"""

from __future__ import annotations

import numpy as np
import pytest
from toy_sphere import NORTH, SOUTH, check_path, is_valid, make_spec

from dexplan.planning.ompl import PlanningProblem, ProjectionSpec


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


def test_project_and_check_motion():
    problem = PlanningProblem(make_spec(), is_valid, planner="RRTConnect")
    y = problem.project([0.0, 0.0, -2.0])
    np.testing.assert_allclose(y, SOUTH, atol=1e-4)
    assert problem.check_motion(SOUTH, [-0.6, 0.0, -0.8])
    assert not problem.check_motion([0.8, 0.0, -0.6], [0.8, 0.0, 0.6])  # crosses the band
