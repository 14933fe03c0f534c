"""Unconstrained paths in a box, such as one free finger's joint space.

:func:`plan_joint_path` is the bounded OMPL fallback of the free-finger moves: a
``RealVectorStateSpace``, the Python validity test, a single-query planner and
OMPL's path simplifier. It shares the bounds set-up
(:func:`~dexplan.planning.ompl.spaces.real_vector_space`), the error sink and the
time/iteration termination (:func:`~dexplan.planning.ompl.callbacks.termination`)
with :class:`~dexplan.planning.ompl.problem.PlanningProblem`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from ompl import base as ob
from ompl import geometric as og

from dexplan.core.errors import InvalidInputError, PlannerError
from dexplan.core.typing import FloatArray
from dexplan.planning.ompl._checks import as_int, as_pos
from dexplan.planning.ompl.callbacks import make_validity, termination
from dexplan.planning.ompl.error_sink import ErrorSink
from dexplan.planning.ompl.registry import PLANNERS, check_planner_name, planner_traits
from dexplan.planning.ompl.results import STATUS_NAMES
from dexplan.planning.ompl.runtime import derived_seed, reseed_ompl
from dexplan.planning.ompl.spaces import Frame, real_vector_space

__all__ = ["plan_joint_path"]


def plan_joint_path(
    start: FloatArray,
    goal: FloatArray,
    lower: FloatArray,
    upper: FloatArray,
    is_valid: Callable[[FloatArray], Any],
    *,
    resolution: float,
    time_limit: float,
    max_iterations: int = 1000,
    seed: int | None = None,
    planner: str = "RRTConnect",
) -> FloatArray | None:
    """A valid path between two points of a box, such as one finger's joint space.

    An unconstrained ``RealVectorStateSpace`` with the given bounds, the Python
    validity test, a single-query OMPL planner, then OMPL's path simplifier
    (shortcuts and smoothing, re-checked). The caps make it usable as a
    bounded fallback; with ``seed`` the answer depends on the seed only unless
    the time limit, not ``max_iterations``, stops the search.

    Args:
        start: (n,) start point.
        goal: (n,) goal point.
        lower: (n,) lower bounds.
        upper: (n,) upper bounds.
        is_valid: ``(n,) -> bool``.
        resolution: largest max-norm distance between checked states of a motion.
        time_limit: seconds.
        max_iterations: planner iterations.
        seed: OMPL seed (None: OMPL's current generator).
        planner: a single-query planner of :data:`~dexplan.planning.ompl.registry.PLANNERS`.

    Returns:
        (K, n) waypoints from ``start`` to ``goal`` (K >= 2) whose straight
        legs are valid at ``resolution``, or None when none was found.

    Raises:
        InvalidInputError: bad shapes, bounds, caps or planner name.
        PlannerError: ``is_valid`` raised.
    """
    check_planner_name(planner)
    if planner_traits(planner).multi_query:
        raise InvalidInputError(f"plan_joint_path needs a single-query planner, not {planner}")
    lo, hi, ends = _checked_box(start, goal, lower, upper)
    n = lo.shape[0]
    step = as_pos(resolution, "resolution")
    limit = as_pos(time_limit, "time_limit")
    budget = as_int(max_iterations, "max_iterations", 1)
    if seed is not None:
        reseed_ompl(derived_seed(int(seed), 0))

    space = real_vector_space(lo, hi)
    si = ob.SpaceInformation(space)
    sink = ErrorSink()
    frame = Frame(n, None)
    si.setStateValidityChecker(make_validity(is_valid, frame, sink))
    # OMPL's resolution is a fraction of the space's extent, in its L2 metric:
    # a max-norm step of `step` is at most sqrt(n) * step long
    si.setStateValidityCheckingResolution(min(1.0, step / space.getMaximumExtent()))
    si.setup()
    pdef = ob.ProblemDefinition(si)
    a, b = space.allocState(), space.allocState()
    for i in range(n):
        a[i], b[i] = float(ends[0][i]), float(ends[1][i])
    pdef.setStartAndGoalStates(a, b)
    solver = PLANNERS[planner](si)
    solver.setProblemDefinition(pdef)
    solver.setup()
    with sink.watching(termination(limit, budget)) as ptc:
        status = solver.solve(ptc)
    if sink.error is not None:
        raise PlannerError(
            f"is_valid raised during plan_joint_path: {type(sink.error).__name__}: {sink.error}"
        ) from sink.error
    if STATUS_NAMES.get(status.getStatus().value) != "exact":
        return None
    return _simplified(si, og.PathGeometric(pdef.getSolutionPath()), sink, frame)


def _checked_box(
    start: object, goal: object, lower: object, upper: object
) -> tuple[FloatArray, FloatArray, tuple[FloatArray, FloatArray]]:
    """Return ``(lower, upper, (start, goal))`` as float64 ``(n,)`` arrays, checked.

    Raises:
        InvalidInputError: bounds not finite ``(n,)`` with lower < upper, or an end
            that is not ``n`` finite numbers.

    """
    lo = np.asarray(lower, dtype=np.float64)
    hi = np.asarray(upper, dtype=np.float64)
    n = lo.shape[0] if lo.ndim == 1 else 0
    if n == 0 or hi.shape != (n,) or not np.all(np.isfinite(lo)) or not np.all(lo < hi):
        raise InvalidInputError(
            f"lower and upper must be finite (n,) arrays with lower < upper, got {lo} and {hi}"
        )
    ends = []
    for name, value in (("start", start), ("goal", goal)):
        arr = np.asarray(value, dtype=np.float64)
        if arr.shape != (n,) or not np.all(np.isfinite(arr)):
            raise InvalidInputError(f"{name} must be {n} finite numbers, got {value!r}")
        ends.append(arr)
    return lo, hi, (ends[0], ends[1])


def _simplified(si: Any, path: Any, sink: ErrorSink, frame: Frame) -> FloatArray | None:
    """Return the simplified, re-checked ``path`` as ``(K, n)`` waypoints, or None.

    One pass of vertex reduction and rope shortcutting: most of ``simplifyMax``'s
    gain on these short paths, at a fraction of its collision checks.
    """
    simplifier = og.PathSimplifier(si)
    simplifier.reduceVertices(path)
    simplifier.ropeShortcutPath(path)
    if sink.error is not None or not path.check():
        return None
    return np.array([frame.read(path.getState(k)) for k in range(path.getStateCount())])
