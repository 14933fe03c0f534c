"""A constrained problem set up the way OMPL users set one up (``og.SimpleSetup``).

:class:`ProblemSetup` hands out the OMPL objects themselves (the
``SpaceInformation``, the ``ProblemDefinition``, the constrained state
space) and takes any ``ob.Planner`` object, one of OMPL's or one written
in Python, where :class:`~dexplan.planning.ompl.problem.PlanningProblem`
only runs planners of the registry by name. States cross the boundary in
ambient coordinates (the constraint's own units, for GSn metres, XYZW
quaternions and radians): OMPL plans in scaled coordinates ``y = x *
scale`` (:class:`~dexplan.planning.ompl.spaces.Frame`), and
:meth:`ProblemSetup.read_state` / :meth:`ProblemSetup.write_state` convert
an OMPL state for a Python planner that wants to look at one.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from ompl import base as ob
from ompl import geometric as og

from dexplan.core.errors import InvalidInputError, PlannerError
from dexplan.core.typing import FloatArray, as_vector
from dexplan.planning.ompl._checks import as_int, as_pos
from dexplan.planning.ompl.callbacks import GoalSpec, goal_message, query_goal, termination
from dexplan.planning.ompl.error_sink import ErrorSink
from dexplan.planning.ompl.problem_space import ProblemSpace
from dexplan.planning.ompl.registry import (
    PLANNERS,
    check_planner_name,
    planner_traits,
    set_planner_param,
)
from dexplan.planning.ompl.results import STATUS_NAMES, PathCheck, SolveResult
from dexplan.planning.ompl.runtime import derived_seed, reseed_ompl
from dexplan.planning.ompl.spaces import ConstraintSpec, ProjectionSpec

__all__ = ["DEFAULT_PLANNER", "ProblemSetup"]

DEFAULT_PLANNER = "RRTConnect"
"""The planner :meth:`ProblemSetup.solve` runs when none was set (as ``og.SimpleSetup``
picks one for the problem)."""


class ProblemSetup:
    """A constrained planning problem with its OMPL objects in reach.

    Typical use (``og.SimpleSetup``'s, in ambient coordinates)::

        setup = ProblemSetup(spec, is_valid, valid_sampler=sample, seed=1)
        setup.set_start(x0)
        setup.set_goal(GoalSpec(distance, 0.01, sample=sample_goal))
        setup.set_planner(og.KPIECE1(setup.space_information))  # or a name
        result = setup.solve(5.0)
        path = setup.solution_path()  # (K, n) ambient states

    Args:
        constraint: the manifold and its bounds.
        is_valid: ``is_valid(x) -> bool`` for an ambient ``(n,)`` state.
        valid_sampler: ``() -> (n,) | None``, the space information's
            ``ValidStateSampler`` (``si.allocValidStateSampler()``: what the
            PRM family draws, and what a Python planner can draw).
        check_sampled_states: re-check ``is_valid`` on the valid sampler's states.
        projection: grid projection, given to planners that take one (KPIECE).
        seed: OMPL's global seed generator is reseeded from it before the
            space is built and before every :meth:`solve` (same calls, same
            paths, as for :class:`~dexplan.planning.ompl.problem.PlanningProblem`);
            None leaves OMPL's time-based seed alone.

    Raises:
        InvalidInputError: malformed arguments.
    """

    def __init__(
        self,
        constraint: ConstraintSpec,
        is_valid: Callable[[FloatArray], Any],
        *,
        valid_sampler: Callable[[], Any] | None = None,
        check_sampled_states: bool = True,
        projection: ProjectionSpec | None = None,
        seed: int | None = None,
    ) -> None:
        if not isinstance(constraint, ConstraintSpec):
            raise InvalidInputError(f"constraint must be a ConstraintSpec, got {constraint!r}")
        if not callable(is_valid):
            raise InvalidInputError(f"is_valid must be callable, got {is_valid!r}")
        self._seed = None if seed is None else as_int(seed, "seed", 0)
        self._solves = 0
        if self._seed is not None:
            reseed_ompl(derived_seed(self._seed, 0))
        self._spec = constraint
        self._sink = ErrorSink()
        self._space = ProblemSpace(
            constraint,
            is_valid,
            self._sink,
            valid_sampler=valid_sampler,
            check_sampled_states=check_sampled_states,
            projection=projection,
        )
        self._pdef = ob.ProblemDefinition(self._space.si)
        self._goal: GoalSpec | None = None
        self._planner: Any = None
        self._planner_name = ""
        self._ready = False

    # ------------------------------------------------------------ OMPL objects

    @property
    def space_information(self) -> Any:
        """The ``ob.SpaceInformation`` (validity checker and samplers set): build planners on it."""
        return self._space.si

    @property
    def problem_definition(self) -> Any:
        """The ``ob.ProblemDefinition`` of the current start and goal."""
        return self._pdef

    @property
    def state_space(self) -> Any:
        """The constrained ``ob.StateSpace`` (projected, atlas or tangent bundle)."""
        return self._space.css

    @property
    def projection_evaluator(self) -> Any:
        """The ``ob.ProjectionEvaluator`` for grid planners (KPIECE), or None."""
        return self._space.projection

    @property
    def planner(self) -> Any:
        """The ``ob.Planner`` set (None before :meth:`set_planner` or :meth:`solve`)."""
        return self._planner

    @property
    def dimension(self) -> int:
        """The ambient dimension n."""
        return self._spec.ambient_dim

    # ------------------------------------------------------------ states

    def read_state(self, state: Any) -> FloatArray:
        """The ambient ``(n,)`` coordinates of an OMPL state of this space (a copy)."""
        return np.array(self._space.frame.state_x(state), dtype=np.float64)

    def write_state(self, state: Any, x: object) -> None:
        """Write ambient coordinates ``x: (n,)`` into an OMPL state of this space."""
        y = self._space.frame.to_y(as_vector(x, "x", self.dimension))
        state.copy(np.asarray(y, dtype=np.float64).tolist())

    def new_state(self, x: object) -> Any:
        """A new OMPL state of this space at ambient ``x: (n,)`` (freed by Python)."""
        return self._space.alloc(self._space.frame.to_y(as_vector(x, "x", self.dimension)))

    # ------------------------------------------------------------ query

    def set_start(self, x: object) -> None:
        """Set the start state ``x: (n,)`` (ambient, on the manifold)."""
        xv = self._space.checked_state(x, "start")
        pdef = ob.ProblemDefinition(self._space.si)
        self._space.add_start(pdef, self._space.frame.to_y(xv), readable=True)
        if self._pdef.getGoal() is not None:
            pdef.setGoal(self._pdef.getGoal())
        self._use(pdef)

    def set_goal(self, goal: GoalSpec) -> None:
        """Set the goal region (a :class:`GoalSpec`; give it ``sample`` for tree planners).

        Raises:
            PlannerError: a callback of the goal raised.
        """
        if not isinstance(goal, GoalSpec):
            raise InvalidInputError(f"goal must be a GoalSpec, got {goal!r}")
        space = self._space
        made, _ = query_goal(
            space.si,
            space.alloc,
            space.frame,
            space.accept,
            self._sink,
            goal,
            None,
            one_state=False,
            anchor=space.anchor(),
        )
        self._sink.reraise("drawing a goal state")
        self._goal = goal
        self._pdef.setGoal(made)
        self._ready = False

    def _use(self, pdef: Any) -> None:
        self._pdef = pdef
        if self._planner is not None:
            self._planner.setProblemDefinition(pdef)
        self._ready = False

    def set_planner(self, planner: Any, params: Mapping[str, object] | None = None) -> None:
        """Use ``planner``: an ``ob.Planner`` built on :attr:`space_information`, or a name.

        A name is looked up in the registry (which
        :func:`~dexplan.planning.ompl.registry.register_planner` adds to);
        ``params`` are set on the planner by OMPL ParamSet name.

        Raises:
            PlannerError: unknown name, not an ``ob.Planner``, or a bad parameter.
        """
        if isinstance(planner, str):
            check_planner_name(planner)
            name, made = planner, PLANNERS[planner](self._space.si)
            if planner_traits(name).needs_projection and self._space.projection is not None:
                made.setProjectionEvaluator(self._space.projection)
        elif isinstance(planner, ob.Planner):
            name, made = str(planner.getName()), planner
        else:
            raise PlannerError(
                f"planner must be an ompl.base.Planner or a planner name, got {planner!r}"
            )
        for key, value in (params or {}).items():
            set_planner_param(made, name, str(key), value)
        made.setProblemDefinition(self._pdef)
        self._planner, self._planner_name, self._ready = made, name, False

    # ------------------------------------------------------------ solving

    def solve(self, time_limit: float) -> SolveResult:
        """Run the planner (:data:`DEFAULT_PLANNER` if none is set) for ``time_limit`` seconds.

        Calling it again continues the search (OMPL's anytime behaviour).

        Returns:
            The :class:`SolveResult`; its ``path`` is in ambient coordinates,
            re-checked in travel direction and densified.

        Raises:
            PlannerError: no start or goal, or a callback raised.
        """
        limit = as_pos(time_limit, "time_limit")
        if self._pdef.getStartStateCount() == 0:
            raise PlannerError("no start state: call set_start() before solve()")
        if self._pdef.getGoal() is None:
            raise PlannerError("no goal: call set_goal() before solve()")
        if self._planner is None:
            self.set_planner(DEFAULT_PLANNER)
        self._solves += 1
        if self._seed is not None:
            reseed_ompl(derived_seed(self._seed, self._solves))
        t0 = time.perf_counter()
        if not self._ready:
            self._planner.setup()
            self._ready = True
        with self._sink.watching(termination(limit)) as ptc:
            status = self._planner.solve(ptc)
        self._sink.reraise(f"planning with {self._planner_name}")
        name = STATUS_NAMES.get(status.getStatus().value, "unknown")
        elapsed = time.perf_counter() - t0
        if name not in ("exact", "approximate") or not self._pdef.hasSolution():
            why = goal_message(name, status.asString(), self._goal, self._planner_name)
            return SolveResult.without_path(name, self._planner_name, elapsed, why)
        checked = self._space.post_process(
            og.PathGeometric(self._pdef.getSolutionPath()), interpolate=True, check=True
        )
        self._sink.reraise("checking the path")
        distance = 0.0 if name == "exact" else float(self._pdef.getSolutionDifference())
        return SolveResult.with_path(
            name, checked, True, self._planner_name, elapsed, distance, status.asString()
        )

    def solution_path(self) -> FloatArray:
        """The planner's solution ``(M, n)``: its waypoints, ambient (not densified).

        Raises:
            PlannerError: no solution yet.
        """
        if not self._pdef.hasSolution():
            raise PlannerError("no solution: solve() has not found a path")
        path = og.PathGeometric(self._pdef.getSolutionPath())
        return np.array([self.read_state(path.getState(i)) for i in range(path.getStateCount())])

    def check_path(self, waypoints: object) -> PathCheck:
        """Re-check ``(M, n)`` ambient waypoints in travel direction, densified.

        Raises:
            InvalidInputError: wrong shape or non-finite values.
        """
        checked = self._space.post_process(
            self._space.geometric_path(waypoints), interpolate=True, check=True
        )
        self._sink.reraise("checking a path")
        return checked

    def clear(self) -> None:
        """Forget what the planner built (its trees or roadmap, atlas charts)."""
        if self._planner is not None:
            self._planner.clear()
        self._space.css.clear()
        self._ready = False
