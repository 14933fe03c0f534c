"""A caller's second motion beside OMPL's discrete geodesic (dexplan.planning.ompl.motions).

On the toy sphere, a = (1, 0, -0.3) and b = (1, 0, 0.3) (normalised) lie on
either side of the band |z| < 0.1: OMPL's geodesic crosses it at x = 1 and is
invalid. The fallback goes round through the window at (-1, 0, 0).
"""

from __future__ import annotations

import numpy as np
import pytest
from toy_sphere import is_valid, make_spec, sphere_f

from dexplan.core.errors import InvalidInputError, PlannerError
from dexplan.planning.ompl import PlanningProblem

A = np.array([1.0, 0.0, -0.3]) / np.linalg.norm([1.0, 0.0, -0.3])
B = np.array([1.0, 0.0, 0.3]) / np.linalg.norm([1.0, 0.0, 0.3])
WINDOW = np.array([-1.0, 0.0, 0.0])


def slerp(p, q, step=0.05):
    angle = float(np.arccos(np.clip(p @ q, -1.0, 1.0)))
    n = max(1, int(np.ceil(angle / step)))
    t = np.linspace(0.0, 1.0, n + 1)[:, None]
    return (np.sin((1 - t) * angle) * p + np.sin(t * angle) * q) / np.sin(angle)


class RoundTheWindow:
    """The fallback: a -> window -> b along great circles; counts its calls."""

    def __init__(self):
        self.calls = 0

    def __call__(self, a, b, deadline):
        self.calls += 1
        assert deadline > 0.0
        return np.vstack([slerp(a, WINDOW), slerp(WINDOW, b)[1:]])


def problem(fallback, **kwargs):
    return PlanningProblem(make_spec(), is_valid, planner="PRM", motion_fallback=fallback, **kwargs)


def test_fallback_joins_what_ompl_does_not_and_paths_follow_it():
    assert not problem(None).check_motion(A, B)
    fallback = RoundTheWindow()
    p = problem(fallback)
    assert p.check_motion(A, B)
    assert p.fallback_motions == (1, 1, 0)
    for a, b in ((A, B), (B, A)):  # recorded once, used in both directions
        checked = p.check_path(np.stack([a, b]))
        assert checked.path_valid and checked.invalid_segments == ()
        path = checked.path
        np.testing.assert_allclose(path[0], a, atol=1e-12)
        np.testing.assert_allclose(path[-1], b, atol=1e-12)
        assert min(path[:, 0]) < -0.99  # through the window, not across the band
        assert all(is_valid(x) and abs(sphere_f(x)[0]) < 1e-9 for x in path)
        dense = p.interpolate_path(np.stack([a, b]))
        np.testing.assert_allclose(dense, path, atol=1e-12)
    assert fallback.calls == 1


def test_ompl_motion_is_asked_first():
    fallback = RoundTheWindow()
    p = problem(fallback)
    c = np.array([0.0, 0.6, -0.8])  # below the band with A: OMPL's motion is valid
    assert p.check_motion(A, c)
    assert fallback.calls == 0
    path = p.check_path(np.stack([A, c])).path
    assert min(path[:, 0]) > -0.5  # OMPL's arc, not round the window


def test_merges_only_does_not_call_the_fallback_inside_a_component():
    fallback = RoundTheWindow()
    p = problem(fallback, fallback_merges_only=True)
    west_low = np.array([-0.8, 0.0, -0.6])
    west_high = np.array([-0.8, 0.0, 0.6])
    assert p.check_motion(A, west_low) and p.check_motion(west_low, west_high)
    assert p.check_motion(west_high, B)  # A, B in one component through the window
    assert fallback.calls == 0
    assert not p.check_motion(A, B)  # OMPL's motion is invalid; already joined
    assert fallback.calls == 0
    free = problem(RoundTheWindow(), fallback_merges_only=False)
    assert free.check_motion(A, B)


def test_fallback_states_off_the_manifold_do_not_join():
    def off(a, b, deadline):
        path = RoundTheWindow()(a, b, deadline)
        path[1:-1] *= 1.01
        return path

    p = problem(off)
    assert not p.check_motion(A, B)
    assert p.fallback_motions == (1, 0, 0)


@pytest.mark.parametrize(
    ("answer", "needle"),
    [
        (lambda a, b: np.zeros((2, 2)), "returned shape"),
        (lambda a, b: np.stack([a, a]), "start and end"),
        (lambda a, b: np.stack([a, np.full(3, np.nan)]), "non-finite states"),
    ],
)
def test_malformed_fallback_answers_raise(answer, needle):
    p = problem(lambda a, b, deadline: answer(a, b))
    with pytest.raises(PlannerError, match=needle):
        p.check_motion(A, B)


def test_fallback_refused_for_tree_planners_and_non_callables():
    with pytest.raises(InvalidInputError, match="PRM family"):
        PlanningProblem(
            make_spec(), is_valid, planner="RRTConnect", motion_fallback=RoundTheWindow()
        )
    with pytest.raises(InvalidInputError, match="callable"):
        PlanningProblem(make_spec(), is_valid, planner="PRM", motion_fallback=3)


def test_fallback_calls_are_budgeted_in_checks_not_time():
    """Fallback calls at most a tenth of the motion checks (the first free):
    the same calls whatever the clock, so a seed keeps its roadmap."""
    fallback = RoundTheWindow()
    p = problem(fallback, fallback_merges_only=False)
    assert p.check_motion(A, B)  # the first call is free
    c = np.array([0.0, 0.6, -0.8])
    d = np.array([0.0, 0.6, 0.8])  # c -> d crosses the band at x = 0: OMPL's motion fails
    assert not p.check_motion(c, d)  # 2 checks, 1 call: no budget left
    assert fallback.calls == 1 and p.fallback_motions == (1, 1, 1)
    for _ in range(8):
        assert p.check_motion(A, c)  # OMPL's motions earn budget
    assert p.check_motion(c, d)  # 11 checks: a second call
    assert fallback.calls == 2


def test_densify_only_problem_keeps_checks_ompl_s():
    fallback = RoundTheWindow()
    p = problem(fallback, fallback_checks=False)
    assert not p.check_motion(A, B)
    assert fallback.calls == 0
    dense = p.interpolate_path(np.stack([A, B]))
    assert fallback.calls == 1
    assert min(dense[:, 0]) < -0.99  # round the window
    np.testing.assert_allclose(dense[0], A, atol=1e-12)
    np.testing.assert_allclose(dense[-1], B, atol=1e-12)


def test_fallback_states_are_found_through_ambient_round_trips():
    """Roadmap vertices come back through ambient coordinates (y * inv * scale):
    the record still answers for them, and the fallback is not called again."""
    fallback = RoundTheWindow()
    spec = make_spec(scale=np.array([1.0 / 3.0, 7.0, 0.3]))
    p = PlanningProblem(spec, is_valid, planner="PRM", motion_fallback=fallback)
    assert p.check_motion(A, B)
    a2 = (A * spec.scale) * (1.0 / spec.scale)  # a vertex as planner_data() gives it
    assert np.any(a2 * spec.scale != A * spec.scale)  # a few ulps off OMPL's coordinates
    checked = p.check_path(np.stack([a2, B]))
    assert checked.path_valid and min(checked.path[:, 0]) < -0.99
    assert fallback.calls == 1


def test_clear_forgets_the_fallback_motions():
    fallback = RoundTheWindow()
    p = problem(fallback)
    assert p.check_motion(A, B)
    p.clear()
    assert p.check_motion(A, B)
    assert fallback.calls == 2
