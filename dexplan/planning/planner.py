"""The manipulation planner: module 1 (GSn roadmap), module 2 (links), reduction.

A query runs in three stages:

1. **Module 1** (:mod:`dexplan.planning.roadmap`): an OMPL planner explores
   GSn from the start state towards the goal region (single query), or a
   loaded roadmap answers the query (multi query).
2. **Module 2**: when start and goal are in different GSn components, the
   components are linked by transfer-regrasp sequences (the same local
   planners as the reduction).
3. **Reduction and smoothing**: the object trajectory of the GSn path is
   shortcut, reduced to transfer and regrasp segments (finger gaits), needless
   regrasps are merged, and the result is checked by the plan verifier before
   it is returned.

"No plan" is a result with a status, not an exception.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dexplan.exceptions import InvalidInputError
from dexplan.hand import Hand
from dexplan.planning.context import PlanningContext, build_context
from dexplan.planning.diagnostics import Rejections
from dexplan.planning.gsn import POSE_DIM
from dexplan.planning.ompl import check_planner
from dexplan.planning.plan_stats import PlanStats
from dexplan.planning.progress import PlanStatus, Progress, ProgressEvent, Stage
from dexplan.planning.reduction import grasp_from_state, reduce_gsn_path, reduce_object_path
from dexplan.planning.roadmap import GsnQuery, Roadmap, explore_gsn, query_roadmap
from dexplan.planning.smoothing import drop_regrasps, merge_regrasps, shortcut_object_path
from dexplan.planning.transitions import densify_poses
from dexplan.pose import quat_angle
from dexplan.scenario import Scenario
from dexplan.segments import Segment, count_kinds, object_path_length
from dexplan.typing import FloatArray

Verifier = Callable[["PlanResult"], Sequence[str]]
"""Checks a finished plan; returns its violations (empty: the plan is valid)."""

REDUCTIONS = ("auto", "gaits", "edges")
"""Reduction methods accepted by :func:`plan`."""

VERIFY_RESERVE = 0.05
"""Fraction of the time limit kept for the final verification: the search
stages (start grasp, module 1 and 2, reduction, smoothing) stop at
``(1 - VERIFY_RESERVE) * time_limit``, so the whole query ends within its limit."""


@dataclass(frozen=True)
class PlanResult:
    """Outcome of :func:`plan`.

    Attributes:
        status: how the query ended (a :class:`PlanStatus`, equal to its string).
        segments: transfer/regrasp segments (empty unless solved).
        start_pose: (7,) start object pose. start_q: (nq,) start hand joints.
        gsn_path: (K, 7 + nq) the GSn path the plan reduces (may be empty).
        roadmap: the GSn roadmap built or used.
        stats: figures for the plan file and benchmarks.
        message: human-readable detail on failure.
        rejections: what the sampler and the validity checker rejected, and why.
        violations: for ``invalid_plan``, the verifier's findings (the
            segments are kept, so the plan can be inspected).
    """

    status: PlanStatus
    segments: tuple[Segment, ...]
    start_pose: FloatArray
    start_q: FloatArray | None
    gsn_path: FloatArray
    roadmap: Roadmap | None
    stats: PlanStats
    message: str = ""
    rejections: Rejections | None = None
    violations: tuple[str, ...] = ()

    @property
    def solved(self) -> bool:
        """True when a verified plan was found."""
        return self.status == PlanStatus.SOLVED


def goal_reached(scenario: Scenario, pose: FloatArray) -> tuple[bool, float]:
    """Whether an object pose is in the goal region, and a distance to it.

    The distance is ``max(position error / position_tol, angle / angle_tol)``,
    so the region is ``distance <= 1``; q and -q are the same orientation.
    """
    g = scenario.goal
    dp = float(np.linalg.norm(pose[:3] - g.object_pose_xyzquat[:3]))
    da = quat_angle(pose[3:7], g.object_pose_xyzquat[3:])
    d = max(dp / g.position_tol, da / g.angle_tol)
    return d <= 1.0, d


def _reduction_schedule(reduction: str) -> Iterator[tuple[str, str]]:
    """Reduction attempts ``(method, trajectory)`` in order, until one succeeds.

    Gaits on the shortcut trajectory first (fewest segments), then on the raw
    GSn trajectory in case the shortcut is the trouble, both once more with
    new random landings (a retry usually works and gives far fewer regrasps
    than the edges), then the edge-by-edge reduction with bisection, then
    gaits twice more. Measured: what fails that often keeps failing.
    """
    if reduction == "edges":
        yield "edges", "gsn"
        return
    yield from (("gaits", "shortcut"), ("gaits", "raw")) * 2
    if reduction == "auto":
        yield "edges", "gsn"
    yield from (("gaits", "shortcut"), ("gaits", "raw")) * 2


def start_state(ctx: PlanningContext, attempts: int = 400) -> FloatArray | None:
    """The start GSn state: the scenario's ``start.q`` (checked) or a sampled grasp.

    Raises:
        InvalidInputError: ``start.q`` has the wrong size or is not a valid grasp.
    """
    spec = ctx.scenario.start
    pose = spec.object_pose_xyzquat
    if spec.q is not None:
        if spec.q.shape != (ctx.hand.nq,):
            raise InvalidInputError(
                f"start.q must have {ctx.hand.nq} entries, got {spec.q.shape[0]}"
            )
        x = ctx.gsn.join(pose, spec.q)
        res = ctx.gsn.residual(x)
        if res > 1e-3:
            raise InvalidInputError(
                f"start.q does not put every fingertip on the object (error {res:.4g} m)"
            )
        verdict = ctx.validity.check(x)
        if not verdict.valid:
            raise InvalidInputError(f"start.q is not a valid grasp: {verdict.reason}")
        return x
    for _ in range(max(1, attempts // ctx.sampler.settings.max_attempts)):
        if ctx.deadline.expired():
            return None
        x = ctx.sampler.sample_at_pose(pose)
        if x is not None:
            return x
    return None


def plan(
    scenario: Scenario,
    *,
    planner: str | None = None,
    seed: int | None = None,
    time_limit: float | None = None,
    roadmap: Roadmap | None = None,
    progress: Progress | None = None,
    reduction: str = "auto",
    verify: Verifier | None = None,
    hand: Hand | None = None,
) -> PlanResult:
    """Plan a manipulation path for a scenario.

    Args:
        scenario: the problem.
        planner: OMPL planner name (defaults to the scenario's).
        seed: random seed (defaults to the scenario's).
        time_limit: seconds for the whole query (defaults to the scenario's).
        roadmap: a roadmap from an earlier run (multi-query); it is extended
            only when it cannot answer.
        progress: called with a :class:`ProgressEvent` at each stage.
        reduction: how the GSn path becomes transfers and regrasps: ``gaits``
            (follow the object trajectory with finger gaits,
            :func:`~dexplan.planning.reduction.reduce_object_path`), ``edges``
            (the reduction property edge by edge with bisection,
            :func:`~dexplan.planning.reduction.reduce_gsn_path`) or ``auto``
            (gaits, then edges when gaits fail).
        verify: the independent check of the finished plan (the plan-file
            verifier, which lives in a layer below planning: the caller passes
            it, see :func:`dexplan.api.plan`); a plan it finds violations in is
            returned as ``invalid_plan``, never as solved. None: not checked.
        hand: the scenario's hand, if the caller has built it already.

    Returns:
        A :class:`PlanResult`; with ``verify``, every solved plan has passed it.

    Raises:
        InvalidInputError: unknown ``reduction`` or planner name.
    """
    t0 = time.perf_counter()
    if reduction not in REDUCTIONS:
        raise InvalidInputError(
            f"reduction must be one of {', '.join(REDUCTIONS)}, got {reduction!r}"
        )

    def say(stage: Stage, message: str, **counts: int) -> None:
        if progress is not None:
            progress(ProgressEvent(stage, message, time.perf_counter() - t0, counts))

    spec = scenario.planner
    planner = planner or spec.name
    seed = spec.seed if seed is None else seed
    time_limit = spec.time_limit if time_limit is None else time_limit
    if roadmap is None:
        check_planner(planner, spec.params)  # bad names fail before any work
    ctx = build_context(scenario, seed, hand=hand)
    # every stage watches one deadline (the sampler, goal sampling and the
    # local planners read it too), keeping a reserve for the verification
    deadline = t0 + (1.0 - VERIFY_RESERVE) * time_limit
    ctx.deadline.at = deadline
    stats: dict[str, Any] = {"planner": planner, "seed": seed, "time_limit": time_limit}
    pose0 = scenario.start.object_pose_xyzquat

    def result(status: PlanStatus, message: str = "", **kw: Any) -> PlanResult:
        stats["time_s"] = time.perf_counter() - t0
        stats["sampler"] = ctx.sampler.stats.as_dict()
        stats["validity"] = ctx.validity.stats.as_dict()
        typed = PlanStats.from_mapping(stats)
        kw.setdefault("segments", ())
        kw.setdefault("gsn_path", np.zeros((0, ctx.gsn.ambient_dim)))
        kw.setdefault("roadmap", roadmap)
        kw.setdefault("start_q", None)
        rejections = Rejections.from_stats(ctx.sampler.stats, ctx.validity.stats)
        return PlanResult(
            status, start_pose=pose0, stats=typed, message=message, rejections=rejections, **kw
        )

    say(Stage.START_GRASP, "sampling a start grasp")
    x_start = start_state(ctx)
    if x_start is None:
        why = " within the time limit" if ctx.deadline.expired() else ""
        return result(PlanStatus.NO_START_GRASP, f"no valid grasp found at the start pose{why}")
    q_start = x_start[POSE_DIM:]

    goal_draws = [0, 0]  # calls, valid states: tells "no goal grasp" from "no path"

    def goal_sampler() -> FloatArray | None:
        x = ctx.sampler.sample_at_pose(scenario.goal.object_pose_xyzquat)
        goal_draws[0] += 1
        goal_draws[1] += x is not None
        return x

    query = GsnQuery(
        start=x_start,
        goal_test=lambda x: goal_reached(scenario, x[:POSE_DIM]),
        goal_sampler=goal_sampler,
    )
    say(Stage.MODULE1, f"module 1: exploring GSn with {planner}")
    if roadmap is None:
        gsn = explore_gsn(
            ctx, query, planner, params=spec.params, space=spec.space, seed=seed, deadline=deadline
        )
    else:
        gsn = query_roadmap(ctx, roadmap, query, deadline=deadline)
    stats.update(gsn.stats)
    roadmap = gsn.roadmap
    stats["goal_samples"] = goal_draws[1]
    if gsn.path is None:
        if goal_draws[0] and not goal_draws[1]:
            msg = f"no valid grasp found at the goal pose ({goal_draws[0]} sampler calls)"
            return result(PlanStatus.NO_GOAL_GRASP, msg, roadmap=roadmap, start_q=q_start)
        return result(PlanStatus.NO_GSN_PATH, gsn.message, roadmap=roadmap, start_q=q_start)

    say(
        Stage.REDUCTION,
        f"GSn path with {len(gsn.path)} states; reducing to transfers and regrasps",
        states=len(gsn.path),
    )
    t_red = time.perf_counter()
    poses = gsn.path[:, :POSE_DIM].copy()
    # projected states meet |quat| = 1 to the projection tolerance only
    poses[:, 3:] /= np.linalg.norm(poses[:, 3:], axis=1, keepdims=True)
    # End on the goal pose itself rather than on whichever goal-region state
    # the planner happened to sample: the plan then depends on OMPL's
    # (thread- and clock-dependent) search only through the object trajectory.
    goal = scenario.goal.object_pose_xyzquat.copy()
    if goal_reached(scenario, poses[-1])[0]:
        if float(np.dot(goal[3:], poses[-1][3:])) < 0.0:
            goal[3:] = -goal[3:]
        poses = np.vstack([poses[:-1], goal[None]])
    settings = ctx.transitions.settings

    def pose_ok(p: FloatArray) -> bool:
        inside = np.all(p[:3] >= ctx.gsn.lower[:3]) and np.all(p[:3] <= ctx.gsn.upper[:3])
        return bool(inside) and not ctx.world.object_collides(p)

    short = shortcut_object_path(poses, pose_ok, settings.max_step_m, settings.max_step_rad)
    grasp = grasp_from_state(ctx.transitions, pose0, q_start)
    # a fresh stream: module-2 link attempts (as many as the clock allowed)
    # must not change the reduction's choices
    ctx.transitions.rng = np.random.default_rng([seed, 2])
    red = None
    attempt = 0
    hopeless: set[str] = set()  # trajectories along which the object itself collides
    for method, source in _reduction_schedule(reduction):
        if time.perf_counter() >= deadline:
            break
        if source in hopeless:
            continue
        attempt += 1
        if method == "gaits":
            traj = short if source == "shortcut" else poses
            dense = densify_poses(traj, settings.max_step_m, settings.max_step_rad)
            red = reduce_object_path(ctx.transitions, dense, q_start, grasp)
        else:
            # the GSn states' own contacts (the last state's pose may be replaced
            # by the goal pose above: its contacts are taken at its own pose)
            grasps = [
                grasp_from_state(ctx.transitions, x[:POSE_DIM], x[POSE_DIM:]) for x in gsn.path
            ]
            grasps[0] = grasp
            red = reduce_gsn_path(ctx.transitions, poses, grasps, q_start, deadline=deadline)
        stats["reduction_method"] = method
        if red.success:
            break
        if red.final:
            hopeless.add(source)
        say(
            Stage.REDUCTION,
            f"reduction attempt {attempt} ({method}, {source}) failed: {red.reason}",
            attempt=attempt,
        )
    stats["reduction_attempts"] = attempt
    stats["reduction_time_s"] = time.perf_counter() - t_red
    stats["object_poses_shortcut"] = len(short)
    if red is None or not red.success:
        msg = red.reason if red is not None else "time limit reached before the reduction"
        return result(
            PlanStatus.REDUCTION_FAILED,
            msg or "",
            roadmap=roadmap,
            gsn_path=gsn.path,
            start_q=q_start,
        )
    stats.update({f"local_{k}": v for k, v in red.stats.items()})
    segments = drop_regrasps(ctx.transitions, merge_regrasps(ctx.transitions, list(red.segments)))
    stats.update(count_kinds(segments))
    stats["graph_nodes"] = len(segments) + 1
    stats["waypoints"] = sum(len(s.waypoints) for s in segments)
    trans_m, rot_rad = object_path_length(segments)
    stats["object_path_m"] = trans_m
    stats["object_path_rad"] = rot_rad
    solved = dict(segments=tuple(segments), roadmap=roadmap, gsn_path=gsn.path, start_q=q_start)
    # re-check the whole plan with the independent verifier, as OMPL checks
    # simplified paths: a plan that fails it is never returned as solved
    if verify is None:
        return result(PlanStatus.SOLVED, **solved)
    say(Stage.VERIFICATION, "verifying the plan")
    t_ver = time.perf_counter()
    violations = tuple(verify(result(PlanStatus.SOLVED, **solved)))
    stats["verify_time_s"] = time.perf_counter() - t_ver
    if violations:
        return result(
            PlanStatus.INVALID_PLAN,
            f"the reduced plan failed verification: {'; '.join(violations[:5])}",
            violations=violations,
            **solved,
        )
    return result(PlanStatus.SOLVED, **solved)
