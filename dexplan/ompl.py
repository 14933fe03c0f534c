"""dexplan as an OMPL plug-in: the GSn problem as OMPL objects, your planners, your paths.

``import dexplan.ompl as dompl`` gives what an OMPL user looks for, under
the names OMPL uses::

    from ompl import geometric as og
    import dexplan.ompl as dompl

    setup = dompl.SimpleSetup("scenarios/paper_sphere.toml", seed=1)
    si = setup.space_information          # ob.SpaceInformation over GSn
    setup.set_planner(og.KPIECE1(si))     # any ob.Planner, a Python one too
    result = setup.solve(10.0)            # a SolveResult
    path = setup.solution_path()          # (K, 7 + nq): metres, XYZW, radians
    plan = setup.to_plan(path)            # module 2 + reduction + verification
    plan.save("plan.json")

    dompl.register_planner("MyRRT", lambda si: og.RRT(si), {"goal_bias": 0.2})
    dexplan.plan("scenarios/paper_sphere.toml", planner="MyRRT")

The module is called ``dexplan.ompl`` because that is where an OMPL user
looks; it does not import ``ompl`` itself (only
:mod:`dexplan.planning.ompl` does, the adapter this module re-exports
from), so ``import ompl`` inside it or next to it means the real OMPL.
See docs/ompl.md.
"""

from __future__ import annotations

from pathlib import Path

from dexplan.api import Plan, plan_path
from dexplan.model.hand.hand import Hand
from dexplan.model.scenario import Scenario, default_scenario, load_scenario
from dexplan.planning.gsn_setup import GsnSetup
from dexplan.planning.ompl import (
    GoalSpec,
    PathCheck,
    PlannerTraits,
    SolveResult,
    available_planners,
    get_log_level,
    set_log_level,
)
from dexplan.planning.ompl.param_declarations import ParamInfo, planner_params
from dexplan.planning.ompl.registry import PlannerFamily, register_planner
from dexplan.planning.ompl.setup import ProblemSetup
from dexplan.planning.progress import Progress

__all__ = [
    "GoalSpec",
    "GsnSetup",
    "ParamInfo",
    "PathCheck",
    "PlannerFamily",
    "PlannerTraits",
    "ProblemSetup",
    "SimpleSetup",
    "SolveResult",
    "available_planners",
    "get_log_level",
    "plan_path",
    "planner_params",
    "register_planner",
    "set_log_level",
]


class SimpleSetup(GsnSetup):
    """The GSn problem of a scenario as OMPL objects, and :meth:`to_plan`.

    See :class:`~dexplan.planning.gsn_setup.GsnSetup` for what it holds.

    Args:
        scenario: a :class:`~dexplan.model.scenario.scenario.Scenario`, a
            scenario TOML path, or None for the paper's experiment.
        seed: seeds the sampler, the start grasp and OMPL (default: the scenario's).
        hand: the scenario's hand, if already built.
        space: ``projected``, ``atlas`` or ``tangent_bundle`` (default: the scenario's).

    Raises:
        DexplanError: bad scenario, or no valid grasp at the start pose.
    """

    def __init__(
        self,
        scenario: Scenario | str | Path | None = None,
        *,
        seed: int | None = None,
        hand: Hand | None = None,
        space: str | None = None,
    ) -> None:
        if scenario is None:
            scenario = default_scenario()
        elif not isinstance(scenario, Scenario):
            scenario = load_scenario(scenario)
        super().__init__(scenario, seed=seed, hand=hand, space=space)

    def to_plan(
        self,
        path: object,
        *,
        planner: str | None = None,
        time_limit: float | None = None,
        reduction: str = "auto",
        progress: Progress | None = None,
        quality: str = "full",
    ) -> Plan:
        """Your GSn path ``(K, 7 + nq)`` from :attr:`start_state` as a verified plan.

        Module 2 joins what the path leaves unjoined (segments that are not
        valid GSn motions, an end short of the goal region), the reduction
        turns it into transfers and regrasps, and the plan-file verifier
        checks the result: ``plan.solved`` only when it passes.

        Args:
            path: GSn states in scenario units, ``path[0]`` at the start pose
                (``solution_path()`` of a solve, or your own).
            planner: the name recorded in the plan's statistics (default: the
                planner set's ``getName()``).
            time_limit: seconds for module 2 and the reduction (default: the scenario's).
            reduction: ``auto``, ``gaits`` or ``edges``.
            progress: called at each stage.
            quality: ``full``, ``fast`` or ``none`` (see :func:`dexplan.plan`).

        Raises:
            DexplanError: a malformed path, or a state that is not a valid grasp.
        """
        return plan_path(
            self.scenario,
            path,
            planner=planner or self.planner_name,
            seed=self.seed,
            time_limit=time_limit,
            reduction=reduction,
            progress=progress,
            hand=self.hand,
            quality=quality,
        )
