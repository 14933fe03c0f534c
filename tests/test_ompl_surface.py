"""The public OMPL surface (dexplan.ompl): setups, your planners, your paths, the registry."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from ompl import base as ob
from ompl import geometric as og
from toy_sphere import NORTH, SOUTH, is_valid, make_spec, north_goal, sphere_f

import dexplan
import dexplan.ompl as dompl
from dexplan.core.errors import InvalidInputError, PlannerError, ScenarioError
from dexplan.model.scenario import checked_scenario
from dexplan.planning.ompl import PlanningProblem, registry

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = ROOT / "scenarios" / "paper_sphere.toml"


@pytest.fixture
def clean_registry():
    """Whatever a test registers is gone afterwards."""
    saved = (dict(registry.PLANNERS), dict(registry.PLANNER_TRAITS), dict(registry.PLANNER_NOTES))
    yield
    for live, old in zip(
        (registry.PLANNERS, registry.PLANNER_TRAITS, registry.PLANNER_NOTES), saved, strict=True
    ):
        live.clear()
        live.update(old)


# ------------------------------------------------------------------ the registry


def test_register_planner_with_params(clean_registry) -> None:
    dompl.register_planner("BiasedRRT", og.RRT, {"goal_bias": 0.25})
    assert "BiasedRRT" in dompl.available_planners()
    params = {p.name: p for p in dompl.planner_params("BiasedRRT")}
    assert params["goal_bias"].default == "0.25"  # set on every planner the factory makes
    assert params["range"].settable
    with pytest.raises(PlannerError, match="already registered"):
        dompl.register_planner("BiasedRRT", og.RRT)
    dompl.register_planner("BiasedRRT", og.RRT, {"goal_bias": 0.5}, replace=True)
    assert {p.name: p.default for p in dompl.planner_params("BiasedRRT")}["goal_bias"] == "0.5"


def test_register_planner_refuses_bad_input(clean_registry) -> None:
    with pytest.raises(PlannerError, match="did you mean 'goal_bias'"):
        dompl.register_planner("BadRRT", og.RRT, {"goal_bais": 0.2})
    with pytest.raises(PlannerError, match=r"not an ompl\.base\.Planner"):
        dompl.register_planner("NotAPlanner", lambda si: object())
    with pytest.raises(PlannerError, match="Python identifier"):
        dompl.register_planner("no spaces", og.RRT)
    with pytest.raises(PlannerError, match="raised ZeroDivisionError"):
        dompl.register_planner("Broken", lambda si: 1 / 0)
    with pytest.raises(PlannerError, match="multi_query=True but no growRoadmapPtc"):
        dompl.register_planner("FakePRM", og.RRT, traits=dompl.PlannerTraits(multi_query=True))
    dompl.register_planner("MyPRM", og.PRM, traits=dompl.PlannerTraits(multi_query=True))
    assert not {"BadRRT", "NotAPlanner", "Broken", "FakePRM"} & set(dompl.available_planners())


class StraightToGoal(ob.Planner):
    """A Python planner: the start, then one goal sample, when the motion between is valid."""

    def solve(self, ptc):
        si, pdef = self.getSpaceInformation(), self.getProblemDefinition()
        goal = si.allocState()
        pdef.getGoal().sampleGoal(goal)
        start = pdef.getStartState(0)
        if not si.checkMotion(start, goal):
            return ob.PlannerStatus(ob.PlannerStatus.TIMEOUT)
        path = og.PathGeometric(si)
        path.append(start)
        path.append(goal)
        pdef.addSolutionPath(path)
        return ob.PlannerStatus(ob.PlannerStatus.EXACT_SOLUTION)


@pytest.mark.timeout(300)
def test_a_registered_python_planner_plans_by_name(clean_registry, tmp_path: Path) -> None:
    dompl.register_planner("StraightToGoal", lambda si: StraightToGoal(si, "StraightToGoal"))
    scen = dexplan.load_scenario(SCENARIO)
    goal = dataclasses.replace(
        scen.goal,
        object_pose_xyzquat=[0, 0, 0.1, 0, 0, 0.08715574, 0.9961947],  # 10 deg yaw
    )
    plan = dexplan.plan(
        dataclasses.replace(scen, goal=goal), planner="StraightToGoal", quality="none"
    )
    assert plan.result.stats.planner == "StraightToGoal"
    assert plan.solved, plan.result.message
    assert plan.result.stats.gsn_status == "exact"  # the Python planner found the GSn path
    assert dexplan.verify(plan.save(tmp_path / "plan.json")).ok


def test_planner_names_get_a_case_insensitive_hint() -> None:
    with pytest.raises(PlannerError, match="did you mean 'RRTConnect'"):
        registry.check_planner_name("rrtconnect")
    with pytest.raises(PlannerError, match="did you mean 'KPIECE1'"):
        registry.check_planner_name("KPIECE")
    with pytest.raises(PlannerError, match="did you mean 'range'"):
        registry.check_planner("RRTConnect", {"rnage": 0.1})


def test_planner_params_come_from_ompl_declarations() -> None:
    for name in dompl.available_planners():
        params = dompl.planner_params(name)
        # the names are what OMPL's printSettings declares, and each one with a
        # suggested range has it in OMPL's own low:step:high or 0,1 form
        for p in params:
            assert p.range == "" or ":" in p.range or p.range == "0,1", (name, p)
    rrtc = {p.name: p for p in dompl.planner_params("RRTConnect")}
    assert rrtc["range"].range == "0.:1.:10000." and rrtc["intermediate_states"].range == "0,1"
    families = {n: registry.planner_traits(n).family for n in dompl.available_planners()}
    assert families["PRM"] == "roadmap" and families["FMT"] == "batch"
    assert families["BITstar"] == "informed" and families["RRTConnect"] == "tree"


# ------------------------------------------------------------------ ProblemSetup


def _circle_setup(goal_sampler: bool) -> dompl.ProblemSetup:
    """The toy sphere, planned in coordinates scaled by 4 (states come back unscaled)."""
    setup = dompl.ProblemSetup(make_spec(scale=np.full(3, 4.0)), is_valid, seed=3)
    setup.set_start(SOUTH)
    setup.set_goal(north_goal(np.random.default_rng(0), with_sampler=goal_sampler))
    return setup


@pytest.mark.timeout(60)
def test_problem_setup_takes_an_ompl_planner_object_and_unscales_states() -> None:
    setup = _circle_setup(goal_sampler=True)
    setup.set_planner(og.RRTConnect(setup.space_information))
    result = setup.solve(10.0)
    assert result.solved and result.planner == "RRTConnect"
    path = setup.solution_path()
    np.testing.assert_allclose(path[0], SOUTH, atol=1e-9)  # ambient, not scaled by 4
    assert np.linalg.norm(path[-1] - NORTH) <= 0.2
    assert all(abs(sphere_f(x)[0]) <= make_spec().tolerance for x in result.path)
    state = setup.new_state([0.0, 1.0, 0.0])
    np.testing.assert_allclose(setup.read_state(state), [0.0, 1.0, 0.0])


@pytest.mark.timeout(60)
def test_a_goal_without_sampler_says_what_is_missing() -> None:
    setup = _circle_setup(goal_sampler=False)
    result = setup.solve(2.0)  # RRTConnect (the default) grows a tree from the goal
    assert result.status == "invalid_goal" and not result.solved
    assert "GoalSpec(sample=...)" in result.message
    with pytest.raises(PlannerError, match="no solution"):
        setup.solution_path()


@pytest.mark.timeout(60)
@pytest.mark.parametrize("planner", ["RRTConnect", "PRM"])
def test_planning_problem_explains_a_goal_without_sampler(planner: str) -> None:
    problem = PlanningProblem(make_spec(), is_valid, planner=planner, seed=3)
    problem.set_start(SOUTH)
    problem.set_goal(north_goal(np.random.default_rng(0), with_sampler=False))
    result = problem.solve(2.0)
    assert result.status == "invalid_goal"
    assert f"{planner} needs goal states" in result.message
    assert "GoalSpec(sample=...)" in result.message


def test_set_planner_refuses_what_is_not_a_planner() -> None:
    setup = _circle_setup(goal_sampler=True)
    with pytest.raises(PlannerError, match=r"ompl\.base\.Planner or a planner name"):
        setup.set_planner(42)
    with pytest.raises(PlannerError, match="did you mean 'PRM'"):
        setup.set_planner("prm")


# ------------------------------------------------------------------ GSn setups


@pytest.fixture(scope="module")
def gsn_setup() -> dompl.SimpleSetup:
    return dompl.SimpleSetup(SCENARIO, seed=1)


def test_simple_setup_hands_over_gsn_in_scenario_units(gsn_setup) -> None:
    assert isinstance(gsn_setup.space_information, ob.SpaceInformation)
    assert isinstance(gsn_setup.problem_definition, ob.ProblemDefinition)
    x0 = gsn_setup.start_state
    assert x0.shape == (gsn_setup.dimension,) == (7 + gsn_setup.hand.nq,)
    scen = gsn_setup.scenario
    np.testing.assert_allclose(x0[:7], scen.start.object_pose_xyzquat, atol=1e-9)  # metres, XYZW
    assert np.all(x0[7:] >= gsn_setup.hand.lower) and np.all(x0[7:] <= gsn_setup.hand.upper)
    # the goal region samples grasps at the goal pose (tree planners need them)
    state = gsn_setup.new_state(x0)
    gsn_setup.problem_definition.getGoal().sampleGoal(state)
    goal = gsn_setup.read_state(state)
    assert dexplan.planning.planner.goal_reached(scen, goal[:7])[0]


def test_to_plan_refuses_a_path_that_is_not_a_gsn_path(gsn_setup) -> None:
    x0 = gsn_setup.start_state
    with pytest.raises(InvalidInputError, match="shape"):
        gsn_setup.to_plan(x0)
    moved = x0.copy()
    moved[2] += 0.01
    with pytest.raises(InvalidInputError, match=r"path\[0\] must be at the scenario's start"):
        gsn_setup.to_plan(np.stack([moved, x0]))
    off = x0.copy()
    off[7] += 0.3  # a finger joint: the fingertip leaves the object
    with pytest.raises(InvalidInputError, match=r"path\[1\] is not on GSn"):
        gsn_setup.to_plan(np.stack([x0, off]))


# ------------------------------------------------------------------ the Python API


def test_python_api_accepts_lists_and_tuples_and_checks_poses() -> None:
    scen = dexplan.load_scenario(SCENARIO)
    for pose in (
        [0, 0, 0.1, 0, 0, 1, 0],
        (0, 0, 0.1, 0, 0, 1, 0),
        np.array([0, 0, 0.1, 0, 0, 1, 0]),
    ):
        goal = dataclasses.replace(scen.goal, object_pose_xyzquat=pose)
        checked = checked_scenario(dataclasses.replace(scen, goal=goal))
        assert isinstance(checked.goal.object_pose_xyzquat, np.ndarray)
        np.testing.assert_allclose(checked.goal.object_pose_xyzquat, [0, 0, 0.1, 0, 0, 1, 0])
    bad = {
        "must have unit norm, got norm 1.41421": [0, 0, 0.1, 0, 0, 1, 1],
        "must be a list of 7 numbers, got 6 entries": (0, 0, 0.1, 0, 0, 1),
        "must be finite": [0, 0, 0.1, 0, 0, float("nan"), 1],
    }
    for needle, pose in bad.items():
        goal = dataclasses.replace(scen.goal, object_pose_xyzquat=pose)
        with pytest.raises(ScenarioError, match=f"^goal.object_pose_xyzquat .*{needle}"):
            dexplan.plan(dataclasses.replace(scen, goal=goal))  # refused before planning
    start = dataclasses.replace(scen.start, object_pose_xyzquat=(0, 0, 0.1, 0, 0, 0, 2))
    with pytest.raises(ScenarioError, match=r"^start\.object_pose_xyzquat quaternion"):
        dexplan.plan(dataclasses.replace(scen, start=start))
    goal = dataclasses.replace(scen.goal, angle_tol=-1.0)
    with pytest.raises(ScenarioError, match=r"^goal.angle_tol must be in \(0"):
        dexplan.plan(dataclasses.replace(scen, goal=goal))


# ------------------------------------------------------------------ exit noise


LEAKY = """
import sys
import dexplan.planning.ompl  # a library user's import
from ompl import base as ob, geometric as og
space = ob.RealVectorStateSpace(2)
bounds = ob.RealVectorBounds(2)
bounds.setLow(-1)
bounds.setHigh(1)
space.setBounds(bounds)
si = ob.SpaceInformation(space)
si.setStateValidityChecker(lambda s: True)
si.setup()
class Mine(ob.Planner):  # a Python planner: nanobind reports it alive at exit
    def solve(self, ptc):
        pdef = self.getProblemDefinition()
        path = og.PathGeometric(self.getSpaceInformation())
        path.append(pdef.getStartState(0))
        pdef.addSolutionPath(path)
        return ob.PlannerStatus(ob.PlannerStatus.EXACT_SOLUTION)
pdef = ob.ProblemDefinition(si)
a, b = si.allocState(), si.allocState()
a[0] = a[1] = 0.0
b[0] = b[1] = 0.5
pdef.setStartAndGoalStates(a, b)
planner = Mine(si, "Mine")
planner.setProblemDefinition(pdef)
planner.setup()
planner.solve(ob.timedPlannerTerminationCondition(1.0))
print("a line of the script's own", file=sys.stderr)
"""


@pytest.mark.parametrize("show", [False, True])
def test_nanobind_leak_report_is_not_shown_to_library_users(tmp_path: Path, show: bool) -> None:
    script = tmp_path / "leaky.py"
    script.write_text(textwrap.dedent(LEAKY))
    env = {"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"}
    if show:
        env["DEXPLAN_SHOW_LEAKS"] = "1"
    res = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=120, env=env
    )
    assert res.returncode == 0, res.stderr
    assert "a line of the script's own" in res.stderr  # the filter passes other lines
    assert ("nanobind: leaked" in res.stderr) == show  # and the report is really there
