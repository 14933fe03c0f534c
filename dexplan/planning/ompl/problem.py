"""The constrained planning problem: one OMPL geometric planner on a manifold.

:class:`PlanningProblem` ties together a constrained state space with its
callbacks (:class:`~dexplan.planning.ompl.problem_space.ProblemSpace`), a
planner of the registry (:mod:`~dexplan.planning.ompl.registry`) and a query
(start states, a goal); it solves queries, grows PRM roadmaps, re-checks paths
in travel direction and reads the planner's graph
(:mod:`~dexplan.planning.ompl.results`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from ompl import base as ob
from ompl import geometric as og

from dexplan.core.errors import InvalidInputError, PlannerError
from dexplan.core.typing import FloatArray
from dexplan.planning.ompl._checks import as_int, as_pos
from dexplan.planning.ompl.callbacks import GoalSpec, goal_message, query_goal, termination
from dexplan.planning.ompl.error_sink import ErrorSink
from dexplan.planning.ompl.motions import MotionFallback
from dexplan.planning.ompl.problem_space import ProblemSpace, written_in_python
from dexplan.planning.ompl.registry import (
    MULTI_QUERY_PLANNERS,
    PLANNERS,
    check_planner_name,
    declared_params,
    first_solution_objective,
    planner_traits,
    set_planner_param,
    settable_params,
)
from dexplan.planning.ompl.results import (
    STATUS_NAMES,
    PathCheck,
    RoadmapData,
    SolveResult,
    read_planner_data,
)
from dexplan.planning.ompl.runtime import derived_seed, reseed_ompl
from dexplan.planning.ompl.spaces import (
    ConstraintSpec,
    ProjectionSpec,
)

__all__ = ["PlanningProblem"]


class PlanningProblem:
    """A constrained planning problem solved by one OMPL geometric planner.

    Typical use::

        problem = PlanningProblem(spec, is_valid, planner="RRTConnect", seed=1)
        problem.set_start(x0)
        problem.set_goal(GoalSpec(distance, 0.01, sample=sample_goal))
        result = problem.solve(5.0)

    Multi-query (PRM family): :meth:`grow_roadmap` builds the roadmap without a
    query; each :meth:`solve` after a new start/goal reuses it (``clearQuery``).
    Other planners start a fresh tree for a new query; calling :meth:`solve` again
    on the same query continues the search (anytime behaviour).

    Determinism. OMPL has one global seed generator per process; every OMPL RNG
    (planner, state samplers, atlas) takes its seed from it when created, and
    ``RNG.setSeed`` re-seeds the generator even after use (OMPL logs an error that
    the adapter silences). With ``seed`` given, the adapter re-seeds it with a value
    derived from ``(seed, 0)`` before building the space and planner, and from
    ``(seed, k)`` before the k-th :meth:`solve` / :meth:`grow_roadmap` call (a new
    query also recreates a single-query planner, so its RNG is seeded then).
    Hence, in one process and across processes: the same problem with the
    same seed and the same call sequence gives the same path for planners that stop
    at their first solution and are single-threaded (RRT, RRTConnect, the KPIECE
    family, and roadmaps grown with :meth:`grow_roadmap` ``(max_milestones=...)``),
    provided the Python callbacks are deterministic (seed the ``valid_sampler``'s and
    goal sampler's own ``np.random.Generator``). Not deterministic: anything
    time-limited (optimizing planners, growth stopped by time), PRM's ``solve``
    (its checker thread races the roadmap growth), and a solve interleaved with
    other OMPL objects being created in another thread. Without ``seed`` OMPL's
    time-based seed is left alone.

    Args:
        constraint: the manifold and its bounds.
        is_valid: ``is_valid(x) -> bool`` for an ambient ``(n,)`` state.
        planner: a name of :data:`PLANNERS`.
        params: planner parameters by OMPL ParamSet name (``{"range": 0.1}``).
        valid_sampler: ``() -> (n,) | None``: a valid state on the manifold, or
            None; becomes the space information's ``ValidStateSampler`` (used by
            the PRM family and ``searchValidNearby``).
        valid_sampler_near: ``(x_near (n,), distance) -> (n,) | None`` for
            ``sampleNear``; without it ``sampleNear`` reports failure.
        check_sampled_states: re-check ``is_valid`` on the valid sampler's states
            (turn off when the sampler already does).
        projection: grid projection for the KPIECE family (ignored by others).
        seed: see Determinism; None leaves OMPL's seed alone.
        motion_fallback: a second motion between two states, tried where
            OMPL's discrete geodesic is invalid
            (:data:`~dexplan.planning.ompl.motions.MotionFallback`); the PRM
            family only (tree planners also call the 3-argument
            ``checkMotion``, whose last valid state a Python validator cannot
            set in this binding). Paths through an edge it joined are
            densified along its states.
        fallback_merges_only: try the fallback only between states that the
            motions accepted so far do not join (see
            :class:`~dexplan.planning.ompl.motions.FallbackMotions`).
        fallback_checks: motion checks (the planner's, :meth:`check_motion`,
            :meth:`check_path`) try the fallback; False keeps them OMPL's and
            uses the fallback only to densify, in :meth:`interpolate_path`,
            edges OMPL's motion does not join (checks then stay cheap and a
            function of their two states).

    Raises:
        PlannerError: unknown planner, unknown parameter or rejected value.
        InvalidInputError: malformed arguments.

    """

    def __init__(
        self,
        constraint: ConstraintSpec,
        is_valid: Callable[[FloatArray], Any],
        *,
        planner: str = "PRM",
        params: Mapping[str, object] | None = None,
        valid_sampler: Callable[[], Any] | None = None,
        valid_sampler_near: Callable[[FloatArray, float], Any] | None = None,
        check_sampled_states: bool = True,
        projection: ProjectionSpec | None = None,
        seed: int | None = None,
        motion_fallback: MotionFallback | None = None,
        fallback_merges_only: bool = True,
        fallback_checks: bool = True,
    ) -> None:
        _check_arguments(constraint, is_valid, planner, motion_fallback)
        if seed is not None:
            seed = as_int(seed, "seed", 0)
        self._spec = constraint
        self._planner_name = planner
        self._seed = seed
        self._solve_count = 0
        self._is_valid = is_valid
        self._projection_spec = projection
        self._sink = ErrorSink()
        if seed is not None:
            reseed_ompl(derived_seed(seed, 0))
        space = ProblemSpace(
            constraint,
            is_valid,
            self._sink,
            valid_sampler=valid_sampler,
            valid_sampler_near=valid_sampler_near,
            check_sampled_states=check_sampled_states,
            projection=projection,
            motion_fallback=motion_fallback,
            fallback_merges_only=fallback_merges_only,
            fallback_checks=fallback_checks,
        )
        self._space = space
        self._frame, self._css, self._si = space.frame, space.css, space.si
        self._motions = space.motions
        self._params: dict[str, object] = {}
        self._starts: list[FloatArray] = []
        self._goal: GoalSpec | None = None
        self._goal_state: tuple[FloatArray, float] | None = None
        self._query_dirty = True
        self._planner_used = False
        self._pdef = ob.ProblemDefinition(self._si)
        self._planner = self._new_planner()
        for name, value in (params or {}).items():
            self.set_param(name, value)

    # ----------------------------------------------------------------- properties

    @property
    def planner_name(self) -> str:
        """Name of the planner."""
        return self._planner_name

    @property
    def constraint(self) -> ConstraintSpec:
        """The constraint specification."""
        return self._spec

    @property
    def delta(self) -> float:
        """Discrete geodesic step of the space, in planning (scaled) units."""
        return float(self._css.getDelta())

    @property
    def lambda_(self) -> float:
        """Maximum wandering ratio of a discrete geodesic."""
        return float(self._css.getLambda())

    @property
    def is_multi_query(self) -> bool:
        """Whether the planner keeps its roadmap across queries (PRM family)."""
        return planner_traits(self._planner_name).multi_query

    # ----------------------------------------------------------------- planner

    def _new_planner(self) -> Any:
        planner = PLANNERS[self._planner_name](self._si)
        projection = self._space.projection
        if projection is not None and planner_traits(self._planner_name).needs_projection:
            planner.setProjectionEvaluator(projection)
        if self._spec.space != "projected" and callable(getattr(planner, "setRange", None)):
            planner.setRange(float(self._css.getRho_s()))  # as OMPL's demos; params override
        for name, value in self._params.items():
            set_planner_param(planner, self._planner_name, name, value)
        planner.setProblemDefinition(self._pdef)
        return planner

    def set_param(self, name: str, value: object) -> None:
        """Set a planner parameter by its OMPL ParamSet name.

        The value is converted to the parameter's type (bool, int or float; strings
        are parsed), must be finite and >= 0 (and <= 1 for ``*bias*``/``*fraction*``),
        and must read back unchanged.

        Raises:
            PlannerError: unknown name (the message lists the valid ones), a name the
                binding cannot set, or a value that is malformed or rejected.

        """
        set_planner_param(self._planner, self._planner_name, name, value)
        self._params[name] = value

    def parameters(self) -> dict[str, str]:
        """Return the planner's settable parameters and their current values (text)."""
        declared = declared_params(self._planner)
        return {name: declared[name] for name in settable_params(self._planner)}

    # ----------------------------------------------------------------- query

    def set_start(self, x: object) -> None:
        """Replace the start states by ``x`` ``(n,)`` (on the manifold)."""
        self._starts = [self._space.checked_state(x, "start")]
        self._query_dirty = True

    def add_start(self, x: object) -> None:
        """Add a start state ``x`` ``(n,)`` (on the manifold)."""
        self._starts.append(self._space.checked_state(x, "start"))
        self._query_dirty = True

    def set_goal(self, goal: GoalSpec) -> None:
        """Set a goal region (replaces any goal)."""
        if not isinstance(goal, GoalSpec):
            raise InvalidInputError(f"goal must be a GoalSpec, got {goal!r}")
        self._goal = goal
        self._goal_state = None
        self._query_dirty = True

    def set_goal_state(self, x: object, threshold: float = 1e-6) -> None:
        """Set a single goal state ``x`` ``(n,)``; ``threshold`` is a planning distance.

        Implemented with OMPL's C++ ``GoalStates``: the fastest goal, safe for every
        planner.
        """
        xv = self._space.checked_state(x, "goal")
        thr = float(threshold)
        if not math.isfinite(thr) or thr < 0.0:
            raise InvalidInputError(f"threshold must be finite and >= 0, got {threshold!r}")
        self._goal_state = (xv, thr)
        self._goal = None
        self._query_dirty = True

    def _build_query(self) -> str | None:
        """Build a fresh ProblemDefinition; return a status name if impossible."""
        pdef = ob.ProblemDefinition(self._si)
        # a planner written in Python reads its start through the binding
        readable = written_in_python(self._planner)
        for x in self._starts:
            self._space.add_start(pdef, self._frame.to_y(x), readable=readable)
        goal, status = query_goal(
            self._si,
            self._space.alloc,
            self._frame,
            self._space.accept,
            self._sink,
            self._goal,
            self._goal_state,
            one_state=self.is_multi_query,
            anchor=self._space.anchor(),
        )
        if goal is None:
            return status
        pdef.setGoal(goal)
        if planner_traits(self._planner_name).first_solution:
            pdef.setOptimizationObjective(first_solution_objective(self._si))
        self._pdef = pdef
        if self.is_multi_query:
            self._planner.setProblemDefinition(pdef)
            self._planner.clearQuery()
        else:
            self._planner = self._new_planner()
        self._planner.setup()
        self._query_dirty = False
        self._planner_used = False
        return None

    # ----------------------------------------------------------------- solving

    def _raise_callback_error(self) -> None:
        self._sink.reraise(f"planning with {self._planner_name}")

    def grow_roadmap(self, time_limit: float, max_milestones: int | None = None) -> int:
        """Grow a PRM-family roadmap without a query (single-threaded).

        Args:
            time_limit: seconds.
            max_milestones: stop once the roadmap has this many vertices (then growth
                is deterministic with a seed, unless the time limit stops it first).

        Returns:
            The number of roadmap vertices (milestones).

        Raises:
            PlannerError: the planner is not multi-query, or a callback raised.

        """
        if not self.is_multi_query:
            raise PlannerError(
                "grow_roadmap needs a multi-query planner "
                f"({', '.join(sorted(MULTI_QUERY_PLANNERS))}), not {self._planner_name}"
            )
        limit = as_pos(time_limit, "time_limit")
        self._next_seed()
        reached = None
        if max_milestones is not None:
            target = as_int(max_milestones, "max_milestones", 1)
            planner = self._planner
            sink = self._sink

            def reached() -> bool:
                return sink.error is not None or planner.milestoneCount() >= target

        with (
            self._sink.watching(termination(limit, stop=reached)) as ptc,
            self._space.motion_deadline(limit),
        ):
            self._planner.growRoadmapPtc(ptc)
        self._raise_callback_error()
        return int(self._planner.milestoneCount())

    def solve(
        self,
        time_limit: float,
        *,
        max_iterations: int | None = None,
        interpolate: bool = True,
        check_path: bool = True,
    ) -> SolveResult:
        """Run the planner on the current query.

        Args:
            time_limit: seconds (a C++ timed termination condition).
            max_iterations: also stop after this many planner iterations
                (termination-condition checks). A search stopped this way, not by
                the clock, depends on the seed only: deterministic. Single-query
                planners only (the PRM family checks the condition from a
                second thread; use :meth:`grow_roadmap` with ``max_milestones``).
            interpolate: densify the path along the space's discrete geodesics
                (steps <= ``lambda_ * delta`` in planning units; an edge the
                motion fallback joined follows its states).
            check_path: re-check the path in travel direction (motions, constraint,
                bounds, validity); with False, ``path_valid`` is False.

        Returns:
            The :class:`SolveResult`; "no path" is a status, not an exception.

        Raises:
            PlannerError: no start or goal set, or a callback raised during planning.

        """
        limit = as_pos(time_limit, "time_limit")
        if not self._starts:
            raise PlannerError("no start state: call set_start() before solve()")
        if self._goal is None and self._goal_state is None:
            raise PlannerError("no goal: call set_goal() or set_goal_state() before solve()")
        t0 = time.perf_counter()
        self._next_seed()
        if self._query_dirty:
            early = self._build_query()
            self._raise_callback_error()
            if early is not None:
                return self._no_path(early, t0, "no acceptable goal sample")
        budget = self._iteration_budget(max_iterations)
        if self._planner_used and planner_traits(self._planner_name).restarted:
            # a batch planner cut short cannot resume: a fresh batch, the budget given
            self._planner = self._new_planner()
            self._planner.setup()
        self._planner_used = True
        with (
            self._sink.watching(termination(limit, budget)) as ptc,
            self._space.motion_deadline(limit),
        ):
            status = self._planner.solve(ptc)
        self._raise_callback_error()
        name = STATUS_NAMES.get(status.getStatus().value, "unknown")
        if name not in ("exact", "approximate") or not self._pdef.hasSolution():
            return self._no_path(name, t0, status.asString())
        return self._solution(name, status.asString(), t0, interpolate, check_path)

    def _next_seed(self) -> None:
        """Count a solve or growth call; with a seed, reseed OMPL for it (see Determinism)."""
        self._solve_count += 1
        if self._seed is not None:
            reseed_ompl(derived_seed(self._seed, self._solve_count))

    def _iteration_budget(self, max_iterations: int | None) -> int | None:
        """``max_iterations`` checked (single-query planners only), or None."""
        if max_iterations is None:
            return None
        if self.is_multi_query:
            raise PlannerError(
                f"max_iterations is for single-query planners, not {self._planner_name} "
                "(its solution checker runs in a second thread)"
            )
        return as_int(max_iterations, "max_iterations", 1)

    def _solution(
        self, name: str, message: str, t0: float, interpolate: bool, check_path: bool
    ) -> SolveResult:
        """The :class:`SolveResult` of a solve started at ``t0`` that found a path."""
        path = og.PathGeometric(self._pdef.getSolutionPath())
        checked = self._space.post_process(path, interpolate=interpolate, check=check_path)
        self._raise_callback_error()
        goal_distance = 0.0 if name == "exact" else float(self._pdef.getSolutionDifference())
        elapsed = time.perf_counter() - t0
        return SolveResult.with_path(
            name, checked, check_path, self._planner_name, elapsed, goal_distance, message
        )

    @property
    def fallback_motions(self) -> tuple[int, int, int]:
        """``(attempts, joined, skipped)`` of the motion fallback (zeros without one)."""
        m = self._motions
        return (0, 0, 0) if m is None else (m.attempts, m.joined, m.skipped)

    def _no_path(self, status: str, t0: float, message: str) -> SolveResult:
        """Return the :class:`SolveResult` of a solve started at ``t0`` without a path."""
        elapsed = time.perf_counter() - t0
        why = goal_message(status, message, self._goal, self._planner_name)
        return SolveResult.without_path(status, self._planner_name, elapsed, why)

    def check_path(self, waypoints: object, *, interpolate: bool = True) -> PathCheck:
        """Re-check (and densify) any path of ambient states in travel direction.

        Each segment ``i -> i+1`` must be a valid motion along the space's discrete
        geodesic (or the motion fallback's, densified along its states); when
        only the reverse motion is valid (projection is direction-dependent)
        the reversed reverse geodesic replaces it. Every
        resulting state must satisfy the constraint within tolerance, the bounds and
        ``is_valid``.

        Args:
            waypoints: ``(M, n)`` ambient states, M >= 1.
            interpolate: return the densified geodesic states rather than the
                waypoints.

        Returns:
            The :class:`PathCheck`.

        Raises:
            InvalidInputError: wrong shape or non-finite values.
            PlannerError: a callback raised.

        """
        path = self._space.geometric_path(waypoints)
        result = self._space.post_process(path, interpolate=interpolate, check=True)
        self._raise_callback_error()
        return result

    def interpolate_path(self, waypoints: object) -> FloatArray:
        """Densify a path of ambient states along the space's motions, unchecked.

        For paths whose motions were checked already (a roadmap's edges): each
        segment ``i -> i+1`` is OMPL's ``PathGeometric.interpolate`` of it, or,
        with a motion fallback, the fallback's states where OMPL's motion is
        invalid and the fallback joins the segment (recorded, or joined again);
        no other validity check is made (use :meth:`check_path` for that).

        Args:
            waypoints: ``(M, n)`` ambient states, M >= 1.

        Returns:
            ``(K, n)`` ambient states, the waypoints included.

        Raises:
            InvalidInputError: wrong shape or non-finite values.
        """
        path = self._space.geometric_path(waypoints)
        if self._motions is not None:
            dense = self._space.interpolate_with_fallback(path)
            self._raise_callback_error()
            return dense
        path.interpolate()
        read = self._frame.read
        ys = np.array([read(path.getState(i)) for i in range(path.getStateCount())])
        self._raise_callback_error()
        return self._frame.to_x(ys.reshape(-1, self._spec.ambient_dim))

    # ----------------------------------------------------------------- data

    def planner_data(self) -> RoadmapData:
        """Return the planner's current graph (roadmap or trees) in ambient coordinates.

        Start ids are the vertices that are the query's start states: FMT
        reports every sample it never connected as a start vertex
        (``FMT::getPlannerData`` marks each parent-less motion so), and a
        caller taking those for starts would link the start to its own
        copies (module 2 did, on every FMT query).
        """
        pd = ob.PlannerData(self._si)
        self._planner.getPlannerData(pd)
        given = self._frame.to_y(np.array(self._starts)) if self._starts else None
        return read_planner_data(pd, self._frame, self._spec.ambient_dim, given)

    def clear(self) -> None:
        """Forget everything the planner built (roadmap, trees, atlas charts, fallback motions)."""
        self._planner.clear()
        self._css.clear()
        if self._motions is not None:
            self._motions.clear()
        self._query_dirty = True

    def project(self, x: object) -> FloatArray | None:
        """Project an ambient ``(n,)`` point onto the manifold with OMPL's projection.

        Returns:
            The projected ``(n,)`` ambient point, or None if projection failed.

        """
        projected = self._space.project(x)
        self._raise_callback_error()
        return projected

    def check_motion(self, a: object, b: object) -> bool:
        """Whether the motion from ``a`` to ``b`` (ambient ``(n,)``) is valid.

        OMPL's discrete geodesic, or with a motion fallback (and
        ``fallback_checks``) the fallback's motion where that one is invalid.
        """
        ok = self._space.check_motion(a, b)
        self._raise_callback_error()
        return ok

    def distance(self, a: object, b: object) -> float:
        """OMPL's state-space distance of two ambient ``(n,)`` states (planning units)."""
        return self._space.distance(a, b)

    def interpolate(self, a: object, b: object, t: float) -> FloatArray:
        """OMPL's geodesic interpolation from ``a`` (t = 0) to ``b`` (t = 1), ambient."""
        out = self._space.interpolate(a, b, t)
        self._raise_callback_error()
        return out

    def round_trip(self, x: object) -> FloatArray:
        """A state written into an OMPL state of this space and read back, ambient.

        (The binding's ``serialize`` takes a raw capsule and ``copyFromReals`` a
        ``std::vector`` that Python lists do not convert to, so this is the
        state I/O the binding offers.)
        """
        return self._space.round_trip(x)

    def valid_sampler_count(self) -> int:
        """Return how many Python valid-state samplers OMPL allocated (diagnostics)."""
        return len(self._space.samplers)


def _check_arguments(
    constraint: object,
    is_valid: object,
    planner: str,
    motion_fallback: object,
) -> None:
    """Raise on a malformed :class:`PlanningProblem` argument (see its Raises)."""
    if not isinstance(constraint, ConstraintSpec):
        raise InvalidInputError(f"constraint must be a ConstraintSpec, got {constraint!r}")
    if not callable(is_valid):
        raise InvalidInputError(f"is_valid must be callable, got {is_valid!r}")
    check_planner_name(planner)
    if motion_fallback is not None:
        if not callable(motion_fallback):
            raise InvalidInputError(f"motion_fallback must be callable, got {motion_fallback!r}")
        if not planner_traits(planner).multi_query:
            raise InvalidInputError(
                f"motion_fallback is for the PRM family "
                f"({', '.join(sorted(MULTI_QUERY_PLANNERS))}), not {planner}"
            )
