"""The OMPL problems of module 1: GSn with its constraint, or its contact chart.

:func:`gsn_problem` hands OMPL the GSn constraint (:func:`constraint_spec`),
the validity checker and the RLG-style sampler; :func:`chart_problem` gives
tree planners GSn's contact chart instead (:mod:`dexplan.planning.gsn.chart`),
where the space's own sampler draws grasps. :func:`search_problem` picks one
for a query and sets its start and goal.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from typing import Any, cast

import numpy as np

from dexplan.core.typing import FloatArray
from dexplan.planning.context import PlanningContext
from dexplan.planning.gsn.chart import ChartProblem, ContactChart, DirectionCaps
from dexplan.planning.gsn.space import POSE_DIM
from dexplan.planning.local.contact_paths import ContactPaths
from dexplan.planning.local.geodesic_motion import GeodesicFallback
from dexplan.planning.ompl import (
    ConstraintSpec,
    GoalSpec,
    PlanningProblem,
    ProjectionSpec,
    planner_traits,
)
from dexplan.planning.ompl.spaces import SpaceKind
from dexplan.planning.roadmap.search import GsnQuery

__all__ = [
    "CHART_RANGE",
    "GEODESIC_MOTIONS",
    "chart_problem",
    "constraint_spec",
    "direction_caps",
    "geodesic_fallback",
    "gsn_problem",
    "orientation_projection",
    "rlg_states",
    "search_problem",
    "searched_space",
]


CHART_RANGE = 0.5
"""Default ``range`` of tree planners on the contact chart (planning units)."""

GEODESIC_MOTIONS = True
"""Whether module 1 on meshes adds the section VI motion to OMPL's (:func:`geodesic_fallback`)."""

CAP_HALF_ANGLE = math.radians(75.0)
"""Half angle of the chart's direction caps (rad)."""

CAP_SAMPLES = 16
"""RLG states whose contact directions (with the start's) centre the chart's caps."""


def constraint_spec(ctx: PlanningContext, space: str) -> ConstraintSpec:
    """The GSn constraint for OMPL, with coordinates scaled so steps mean something.

    Positions are scaled by ``1 / (2 * characteristic length)``: an object move
    of a fingertip-contact's worth of arc counts like a 0.05 rad rotation.
    """
    gsn = ctx.gsn
    scale = np.ones(gsn.ambient_dim)
    scale[:3] = 1.0 / (2.0 * ctx.obj.characteristic_length)
    return ConstraintSpec(
        ambient_dim=gsn.ambient_dim,
        co_dim=gsn.co_dim,
        function=gsn.function,
        jacobian=gsn.jacobian,
        lower=gsn.lower,
        upper=gsn.upper,
        tolerance=1e-5,
        space=cast(SpaceKind, space),  # ConstraintSpec checks the name
        scale=scale,
        delta=0.15,
    )


def orientation_projection() -> ProjectionSpec:
    """KPIECE grid projection: the object's orientation (canonical quaternion x, y, z).

    Reorientation is what the task is about, so cells split the rotation group;
    0.1 per cell is about 11 degrees.
    """

    def project(x: FloatArray) -> FloatArray:
        q = x[3:7]
        return -q[:3] if q[3] < 0 else q[:3]

    return ProjectionSpec(
        3, project, cell_sizes=np.full(3, 0.1), lower=-np.ones(3), upper=np.ones(3)
    )


def gsn_problem(
    ctx: PlanningContext,
    planner: str,
    params: Mapping[str, Any] | None,
    space: str,
    seed: int,
) -> PlanningProblem:
    """The OMPL problem over GSn: the constraint, the validity checker and the RLG sampler.

    On meshes the PRM family joins milestones with the paper's section VI
    motion where OMPL's projected one fails (:func:`geodesic_fallback`).
    """
    return PlanningProblem(
        constraint_spec(ctx, space),
        ctx.validity.is_valid,
        planner=planner,
        params=dict(params or {}),
        valid_sampler=ctx.sampler.sample,
        check_sampled_states=False,  # the sampler returns checked states
        projection=orientation_projection(),
        seed=seed,
        motion_fallback=geodesic_fallback(ctx) if planner_traits(planner).multi_query else None,
    )


def geodesic_fallback(ctx: PlanningContext) -> GeodesicFallback | None:
    """Module 1's second GSn motion on a mesh: contacts along surface geodesics, or None.

    None for the primitives and meshes without geodesics (the projected
    motion is then the only one), for hands with redundant fingers (more
    than 3 joints: their IK's free joint is tabulated, so the motion would
    end beside ``b``'s joints, not on them, and never join), and when
    :data:`GEODESIC_MOTIONS` is off.
    """
    if not GEODESIC_MOTIONS:
        return None
    if any(len(ix) > 3 for ix in ctx.hand.finger_q_index):
        return None
    paths = ContactPaths(ctx.obj)
    return GeodesicFallback(ctx.transitions, ctx.validity, paths) if paths.active else None


