"""The manipulation planner: module 1 (GSn roadmap), module 2 (links), reduction.

A query runs in three stages:

1. **Module 1** (:mod:`dexplan.planning.roadmap.module1`): an OMPL planner explores
   GSn from the start state towards the goal region (single query), or a
   loaded roadmap answers the query (multi query).
2. **Module 2** (:mod:`dexplan.planning.roadmap.module2`): when start and
   goal are in different GSn components, the components are linked by
   transfer-regrasp sequences (the same local planners as the reduction).
3. **Reduction and smoothing**: the object trajectory of the GSn path is
   shortcut, reduced to transfer and regrasp segments (finger gaits), needless
   regrasps are merged, and the result is checked by the plan verifier before
   it is returned.

"No plan" is a result with a status, not an exception.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dexplan.core.errors import InvalidInputError
from dexplan.core.pose import quat_angle
from dexplan.core.segments import Segment, count_kinds, joint_travel, object_path_length
from dexplan.core.typing import FloatArray
from dexplan.model.hand.hand import Hand
from dexplan.model.scenario import Scenario, checked_scenario
from dexplan.planning.context import build_context
from dexplan.planning.deadline import budget
from dexplan.planning.diagnostics import Rejections
from dexplan.planning.gsn.space import POSE_DIM
from dexplan.planning.local.edge_reduction import reduce_gsn_path
from dexplan.planning.local.grasps import grasp_from_state
from dexplan.planning.local.reduction import (
    PathSource,
    Reduction,
    ReductionResult,
    reduce_object_path,
)
from dexplan.planning.local.smoothing import drop_regrasps, merge_regrasps, shortcut_object_path
from dexplan.planning.local.transitions import GraspContacts, densify_poses
from dexplan.planning.ompl import check_planner
from dexplan.planning.pose_check import check_pose, check_query
from dexplan.planning.progress import PlanStatus, Progress, ProgressEvent, Stage
from dexplan.planning.roadmap.graph import Roadmap
from dexplan.planning.roadmap.module1 import explore_gsn
from dexplan.planning.roadmap.queries import answer_query
from dexplan.planning.roadmap.search import GsnQuery, GsnResult
from dexplan.planning.start import start_state
from dexplan.planning.stats import PlanStats

Verifier = Callable[["PlanResult"], Sequence[str]]
"""Checks a finished plan; returns its violations (empty: the plan is valid)."""

REDUCTIONS = tuple(Reduction)
"""Reduction methods accepted by :func:`plan`."""

EXPLORE_AGAIN = 3
"""Module-1 explorations run again (fresh OMPL seeds) when every reduction of
a GSn path fails before the deadline: the reductions give up early only when
the object's own trajectory collides (the slerp between two GSn states
clips an obstacle, a failure long before the deadline), and another GSn
path usually goes around."""

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


def _reduction_schedule(
    reduction: str, hopeless: set[PathSource]
) -> Iterator[tuple[Reduction, PathSource]]:
    """Reduction attempts ``(method, trajectory)`` in order, until one succeeds.

    Gaits on the shortcut trajectory first (fewest segments), then on the raw
    GSn trajectory in case the shortcut is the trouble, both once more with
    new random landings (a retry usually works and gives far fewer regrasps
    than the edges), then the edge-by-edge reduction with bisection, then
    gaits again with new landings for as long as the caller lets it (it
    stops at the deadline) and some trajectory is not ``hopeless`` (the
    object itself collides along it): an attempt ends early when it stalls
    (``ReductionSettings.max_stall``, ``max_blind``), and on boxes a fresh
    one often goes through where the first stalled.
    """
    if reduction == Reduction.EDGES:
        yield Reduction.EDGES, PathSource.GSN
        return
    gaits = ((Reduction.GAITS, PathSource.SHORTCUT), (Reduction.GAITS, PathSource.RAW))
    yield from gaits * 2
    if reduction == Reduction.AUTO:
        yield Reduction.EDGES, PathSource.GSN
    while not {PathSource.SHORTCUT, PathSource.RAW} <= hopeless:
        yield from gaits


def plan(
    scenario: Scenario,
    *,
    planner: str | None = None,
    seed: int | None = None,
    time_limit: float | None = None,
    roadmap: Roadmap | None = None,
    progress: Progress | None = None,
    reduction: Reduction | str = Reduction.AUTO,
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
            :func:`~dexplan.planning.local.reduction.reduce_object_path`), ``edges``
            (the reduction property edge by edge with bisection,
            :func:`~dexplan.planning.local.edge_reduction.reduce_gsn_path`) or ``auto``
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
        ScenarioError: a start or goal the scenario parser would refuse
            (:func:`~dexplan.model.scenario.scenario.checked_scenario`).
    """
    if reduction not in REDUCTIONS:
        raise InvalidInputError(
            f"reduction must be one of {', '.join(REDUCTIONS)}, got {reduction!r}"
        )
    scenario = checked_scenario(scenario)  # poses built in Python: checked as the parser does
    spec = scenario.planner
    planner = planner or spec.name
    if roadmap is None:
        check_planner(planner, spec.params)  # bad names fail before any work
    query = QueryRun(
        scenario,
        planner,
        spec.seed if seed is None else seed,
        spec.time_limit if time_limit is None else time_limit,
        roadmap,
        progress,
        hand,
    )
    x_start, failed = query.start()
    if failed is not None:
        return failed
    assert x_start is not None  # start() returns a state or a failure
    gsn, failed = query.explore(x_start)
    if failed is not None:
        return failed
    assert gsn is not None and gsn.path is not None
    red = query.reduce(gsn, reduction)
    again = 0
    while not red.success and query.roadmap_own and again < EXPLORE_AGAIN:
        if time.perf_counter() >= query.deadline:
            break
        again += 1
        query.say(
            Stage.MODULE1, f"exploring GSn again ({again} of {EXPLORE_AGAIN}) for another path"
        )
        other, _ = query.explore(x_start, again)
        if other is None:
            break
        gsn, red = other, query.reduce(other, reduction)
    query.note(explorations=1 + again)
    if not red.success:
        return query.result(
            PlanStatus.REDUCTION_FAILED, red.reason or "", gsn_path=gsn.path, start_q=query.q0
        )
    assert gsn.path is not None  # explore() returns only GSn results with a path
    return query.finish(query.smooth(red), gsn.path, verify)


