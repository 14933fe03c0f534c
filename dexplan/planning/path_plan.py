"""A transfer/regrasp plan from a GSn path found elsewhere: modules 2 and 3 on it.

A user's own OMPL planner (on :class:`~dexplan.planning.gsn_setup.GsnSetup`'s
space, or anywhere) returns a GSn path; :func:`plan_path` makes of it what
:func:`~dexplan.planning.planner.plan` makes of module 1's: module 2 joins
what the path does not (segments that are not valid GSn motions, an end
outside the goal region) with transfer-regrasp links
(:func:`~dexplan.planning.roadmap.given_path.link_given_path`), then the
reduction, smoothing and the final check run as for any query.
"""

from __future__ import annotations

import numpy as np

from dexplan.core.errors import InvalidInputError
from dexplan.core.pose import quat_angle
from dexplan.core.typing import FloatArray
from dexplan.model.hand.hand import Hand
from dexplan.model.scenario import Scenario, checked_scenario
from dexplan.planning.gsn.space import POSE_DIM
from dexplan.planning.planner import REDUCTIONS, PlanResult, QueryRun, Verifier
from dexplan.planning.progress import PlanStatus, Progress
from dexplan.planning.roadmap.given_path import link_given_path
from dexplan.planning.roadmap.problems import gsn_problem

__all__ = ["START_TOLERANCE", "plan_path"]

START_TOLERANCE = 1e-6
"""How far (m, rad) the path's first object pose may be from the scenario's start pose."""


def plan_path(
    scenario: Scenario,
    path: object,
    *,
    planner: str = "user",
    seed: int | None = None,
    time_limit: float | None = None,
    reduction: str = "auto",
    progress: Progress | None = None,
    verify: Verifier | None = None,
    hand: Hand | None = None,
) -> PlanResult:
    """Module 2, the reduction and the check on ``path``, a GSn path from the start.

    Args:
        scenario: the problem the path solves.
        path: ``(K, 7 + nq)`` GSn states in scenario units (object position
            in metres, quaternion XYZW, hand joints in radians, in the hand's
            planning order), each a valid grasp, the first at the scenario's
            start pose; the last need not reach the goal region (module 2
            links on).
        planner: the name of the planner that found it (the plan's statistics).
        seed: seeds module 2 and the reduction (default: the scenario's).
        time_limit: seconds for modules 2 and 3 (default: the scenario's).
        reduction: as :func:`~dexplan.planning.planner.plan` takes it.
        progress: called at each stage.
        verify: the independent check of the finished plan (see
            :func:`~dexplan.planning.planner.plan`).
        hand: the scenario's hand, if already built.

    Returns:
        A :class:`~dexplan.planning.planner.PlanResult` (``no_gsn_path`` when
        module 2 cannot join the path to the goal region).

    Raises:
        InvalidInputError: a malformed path, a state that is not a valid
            grasp, or a first state away from the start pose; an unknown
            ``reduction``.
    """
    if reduction not in REDUCTIONS:
        raise InvalidInputError(
            f"reduction must be one of {', '.join(REDUCTIONS)}, got {reduction!r}"
        )
    scenario = checked_scenario(scenario)
    spec = scenario.planner
    seed = spec.seed if seed is None else seed
    run = QueryRun(
        scenario,
        planner,
        seed,
        spec.time_limit if time_limit is None else time_limit,
        None,
        progress,
        hand,
    )
    states = _checked_path(run, path)
    run.q0 = states[0][POSE_DIM:]
    problem = gsn_problem(run.ctx, "RRTConnect", None, spec.space, seed)

    def geodesic(a: FloatArray, b: FloatArray) -> FloatArray | None:
        checked = problem.check_path(np.stack([a, b]), interpolate=True)
        return np.asarray(checked.path) if checked.path_valid else None

    draws = [0, 0]
    gsn = link_given_path(
        run.ctx, states, run.gsn_query(states[0], draws), geodesic, run.deadline, planner
    )
    run.note(**gsn.stats, goal_samples=draws[1])
    run.roadmap = gsn.roadmap
    if gsn.path is None:
        return run.result(PlanStatus.NO_GSN_PATH, gsn.message, start_q=run.q0)
    red = run.reduce(gsn, reduction)
    run.note(explorations=0)
    if not red.success:
        return run.result(
            PlanStatus.REDUCTION_FAILED, red.reason or "", gsn_path=gsn.path, start_q=run.q0
        )
    return run.finish(run.smooth(red), gsn.path, verify)


def _checked_path(run: QueryRun, path: object) -> FloatArray:
    """``path`` as ``(K, 7 + nq)`` valid grasps from the start pose, or raise."""
    ctx = run.ctx
    n = ctx.gsn.ambient_dim
    try:
        states = np.array(path, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"path must be a (K, {n}) array of GSn states: {exc}") from exc
    if states.ndim != 2 or states.shape[1] != n or states.shape[0] < 1:
        raise InvalidInputError(f"path must have shape (K, {n}), got {states.shape}")
    if not np.all(np.isfinite(states)):
        raise InvalidInputError("path must be finite")
    start = run.scenario.start.object_pose_xyzquat
    first = states[0, :POSE_DIM]
    off = max(
        float(np.linalg.norm(first[:3] - start[:3])),
        quat_angle(first[3:] / np.linalg.norm(first[3:]), start[3:]),
    )
    if off > START_TOLERANCE:
        raise InvalidInputError(
            f"path[0] must be at the scenario's start pose, it is {off:.3g} (m or rad) away"
        )
    for k, x in enumerate(states):
        residual = ctx.gsn.residual(x)
        if residual > 1e-4:
            raise InvalidInputError(
                f"path[{k}] is not on GSn (constraint residual {residual:.3g} > 1e-4)"
            )
        verdict = ctx.validity.check(x)
        if not verdict.valid:
            raise InvalidInputError(f"path[{k}] is not a valid grasp: {verdict.reason}")
    return states