def search_problem(
    ctx: PlanningContext,
    query: GsnQuery,
    planner: str,
    params: Mapping[str, Any] | None,
    space: str,
    seed: int,
) -> PlanningProblem | ChartProblem:
    """The OMPL problem of a query, with its start and goal.

    Tree planners search the contact chart (:func:`chart_problem`) when it
    represents the start state; the PRM family (which draws the RLG
    sampler's states) and unrepresentable starts use :func:`gsn_problem`.
    """

    def distance(x: FloatArray) -> float:
        return query.goal_test(x)[1]

    if not planner_traits(planner).multi_query:
        charted = chart_problem(ctx, planner, params, space, seed, query.start)
        if charted is not None:
            charted.set_query(query.start, distance, 1.0, query.goal_sampler)
            return charted
    problem = gsn_problem(ctx, planner, params, space, seed)
    problem.set_start(query.start)
    problem.set_goal(GoalSpec(distance=distance, threshold=1.0, sample=query.goal_sampler))
    return problem


def searched_space(planner: str) -> tuple[str, str]:
    """What module 1 gives ``planner`` to search, and why: ``(space, reason)``.

    As :func:`search_problem` decides: the PRM family searches GSn itself,
    every other planner GSn's contact chart when it represents the start.
    """
    traits = planner_traits(planner)
    if traits.multi_query:
        return (
            "GSn",
            "it draws dexplan's RLG-style grasp sampler, and the ompl binding takes a "
            "Python sampler only from planners that ask for valid states (the PRM family)",
        )
    how = "the contact chart"
    if traits.r_n_sampler:
        how += " without unit-sphere rows (its informed sampler treats the space as R^n)"
    if traits.capped:
        how += ", each finger's direction within a 75 degree cap"
    return (
        how,
        "it draws OMPL's own uniform samples, which rarely project onto a valid grasp in "
        "GSn's ambient space and always are one on the chart; GSn itself when the chart "
        "cannot represent the start (an object not star-shaped from its origin)",
    )


def chart_problem(
    ctx: PlanningContext,
    planner: str,
    params: Mapping[str, Any] | None,
    space: str,
    seed: int,
    start: FloatArray,
) -> ChartProblem | None:
    """The OMPL problem over GSn's contact chart (:mod:`dexplan.planning.gsn.chart`), or None.

    None when rays from the object's origin do not parameterise its surface,
    or when the chart does not map the start state back onto itself (within
    1e-7). Planners with a ``range`` get :data:`CHART_RANGE` unless ``params``
    sets one. Planners with capped charts
    (:attr:`~dexplan.planning.ompl.registry.PlannerTraits.capped`) get direction
    caps (:func:`direction_caps`) when the capped chart represents the start.
    """
    if not ContactChart.applies(ctx.gsn):
        return None
    traits = planner_traits(planner)
    spheres = not traits.r_n_sampler  # an R^n informed sampler: no unit-sphere rows
    chart = ContactChart(ctx.gsn, ctx.validity.is_valid, spheres=spheres)
    if chart.round_trip_error(start) > 1e-7:
        return None
    if traits.capped:
        caps = direction_caps(ctx, chart, start, CAP_HALF_ANGLE)
        if caps is not None:
            capped = ContactChart(ctx.gsn, ctx.validity.is_valid, spheres=spheres, caps=caps)
            if capped.represents(start):
                chart = capped
    problem = PlanningProblem(
        chart.constraint_spec(1.0 / (2.0 * ctx.obj.characteristic_length), space),
        chart.is_valid_chart,
        planner=planner,
        params=dict(params or {}),
        projection=orientation_projection(),
        seed=seed,
    )
    if "range" not in (params or {}) and "range" in problem.parameters():
        problem.set_param("range", CHART_RANGE)
    return ChartProblem(chart, problem)


def direction_caps(
    ctx: PlanningContext, chart: ContactChart, start: FloatArray, half_angle: float
) -> DirectionCaps | None:
    """Caps about each finger's mean chart direction, over the start and RLG states.

    The mean of the start's directions and those of up to
    :data:`CAP_SAMPLES` states of the RLG sampler (valid grasps anywhere in
    the workspace): where the hand's fingers touch objects in this scene.
    None when a finger's directions scatter so that their mean is shorter
    than 0.2 (no cap about it would keep its states).
    """
    states = [start, *rlg_states(ctx, CAP_SAMPLES, ctx.deadline.at)]
    k = chart.k
    dirs = np.array([chart.to_chart(x)[POSE_DIM : POSE_DIM + 3 * k].reshape(k, 3) for x in states])
    mean = dirs.mean(axis=0)
    length = np.linalg.norm(mean, axis=1, keepdims=True)
    if np.any(length < 0.2):
        return None
    return DirectionCaps(mean / length, half_angle)


def rlg_states(ctx: PlanningContext, count: int, deadline: float) -> list[FloatArray]:
    """Up to ``count`` valid GSn states ``(7 + nq,)`` of the RLG sampler.

    At most ``4 * count`` draws, none at or past ``deadline``
    (``time.perf_counter()``); used for the chart's caps and module 2's
    waypoints.
    """
    out: list[FloatArray] = []
    for _ in range(4 * count):
        if len(out) >= count or time.perf_counter() >= deadline:
            break
        x = ctx.sampler.sample()
        if x is not None:
            out.append(x)
    return out
