"""The toy problem of the OMPL adapter's tests: a point on the unit sphere in R^3.

The obstacle band |z| < 0.1 blocks the sphere except for x <= -0.5, so a path from
the south pole to the north pole must pass through that window.
"""

from __future__ import annotations

import numpy as np

from dexplan.planning.ompl import ConstraintSpec, GoalSpec

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
