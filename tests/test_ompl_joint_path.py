"""Tests of dexplan.planning.ompl.joint_path: unconstrained paths in a box."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from dexplan.core.errors import InvalidInputError, PlannerError
from dexplan.planning.ompl import plan_joint_path


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