class QueryRun:
    """One query's state, stage by stage: models, deadline, statistics, progress.

    :func:`plan` runs the stages in order; each returns what the next needs,
    or the :class:`PlanResult` of the failure that ends the query.
    """

    def __init__(
        self,
        scenario: Scenario,
        planner: str,
        seed: int,
        time_limit: float,
        roadmap: Roadmap | None,
        progress: Progress | None,
        hand: Hand | None,
    ) -> None:
        self.t0 = time.perf_counter()
        self.c0 = time.process_time()
        self.scenario, self.planner, self.seed = scenario, planner, seed
        self.roadmap = roadmap
        self.roadmap_given = roadmap
        self.progress = progress
        self.ctx = build_context(scenario, seed, hand=hand)
        # every stage watches one deadline (the sampler, goal sampling and the
        # local planners read it too), keeping a reserve for the verification
        self.deadline = self.t0 + (1.0 - VERIFY_RESERVE) * budget(time_limit)
        self.ctx.deadline.at = self.deadline
        self.stats = PlanStats(planner=planner, seed=seed, time_limit=time_limit)
        self.pose0 = scenario.start.object_pose_xyzquat
        self.q0: FloatArray | None = None

    def note(self, **figures: Any) -> None:
        """Record figures in the query's :class:`PlanStats` (keywords: its fields)."""
        self.stats = dataclasses.replace(self.stats, **figures)

    def say(self, stage: Stage, message: str, **counts: int) -> None:
        """Report progress (a :class:`ProgressEvent`), if anyone listens."""
        if self.progress is not None:
            elapsed = time.perf_counter() - self.t0
            self.progress(ProgressEvent(stage, message, elapsed, counts))

    def result(self, status: PlanStatus, message: str = "", **kw: Any) -> PlanResult:
        """The query's result now: statistics, diagnostics, and the given fields."""
        ctx = self.ctx
        self.note(
            time_s=time.perf_counter() - self.t0,
            cpu_time_s=time.process_time() - self.c0,
            sampler=ctx.sampler.stats.as_dict(),
            validity=ctx.validity.stats.as_dict(),
        )
        fields: dict[str, Any] = {
            "segments": (),
            "gsn_path": np.zeros((0, ctx.gsn.ambient_dim)),
            "roadmap": self.roadmap,
            "start_q": self.q0,
            **kw,
        }
        return PlanResult(
            status,
            start_pose=self.pose0,
            stats=self.stats,
            message=message,
            rejections=Rejections.from_stats(ctx.sampler.stats, ctx.validity.stats),
            **fields,
        )

    # -- stage 0: can a grasp exist at the start and goal poses? ------------
    def start(self) -> tuple[FloatArray | None, PlanResult | None]:
        """The start GSn state, or the failure that ends the query before it.

        The poses are checked first (:meth:`check_poses`), then a start
        grasp is found (:meth:`start_grasp`).
        """
        blocked = self.check_poses()
        if blocked is not None:
            return None, blocked
        x_start = self.start_grasp()
        if x_start is None:
            why = " within the time limit" if self.ctx.deadline.expired() else ""
            msg = f"no valid grasp found at the start pose{why}{self.reach_note('start')}"
            return None, self.result(PlanStatus.NO_START_GRASP, msg)
        return x_start, None

    def check_poses(self) -> PlanResult | None:
        """The failure of a start or goal pose where no grasp can exist (:func:`check_query`).

        Seconds of sampling (and for a goal, the whole time limit) would find
        none and could not say why; the check says what to change at once, and
        ``--debug-rrd`` shows the verdict's states.
        """
        check = check_query(self.ctx)
        if check is None:
            return None
        self.ctx.validity.stats.samples.extend(check.samples(self.ctx.hand.neutral))
        status = PlanStatus.NO_START_GRASP if check.which == "start" else PlanStatus.NO_GOAL_GRASP
        return self.result(
            status, f"no grasp can exist at the {check.which} pose: {check.describe()}"
        )

    def reach_note(self, which: str) -> str:
        """After sampling found no grasp at a pose: fingertips at the edge of their reach there."""
        sc = self.scenario
        pose = sc.start.object_pose_xyzquat if which == "start" else sc.goal.object_pose_xyzquat
        return check_pose(self.ctx, pose, which).edge_hint()

    # -- stage 1: the start grasp --------------------------------------------
    def start_grasp(self) -> FloatArray | None:
        """The start GSn state (``start.q`` checked, or a sampled grasp)."""
        self.say(Stage.START_GRASP, "sampling a start grasp")
        x = start_state(self.ctx, rng=np.random.default_rng([self.seed, 5]))
        if x is not None:
            self.q0 = x[POSE_DIM:]
        return x

    # -- stage 2: modules 1 and 2 --------------------------------------------
    @property
    def roadmap_own(self) -> bool:
        """Whether module 1 explores GSn itself (no roadmap of an earlier run was given)."""
        return self.roadmap_given is None

    def explore(
        self, x_start: FloatArray, again: int = 0
    ) -> tuple[GsnResult | None, PlanResult | None]:
        """A GSn path from the start to the goal region: ``(gsn, None)`` or ``(None, failure)``.

        ``again``: the how-manieth exploration this is after the first (its
        OMPL planner gets a seed of its own).
        """
        ctx, scenario = self.ctx, self.scenario
        draws = [0, 0]  # calls, valid states: tells "no goal grasp" from "no path"
        query = self.gsn_query(x_start, draws)
        self.say(Stage.MODULE1, f"module 1: exploring GSn with {self.planner}")
        spec = scenario.planner
        if self.roadmap_given is None:
            gsn = explore_gsn(
                ctx,
                query,
                self.planner,
                params=spec.params,
                space=spec.space,
                seed=(self.seed + 104_729 * again) % 2**31,
                deadline=self.deadline,
                on_round=self.on_round,
            )
        else:
            assert self.roadmap is not None  # the given roadmap, or it grown by a query
            gsn = answer_query(ctx, self.roadmap, query, deadline=self.deadline, space=spec.space)
        self.note(**gsn.stats, goal_samples=draws[1])
        self.roadmap = gsn.roadmap
        if gsn.path is not None:
            return gsn, None
        if draws[0] and not draws[1]:
            msg = (
                f"no valid grasp found at the goal pose ({draws[0]} sampler calls)"
                f"{self.reach_note('goal')}"
            )
            return None, self.result(PlanStatus.NO_GOAL_GRASP, msg)
        return None, self.result(PlanStatus.NO_GSN_PATH, gsn.message)

    def gsn_query(self, x_start: FloatArray, draws: list[int]) -> GsnQuery:
        """The query's GSn query from ``x_start``; ``draws`` counts goal sampler calls, states."""
        ctx, scenario = self.ctx, self.scenario

        def goal_sampler() -> FloatArray | None:
            x = ctx.sampler.sample_at_pose(scenario.goal.object_pose_xyzquat)
            draws[0] += 1
            draws[1] += x is not None
            return x

        return GsnQuery(
            start=x_start,
            goal_test=lambda x: goal_reached(scenario, x[:POSE_DIM]),
            goal_sampler=goal_sampler,
            goal_pose=scenario.goal.object_pose_xyzquat,
        )

    def on_round(self, stage: Stage, counts: Mapping[str, int]) -> None:
        """Progress of modules 1 and 2 while they run (see :func:`explore_gsn`)."""
        if stage == Stage.MODULE1:
            msg = (
                f"module 1: round {counts['rounds']}: {counts['nodes']} nodes, "
                f"{counts['edges']} edges, {counts['components']} components"
            )
            self.say(Stage.MODULE1, msg, **counts)
        else:
            msg = f"module 2: {counts['attempts']} link attempts, {counts['links']} links"
            self.say(Stage.MODULE2, msg, **counts)

    # -- stage 3: the reduction ----------------------------------------------
    def object_trajectory(self, path: FloatArray) -> FloatArray:
        """(K, 7) object poses of a GSn path, unit quaternions, ending on the goal pose.

        Ending on the goal pose itself rather than on whichever goal-region
        state the planner happened to sample makes the plan depend on OMPL's
        (thread- and clock-dependent) search only through the object trajectory.
        """
        poses = path[:, :POSE_DIM].copy()
        # projected states meet |quat| = 1 to the projection tolerance only
        poses[:, 3:] /= np.linalg.norm(poses[:, 3:], axis=1, keepdims=True)
        goal = self.scenario.goal.object_pose_xyzquat.copy()
        if goal_reached(self.scenario, poses[-1])[0]:
            if float(np.dot(goal[3:], poses[-1][3:])) < 0.0:
                goal[3:] = -goal[3:]
            poses = np.vstack([poses[:-1], goal[None]])
        return poses

    def reduce(self, gsn: GsnResult, reduction: Reduction | str) -> ReductionResult:
        """Transfers and regrasps along the GSn path, per :func:`_reduction_schedule`."""
        ctx, path = self.ctx, gsn.path
        assert path is not None and self.q0 is not None
        self.say(
            Stage.REDUCTION,
            f"GSn path with {len(path)} states; reducing to transfers and regrasps",
            states=len(path),
        )
        t_red = time.perf_counter()
        poses = self.object_trajectory(path)
        settings = ctx.transitions.settings

        def pose_ok(p: FloatArray) -> bool:
            inside = np.all(p[:3] >= ctx.gsn.lower[:3]) and np.all(p[:3] <= ctx.gsn.upper[:3])
            return bool(inside) and not ctx.world.object_collides(p)

        short = shortcut_object_path(poses, pose_ok, settings.max_step_m, settings.max_step_rad)
        trajectories = {PathSource.SHORTCUT: short, PathSource.RAW: poses}
        grasp = grasp_from_state(ctx.transitions, self.pose0, self.q0)
        # a fresh stream: module-2 link attempts (as many as the clock allowed)
        # must not change the reduction's choices
        ctx.reseed_local_planners(self.seed, 2)
        red = ReductionResult(False, (), 0, "time limit reached before the reduction")
        attempt = 0
        hopeless: set[PathSource] = set()  # those along which the object itself collides
        for method, source in _reduction_schedule(reduction, hopeless):
            if time.perf_counter() >= self.deadline:
                break
            if source in hopeless:
                continue
            attempt += 1
            red, from_link = self._reduce_once(gsn, method, source, trajectories, grasp)
            self.note(reduction_method=method.value)
            if from_link:
                self.note(reduction_from_link=True)
            if red.success or from_link:
                break
            if red.final:
                hopeless.add(source)
            self.say(
                Stage.REDUCTION,
                f"reduction attempt {attempt} ({method}, {source}) failed: {red.reason}",
                attempt=attempt,
            )
        self.note(
            reduction_attempts=attempt,
            reduction_time_s=time.perf_counter() - t_red,
            object_poses_shortcut=len(short),
        )
        return red

    def _reduce_once(
        self,
        gsn: GsnResult,
        method: Reduction,
        source: PathSource,
        trajectories: Mapping[PathSource, FloatArray],
        grasp: GraspContacts,
    ) -> tuple[ReductionResult, bool]:
        """One reduction attempt: ``(result, taken from a module-2 link)``.

        ``trajectories``: the ``shortcut`` and ``raw`` object trajectories, (K, 7);
        ``grasp``: the start grasp's contacts.
        """
        ctx, path, q0 = self.ctx, gsn.path, self.q0
        assert path is not None and q0 is not None
        if method == Reduction.GAITS:
            settings = ctx.transitions.settings
            dense = densify_poses(trajectories[source], settings.max_step_m, settings.max_step_rad)
            link = next((k for k in gsn.links if k.matches(dense, q0)), None)
            if link is not None:
                # module 2 has reduced this very trajectory from this grasp
                return link.result, True
            return reduce_object_path(ctx.transitions, dense, q0, grasp), False
        # the GSn states' own contacts (the last state's pose may be the
        # goal pose: its contacts are taken at the state's own pose)
        grasps = [grasp_from_state(ctx.transitions, x[:POSE_DIM], x[POSE_DIM:]) for x in path]
        grasps[0] = grasp
        poses = trajectories[PathSource.RAW]
        return reduce_gsn_path(ctx.transitions, poses, grasps, q0, deadline=self.deadline), False

    # -- stage 4: smoothing and the final check ------------------------------
    def smooth(self, red: ReductionResult) -> list[Segment]:
        """Merge and drop needless regrasps; count what the plan is made of."""
        trans = self.ctx.transitions
        self.note(local={**self.stats.local, **red.stats})
        segments = drop_regrasps(trans, merge_regrasps(trans, list(red.segments)))
        path_m, path_rad = object_path_length(segments)
        self.note(
            **count_kinds(segments),
            graph_nodes=len(segments) + 1,
            waypoints=sum(len(s.waypoints) for s in segments),
            object_path_m=path_m,
            object_path_rad=path_rad,
            joint_travel_rad=joint_travel(segments),
        )
        return segments

    def finish(
        self, segments: list[Segment], gsn_path: FloatArray, verify: Verifier | None
    ) -> PlanResult:
        """The solved result, once the independent verifier (if any) passes it.

        As OMPL re-checks simplified paths, the whole plan is re-checked: a
        plan the verifier finds violations in is never returned as solved.
        """
        fields: dict[str, Any] = {"segments": tuple(segments), "gsn_path": gsn_path}
        if verify is None:
            return self.result(PlanStatus.SOLVED, **fields)
        self.say(Stage.VERIFICATION, "verifying the plan")
        t_ver = time.perf_counter()
        violations = tuple(verify(self.result(PlanStatus.SOLVED, **fields)))
        self.note(verify_time_s=time.perf_counter() - t_ver)
        if violations:
            return self.result(
                PlanStatus.INVALID_PLAN,
                f"the reduced plan failed verification: {'; '.join(violations[:5])}",
                violations=violations,
                **fields,
            )
        return self.result(PlanStatus.SOLVED, **fields)
