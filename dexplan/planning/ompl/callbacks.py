"""Python callbacks handed to OMPL, and termination conditions.

- ``is_valid(x) -> bool`` becomes the state validity checker (:func:`make_validity`);
- an optional ``valid_sampler() -> x | None`` becomes an ``ob.ValidStateSampler``
  (:func:`make_sampler_allocator`; used by the PRM family only: tree planners
  draw from the space's own sampler, uniform ambient states then projected,
  and the wheel offers no hook to replace it, see
  :mod:`dexplan.planning.gsn.chart` for how dexplan's tree planners get GSn
  states anyway);
- a :class:`GoalSpec` (distance, threshold, optional sampler) becomes a goal region
  (:func:`make_goal_region`), or a single goal state given to
  :meth:`~dexplan.planning.ompl.problem.PlanningProblem.set_goal_state`;
- a time limit, an iteration budget and a Python stop test become one planner
  termination condition (:func:`termination`).

A callback never lets an exception unwind through OMPL's C++ frames: it records it
in the :class:`~dexplan.planning.ompl.error_sink.ErrorSink`, answers "invalid" and
terminates the running solve; the caller re-raises it as a
:class:`~dexplan.core.errors.PlannerError`.

Binding facts (ompl 2.0.1 PyPI wheel, nanobind):

- No binding releases the GIL. ``PRM.solve`` runs a solution-checking thread; when
  that thread calls Python (a Python goal, a Python termination condition, or goal
  milestones added while it holds PRM's graph mutex) while the main thread waits
  for that mutex or joins it, the process deadlocks (a ``GoalStates`` goal of
  several states does). The adapter therefore gives the PRM family exactly one
  C++ ``ob.GoalStates`` goal (sampled in Python beforehand) and a C++
  ``timedPlannerTerminationCondition``; the checker thread then never enters
  Python. Roadmap growth without a query
  (:meth:`~dexplan.planning.ompl.problem.PlanningProblem.grow_roadmap`) calls
  ``PRM.growRoadmap`` directly: single-threaded, no deadlock possible.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from ompl import base as ob

from dexplan.core.errors import InvalidInputError
from dexplan.core.typing import FloatArray
from dexplan.planning.ompl._checks import as_int
from dexplan.planning.ompl.error_sink import ErrorSink
from dexplan.planning.ompl.spaces import ConstraintSpec, Frame

__all__ = [
    "Accept",
    "GoalSpec",
    "draw_goal",
    "goal_message",
    "make_goal_region",
    "make_sampler_allocator",
    "make_validity",
    "query_goal",
    "termination",
]


def termination(
    time_limit: float,
    max_iterations: int | None = None,
    stop: Callable[[], bool] | None = None,
) -> Any:
    """Return a planner termination condition: time, iteration budget, stop test.

    The time limit is OMPL's C++ ``timedPlannerTerminationCondition``; the budget
    and ``stop`` are Python conditions or-ed onto it, so give them only to
    single-threaded searches (see the module notes on the PRM deadlock).

    Args:
        time_limit: seconds.
        max_iterations: stop after this many termination-condition checks
            (planner iterations), or None for no budget.
        stop: ``() -> bool``, checked each iteration, or None.

    Returns:
        The ``ob.PlannerTerminationCondition``.

    """
    ptc = ob.timedPlannerTerminationCondition(time_limit)
    if max_iterations is not None:
        budget = max_iterations
        count = [0]

        def spent() -> bool:
            count[0] += 1
            return count[0] > budget

        ptc = ob.plannerOrTerminationCondition(ptc, ob.PlannerTerminationCondition(spent))
    if stop is not None:
        ptc = ob.plannerOrTerminationCondition(ptc, ob.PlannerTerminationCondition(stop))
    return ptc


# -------------------------------------------------------------- validity, samplers


def make_validity(
    is_valid: Callable[[FloatArray], Any], frame: Frame, sink: ErrorSink
) -> Callable[[Any], bool]:
    """Return OMPL's validity callback ``check(state) -> bool`` wrapping ``is_valid``.

    Args:
        is_valid: ``is_valid(x) -> bool`` for an ambient ``(n,)`` state.
        frame: the space's coordinate frame.
        sink: where an exception is recorded (the state is then invalid).

    Returns:
        The callback; it answers False once any callback has raised.

    """
    state_x = frame.state_x

    def check(state: Any) -> bool:
        if sink.error is not None:
            return False
        try:
            return bool(is_valid(state_x(state)))
        except Exception as exc:  # must not unwind through C++: recorded, re-raised
            sink.record(exc)
            return False

    return check


class Accept:
    """Turn a candidate ambient state into an on-manifold, in-bounds, valid one."""

    __slots__ = ("check_valid", "constraint", "frame", "fun", "is_valid", "lo", "tol", "up")

    def __init__(
        self,
        spec: ConstraintSpec,
        frame: Frame,
        constraint: Any,
        is_valid: Callable[[FloatArray], Any],
        check_valid: bool,
    ) -> None:
        self.fun = spec.function
        self.tol = spec.tolerance
        self.lo = frame.to_y(spec.lower)
        self.up = frame.to_y(spec.upper)
        self.frame = frame
        self.constraint = constraint
        self.is_valid = is_valid
        self.check_valid = check_valid

    def __call__(self, candidate: object) -> FloatArray | None:
        """Return the accepted state in planning coordinates ``(n,)``, or None."""
        x = np.asarray(candidate, dtype=np.float64)
        if x.shape != (self.frame.n,) or not np.isfinite(x).all():
            raise InvalidInputError(
                f"a sampler returned shape {x.shape} (need ({self.frame.n},)) or non-finite"
            )
        y = np.array(self.frame.to_y(x), dtype=np.float64)
        if float(np.linalg.norm(np.asarray(self.fun(x), dtype=np.float64))) > self.tol:
            if not self.constraint.project(y):
                return None
            x = self.frame.to_x(y)
        if np.any(y < self.lo) or np.any(y > self.up):
            return None
        if self.check_valid and not bool(self.is_valid(x)):
            return None
        return y


def make_sampler_allocator(
    sample: Callable[[], Any],
    sample_near: Callable[[FloatArray, float], Any] | None,
    accept: Accept,
    frame: Frame,
    sink: ErrorSink,
    keep: list[Any],
) -> Callable[[Any], Any]:
    """Return ``alloc(si) -> ob.ValidStateSampler`` wrapping the Python samplers."""

    def fill(state: Any, draw: Callable[[], Any]) -> bool:
        """Copy an accepted draw into ``state``; exceptions are recorded, not raised."""
        if sink.error is not None:
            return False
        try:
            x = draw()
            y = None if x is None else accept(x)
        except Exception as exc:  # must not unwind through C++: recorded, re-raised
            sink.record(exc)
            return False
        if y is None:
            return False
        state.copy(y.tolist())
        return True

    class _Sampler(ob.ValidStateSampler):
        def sample(self, state: Any) -> bool:
            return fill(state, sample)

        def sampleNear(self, state: Any, near: Any, distance: float) -> bool:  # noqa: N802
            if sample_near is None:
                return False
            return fill(state, lambda: sample_near(frame.state_x(near), float(distance)))

    def allocate(si: Any) -> Any:
        sampler = _Sampler(si)
        sampler.setName("dexplan_python_valid_sampler")
        keep.append(sampler)  # nanobind lifetime: keep the Python object referenced
        return sampler

    return allocate


# ------------------------------------------------------------------------- goals


@dataclass(frozen=True, eq=False)
class GoalSpec:
    """A goal region ``{x : distance(x) <= threshold}`` on the manifold.

    Attributes:
        distance: ``d(x) -> float >= 0`` for an ambient ``(n,)`` state.
        threshold: states with ``distance(x) <= threshold`` satisfy the goal.
        sample: ``() -> (n,) | None``: a state in the region, on the manifold
            (re-projected if it is off by more than the tolerance) and valid, or None
            on failure. Required by planners that need goal states (RRTConnect,
            the FMT and PRM families...). Its randomness is the caller's: use
            your own seeded ``np.random.Generator``.
        max_samples: goal states a tree planner may draw per query. The PRM family
            always gets exactly one (see the module notes on the PRM deadlock).
        sample_attempts: calls of ``sample`` allowed to find one acceptable state.

    """

    distance: Callable[[FloatArray], float]
    threshold: float
    sample: Callable[[], Any] | None = None
    max_samples: int = 10
    sample_attempts: int = 100

    def __post_init__(self) -> None:
        if not callable(self.distance):
            raise InvalidInputError(f"distance must be callable, got {self.distance!r}")
        if self.sample is not None and not callable(self.sample):
            raise InvalidInputError(f"sample must be callable or None, got {self.sample!r}")
        threshold = float(self.threshold)
        if not math.isfinite(threshold) or threshold < 0.0:
            raise InvalidInputError(f"threshold must be finite and >= 0, got {self.threshold!r}")
        object.__setattr__(self, "threshold", threshold)
        as_int(self.max_samples, "max_samples", 1)
        as_int(self.sample_attempts, "sample_attempts", 1)


def make_goal_region(
    si: Any,
    spec: GoalSpec,
    frame: Frame,
    accept: Accept,
    sink: ErrorSink,
    first: FloatArray | None,
    anchor: Callable[[Any], None] | None,
) -> Any:
    """Return a Python ``GoalSampleableRegion`` (tree planners only: never PRM)."""
    distance = spec.distance
    sample = spec.sample
    attempts = spec.sample_attempts
    count = spec.max_samples if (sample is not None and first is not None) else 0
    state_x = frame.state_x
    pending = [first]

    class _Goal(ob.GoalSampleableRegion):
        def distanceGoal(self, state: Any) -> float:  # noqa: N802
            if sink.error is not None:
                return math.inf
            try:
                return float(distance(state_x(state)))
            except Exception as exc:  # must not unwind through C++: recorded, re-raised
                sink.record(exc)
                return math.inf

        def sampleGoal(self, state: Any) -> None:  # noqa: N802
            y = pending.pop() if pending and pending[-1] is not None else None
            if y is None and sink.error is None:
                try:
                    y = draw_goal(sample, attempts, accept, distance, spec.threshold, frame)
                except Exception as exc:  # must not unwind through C++: recorded, re-raised
                    sink.record(exc)
            # OMPL samples only while maxSampleCount() > 0, which needs first (count above)
            state.copy((first if y is None else y).tolist())  # type: ignore[union-attr]
            if anchor is not None:
                anchor(state)

        def maxSampleCount(self) -> int:  # noqa: N802
            return count

        def couldSample(self) -> bool:  # noqa: N802
            return count > 0

    goal = _Goal(si)
    goal.setThreshold(spec.threshold)
    return goal


def goal_message(status: str, ompl_text: str, goal: GoalSpec | None, planner: str) -> str:
    """What a solve without a path says: OMPL's text, or why for a goal without a sampler.

    OMPL answers ``invalid_goal`` when a planner that grows a tree from the
    goal (RRTConnect, BFMT, BITstar...) or needs one goal state (the PRM
    family) gets a goal region it cannot sample: a :class:`GoalSpec`
    without ``sample``.
    """
    if status == "invalid_goal" and goal is not None and goal.sample is None:
        return (
            f"{planner} needs goal states, and the goal region has no sampler: "
            "give GoalSpec(sample=...) a function returning a valid state in the region"
        )
    return ompl_text


def draw_goal(
    sample: Callable[[], Any] | None,
    attempts: int,
    accept: Accept,
    distance: Callable[[FloatArray], float],
    threshold: float,
    frame: Frame,
) -> FloatArray | None:
    """Return an accepted goal state in planning coordinates, or None."""
    if sample is None:
        return None
    for _ in range(attempts):
        x = sample()
        if x is None:
            continue
        y = accept(x)
        if y is not None and float(distance(frame.to_x(y))) <= threshold:
            return y
    return None


def query_goal(
    si: Any,
    alloc: Callable[..., Any],
    frame: Frame,
    accept: Accept,
    sink: ErrorSink,
    goal: GoalSpec | None,
    goal_state: tuple[FloatArray, float] | None,
    *,
    one_state: bool,
    anchor: Callable[[Any], None] | None,
) -> tuple[Any, str | None]:
    """The OMPL goal of a query: a goal state, or a :class:`GoalSpec` region.

    Args:
        si: the space information.
        alloc: ``alloc(y, anchor=...)`` a new OMPL state at planning coordinates.
        frame: ambient <-> planning coordinates.
        accept: projects and checks the goal sampler's states.
        sink: where a callback's exception is recorded.
        goal: the goal region (when ``goal_state`` is None).
        goal_state: ``(x (n,) ambient, threshold)``: one C++ ``GoalStates`` goal.
        one_state: give the region as one sampled C++ goal state (the PRM
            family: its checker thread must never call Python).
        anchor: anchors a state as an atlas chart, or None.

    Returns:
        ``(goal, None)``; ``(None, "invalid_goal")`` when a one-state goal has
        no acceptable sample; ``(None, None)`` when a callback raised (kept in
        ``sink``).
    """
    if goal_state is not None:
        states = ob.GoalStates(si)
        states.addState(alloc(frame.to_y(goal_state[0]), anchor=True))
        states.setThreshold(goal_state[1])
        return states, None
    assert goal is not None
    first = draw_goal(
        goal.sample, goal.sample_attempts, accept, goal.distance, goal.threshold, frame
    )
    if sink.error is not None:
        return None, None
    if not one_state:
        return make_goal_region(si, goal, frame, accept, sink, first, anchor), None
    if first is None:
        return None, "invalid_goal"
    states = ob.GoalStates(si)  # C++ goal: PRM's checker thread stays C++
    states.addState(alloc(first, anchor=True))
    states.setThreshold(1e-9)
    return states, None
