"""A scenario's GSn as an OMPL problem, set up for your own planner.

:class:`GsnSetup` is the problem module 1 solves, handed over the way
``og.SimpleSetup`` hands one over: the constrained state space of GSn (the
grasp subspace: object pose and hand joints with every fingertip on the
object), its ``SpaceInformation`` with dexplan's validity checker (joint
limits, collisions, force closure of every (n-1)-finger subgrasp) and the
RLG-style valid-state sampler, and a ``ProblemDefinition`` whose start is
the planner's start grasp and whose goal is the scenario's goal region,
sampled (tree planners that grow from the goal need goal states). States
are in scenario units: ``[x, y, z, qx, qy, qz, qw, q_0 ... q_{nq-1}]``,
metres, a quaternion XYZW, radians in the hand's planning order.
:func:`~dexplan.planning.path_plan.plan_path` turns a GSn path of yours into
a transfer/regrasp plan (``dexplan.ompl.SimpleSetup.to_plan``, verified).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dexplan.core.errors import PlannerError
from dexplan.core.typing import FloatArray
from dexplan.model.hand.hand import Hand
from dexplan.model.scenario import Scenario, checked_scenario
from dexplan.planning.context import PlanningContext, build_context
from dexplan.planning.gsn.space import POSE_DIM
from dexplan.planning.ompl import GoalSpec
from dexplan.planning.ompl.setup import ProblemSetup
from dexplan.planning.planner import goal_reached
from dexplan.planning.roadmap.problems import constraint_spec, orientation_projection
from dexplan.planning.start import start_state

__all__ = ["GsnSetup"]


class GsnSetup(ProblemSetup):
    """The GSn problem of a scenario, as OMPL objects (see the module notes).

    The start grasp is the one :func:`dexplan.plan` would start from with the
    same seed. The goal region is ``max(position error / position_tol,
    angle / angle_tol) <= 1`` around the goal pose; its sampler draws valid
    grasps at the goal pose.

    Args:
        scenario: the problem.
        seed: seeds the sampler, the start grasp and OMPL (default: the
            scenario's planner seed).
        hand: the scenario's hand, if already built.
        space: ``projected``, ``atlas`` or ``tangent_bundle`` (default: the
            scenario's ``[planner] space``).

    Attributes:
        scenario: the scenario.
        seed: the seed used.
        context: the models and GSn machinery
            (:class:`~dexplan.planning.context.PlanningContext`).
        start_state: ``(7 + nq,)`` the start grasp.

    Raises:
        ScenarioError: the models cannot be built.
        PlannerError: no valid grasp at the start pose.
    """

    def __init__(
        self,
        scenario: Scenario,
        *,
        seed: int | None = None,
        hand: Hand | None = None,
        space: str | None = None,
    ) -> None:
        scenario = checked_scenario(scenario)
        self.scenario = scenario
        self.seed = scenario.planner.seed if seed is None else int(seed)
        self.context: PlanningContext = build_context(scenario, self.seed, hand=hand)
        ctx = self.context
        super().__init__(
            constraint_spec(ctx, space or scenario.planner.space),
            ctx.validity.is_valid,
            valid_sampler=ctx.sampler.sample,
            check_sampled_states=False,  # the sampler returns checked states
            projection=orientation_projection(),
            seed=self.seed,
        )
        x0 = start_state(ctx, rng=np.random.default_rng([self.seed, 5]))
        if x0 is None:
            raise PlannerError(
                f"scenario {scenario.name!r}: no valid grasp found at the start pose"
            )
        self.start_state: FloatArray = x0
        self.set_start(x0)
        goal_pose = scenario.goal.object_pose_xyzquat

        def distance(x: FloatArray) -> float:
            return goal_reached(scenario, x[:POSE_DIM])[1]

        def sample() -> Any:
            return ctx.sampler.sample_at_pose(goal_pose)

        self.set_goal(GoalSpec(distance=distance, threshold=1.0, sample=sample))

    @property
    def hand(self) -> Hand:
        """The hand model."""
        return self.context.hand

    def object_pose(self, x: object) -> FloatArray:
        """The object pose ``(7,)`` (metres, quaternion XYZW) of a GSn state ``(7 + nq,)``."""
        return np.asarray(x, dtype=np.float64)[:POSE_DIM].copy()

    def hand_joints(self, x: object) -> FloatArray:
        """The hand joints ``(nq,)`` (radians, planning order) of a GSn state ``(7 + nq,)``."""
        return np.asarray(x, dtype=np.float64)[POSE_DIM:].copy()

    @property
    def planner_name(self) -> str:
        """The name of the planner set (its ``getName()``), or ``"user"`` before one is."""
        return str(self.planner.getName()) if self.planner is not None else "user"
