"""Everything the planner builds from a scenario, in one place.

A :class:`PlanningContext` holds the models (hand, object, collision world),
the grasp subspace GSn, its validity checker and sampler, and the transfer and
regrasp local planners, all wired to one seeded random generator.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from dexplan.core.errors import DexplanError, ScenarioError
from dexplan.model.collision import CollisionWorld, Obstacle
from dexplan.model.grasp.grip_forces import (
    DEFAULT_GRAVITY,
    DEFAULT_MASS,
    ForceSettings,
)
from dexplan.model.grasp.holds import HoldChecker
from dexplan.model.hand.hand import Hand
from dexplan.model.objects import Shape, shape_from_dict
from dexplan.model.scenario import Scenario
from dexplan.planning.deadline import Deadline
from dexplan.planning.gsn.sampler import GraspSampler, SamplerSettings
from dexplan.planning.gsn.space import GraspSubspace
from dexplan.planning.gsn.validity import GraspValidity, ValiditySettings, let_go_problem
from dexplan.planning.local.transitions import Transitions, TransitionSettings

#: Corner points added to a landing search's candidates where faces alone
#: cannot hold (:attr:`TransitionSettings.landing_vertices`): a third of the
#: default edge points, about the corners' share of a cube's edge cones.
LANDING_VERTICES = 100


@dataclass
class PlanningContext:
    """Models and GSn machinery of one scenario.

    Attributes:
        scenario: the scenario it was built from.
        hand: the hand.
        obj: the object shape.
        world: collision world (hand, object, obstacles).
        gsn: the grasp subspace GSn (all fingers in contact).
        validity: GSn validity checker.
        sampler: RLG-style sampler of valid GSn states.
        transitions: transfer and regrasp local planners.
        rng: the sampler's random generator (the local planners have their own).
        deadline: the query's deadline, shared by the sampler and the local
            planners (the planner sets it; default: never).
        seed: the seed the streams were made from (module 2 seeds each link
            attempt's stream from it).
    """

    scenario: Scenario
    hand: Hand
    obj: Shape
    world: CollisionWorld
    gsn: GraspSubspace
    validity: GraspValidity
    sampler: GraspSampler
    transitions: Transitions
    rng: np.random.Generator
    deadline: Deadline
    seed: int = 0

    def reseed_local_planners(self, *key: int) -> None:
        """Give the local planners a fresh random stream seeded by ``key``.

        The planner starts the reduction on its own stream, so that how many
        module-2 link attempts the clock allowed never changes its choices.
        """
        self.transitions.rng = np.random.default_rng(list(key))


def build_hand(scenario: Scenario, *, check_contacts: bool = True) -> Hand:
    """The scenario's hand (builtin or URDF).

    Args:
        scenario: the problem.
        check_contacts: refuse a hand that could never let a finger go under
            the scenario's contact model (:func:`validity_settings`), so that
            the CLI says so before planning; False to build it anyway (to show
            the scenario).

    Raises:
        ScenarioError: with ``check_contacts``, no (n-1)-finger subgrasp can be
            force closure under the scenario's contact model, or a finger has
            1 joint (:func:`check_finger_joints`).
    """
    hand = Hand.from_spec(scenario.hand)
    if check_contacts:
        check_finger_joints(scenario, hand)
        validity_settings(scenario, hand.n_fingers)
    return hand


def check_finger_joints(scenario: Scenario, hand: Hand) -> None:
    """Refuse fingers of 1 joint: dexplan plans for fingers of 2 joints or more.

    A 1-joint fingertip sweeps a circle and touches an object at isolated
    points only: it could neither land on a contact nor follow a turning
    object. (A :class:`Hand` may have such fingers: plans of it can still be
    checked and shown.) Fingers of 2 joints have their contacts on a curve
    (:mod:`dexplan.planning.gsn.contact_curve`).

    Raises:
        ScenarioError: naming the first such finger's tip frame.
    """
    for tip, idx in zip(hand.fingertip_frames, hand.finger_q_index, strict=True):
        if len(idx) < 2:
            raise ScenarioError(
                f"scenario {scenario.name!r}: fingertip frame {tip!r} of hand {hand.name!r} "
                "is moved by 1 joint: dexplan plans for fingers of at least 2 joints "
                "(a 1-joint fingertip touches an object at isolated points only)"
            )


def validity_settings(scenario: Scenario, n_fingers: int) -> ValiditySettings:
    """The validity settings of a scenario (friction, contact model, margin).

    Raises:
        ScenarioError: no (n-1)-finger subgrasp of an ``n_fingers`` hand can be
            force closure under the scenario's contact model, e.g. 3 fingers with
            point contacts (:func:`~dexplan.planning.gsn.validity.let_go_problem`).
    """
    vset = ValiditySettings(
        mu=scenario.mu,
        friction_edges=scenario.friction_edges,
        fc_margin=scenario.fc_margin,
        contact_model=scenario.contact_model,
        torsion=scenario.torsion,
    )
    problem = let_go_problem(n_fingers, vset)
    if problem is not None:
        raise ScenarioError(f"scenario {scenario.name!r}: {problem}")
    return vset


def hold_checker(scenario: Scenario, hand: Hand, obj: Shape, vset: ValiditySettings) -> HoldChecker:
    """The holds of the scenario's plans (:mod:`dexplan.model.grasp.holds`).

    The scenario's object mass and gravity (the export's defaults where it
    gives none), its friction, contact model and hold shift: the local
    planners let a finger go only where the others hold the object within
    the scenario's share of the hand's effort limits (``[contact]
    hold_effort_share``; :meth:`Transitions.can_release`).
    """
    g = scenario.gravity
    settings = ForceSettings(
        mass=DEFAULT_MASS if scenario.object_mass is None else scenario.object_mass,
        gravity=DEFAULT_GRAVITY if g is None else (float(g[0]), float(g[1]), float(g[2])),
    )
    return HoldChecker(
        hand,
        obj,
        vset.mu,
        vset.friction_edges,
        vset.contact_model,
        vset.torsion,
        settings,
        shift_m=scenario.hold_shift,
        effort_share=scenario.hold_effort_share,
    )


def build_obstacles(scenario: Scenario) -> list[Obstacle]:
    """The scenario's obstacles."""
    out = []
    for ob in scenario.obstacles:
        shape = {k: v for k, v in ob.items() if k not in ("pose_xyzquat", "name")}
        out.append(
            Obstacle(
                shape_from_dict(shape, scenario.base_dir), tuple(ob["pose_xyzquat"]), ob["name"]
            )
        )
    return out


