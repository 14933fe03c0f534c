"""Tests of dexplan.planning.ompl.registry: planner names and parameters."""

from __future__ import annotations

import pytest
from toy_sphere import is_valid, make_spec

from dexplan.core.errors import PlannerError
from dexplan.planning.ompl import (
    MULTI_QUERY_PLANNERS,
    PLANNERS,
    UNSUPPORTED_PLANNERS,
    PlanningProblem,
    available_planners,
)


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