def build_context(
    scenario: Scenario,
    seed: int | None = None,
    *,
    transition_settings: TransitionSettings | None = None,
    sampler_settings: SamplerSettings | None = None,
    hand: Hand | None = None,
) -> PlanningContext:
    """Build hand, object, world, GSn, validity, sampler and local planners.

    Args:
        scenario: the problem.
        seed: random seed (defaults to the scenario's planner seed).
        transition_settings: local-planner settings.
        sampler_settings: sampler settings.
        hand: the scenario's hand if the caller has built it already
            (:func:`build_hand`); built here otherwise.

    Raises:
        ScenarioError: the models cannot be built from the scenario, or no
            (n-1)-finger subgrasp of the hand can be force closure under the
            scenario's contact model (:func:`let_go_problem`), or a finger has
            1 joint (:func:`check_finger_joints`).
    """
    try:
        hand = hand or build_hand(scenario, check_contacts=False)
        obj = shape_from_dict(dict(scenario.object), scenario.base_dir)
        world = CollisionWorld(hand, obj, build_obstacles(scenario))
    except ScenarioError:
        raise
    except DexplanError as exc:
        raise ScenarioError(f"scenario {scenario.name!r}: {exc}") from exc
    seed = scenario.planner.seed if seed is None else seed
    # Separate streams: how many samples OMPL draws (which can vary with PRM's
    # threads and the clock) never changes the local planners' choices.
    rng = np.random.default_rng([seed, 0])
    rng_local = np.random.default_rng([seed, 1])
    start_pos = scenario.start.object_pose_xyzquat[:3]
    goal_pos = scenario.goal.object_pose_xyzquat[:3]
    gsn = GraspSubspace(
        hand,
        obj,
        workspace_center=0.5 * (start_pos + goal_pos),
        workspace_half_extent=0.5 * np.abs(goal_pos - start_pos) + scenario.workspace_half_extent,
    )
    check_finger_joints(scenario, hand)
    vset = validity_settings(scenario, hand.n_fingers)
    validity = GraspValidity(gsn, world, vset)
    deadline = Deadline()
    sampler = GraspSampler(gsn, validity, rng, sampler_settings, deadline)
    transitions = Transitions(
        hand,
        obj,
        world,
        vset,
        transition_settings
        or TransitionSettings(
            contact_motion=scenario.contact_motion,
            # corners as landings too where faces alone cannot hold, as the sampler draws them
            landing_vertices=LANDING_VERTICES if sampler.faces_only is not None else 0,
        ),
        rng_local,
        deadline,
        hold_checker(scenario, hand, obj, vset),
    )
    return PlanningContext(
        scenario, hand, obj, world, gsn, validity, sampler, transitions, rng, deadline, seed
    )


def learning_scenario(scenario: Scenario) -> Scenario:
    """The scenario without its goal: the goal pose set to the start pose.

    The GSn bounds then are the ``[workspace]`` box around the start position,
    for every query whose goal lies in it (a query's own bounds contain them):
    the roadmap of a learning phase serves them all.
    """
    goal = dataclasses.replace(
        scenario.goal, object_pose_xyzquat=scenario.start.object_pose_xyzquat.copy()
    )
    return dataclasses.replace(scenario, goal=goal)


def learning_context(scenario: Scenario, seed: int, hand: Hand | None = None) -> PlanningContext:
    """The planning context of a roadmap's learning phase (:func:`learning_scenario`)."""
    return build_context(learning_scenario(scenario), seed, hand=hand)
