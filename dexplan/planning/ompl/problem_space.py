"""The constrained space of a planning problem: built, its states, motions and paths.

:class:`ProblemSpace` builds what a
:class:`~dexplan.planning.ompl.problem.PlanningProblem`'s planner runs on (the
constraint, the constrained state space and its space information with the
validity checker, the valid-state sampler, the motion fallback and the grid
projection) and answers questions on ambient states: motions, distances,
interpolation, and paths re-checked in travel direction and densified
(:class:`~dexplan.planning.ompl.results.PathCheck`). Callbacks record their
exceptions in the problem's :class:`~dexplan.planning.ompl.error_sink.ErrorSink`;
the problem re-raises them after each call.
"""

from __future__ import annotations

import ctypes
import itertools
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
from ompl import geometric as og

from dexplan.core.errors import InvalidInputError
from dexplan.core.typing import FloatArray, as_vector
from dexplan.planning.ompl.callbacks import Accept, make_sampler_allocator, make_validity
from dexplan.planning.ompl.error_sink import ErrorSink
from dexplan.planning.ompl.motions import FallbackMotions, MotionFallback
from dexplan.planning.ompl.results import PathCheck
from dexplan.planning.ompl.spaces import (
    ConstraintSpec,
    Frame,
    ProjectionSpec,
    constrained_space,
    make_constraint,
    make_projection,
)

__all__ = ["ProblemSpace"]


def written_in_python(planner: Any) -> bool:
    """Whether ``planner`` is an ``ob.Planner`` subclass defined in Python (not OMPL's own)."""
    return not type(planner).__module__.startswith("ompl")


class ProblemSpace:
    """A constrained state space with its checks, sampler, motions and paths.

    Args:
        spec: the manifold and its bounds.
        is_valid: ``is_valid(x) -> bool`` for an ambient ``(n,)`` state.
        sink: where callbacks record their exceptions.
        valid_sampler, valid_sampler_near, check_sampled_states, projection,
            motion_fallback, fallback_merges_only, fallback_checks: as
            :class:`~dexplan.planning.ompl.problem.PlanningProblem` takes them.

    Attributes:
        frame: ambient <-> planning coordinates.
        constraint: the OMPL constraint. css: the constrained state space.
        si: the space information. accept: projects and checks goal samples.
        motions: the motion fallback's record, or None.
        projection: the OMPL projection evaluator, or None.
        samplers: the Python valid-state samplers OMPL allocated.
    """

    def __init__(
        self,
        spec: ConstraintSpec,
        is_valid: Callable[[FloatArray], Any],
        sink: ErrorSink,
        *,
        valid_sampler: Callable[[], Any] | None = None,
        valid_sampler_near: Callable[[FloatArray, float], Any] | None = None,
        check_sampled_states: bool = True,
        projection: ProjectionSpec | None = None,
        motion_fallback: MotionFallback | None = None,
        fallback_merges_only: bool = True,
        fallback_checks: bool = True,
    ) -> None:
        self._spec = spec
        self._is_valid = is_valid
        self._sink = sink
        self.frame = Frame(spec.ambient_dim, spec.scale)
        self.samplers: list[Any] = []
        self.constraint = make_constraint(spec, self.frame, sink)
        self.ambient, css, si = constrained_space(spec, self.frame, self.constraint)
        si.setStateValidityChecker(make_validity(is_valid, self.frame, sink))
        self.accept = Accept(spec, self.frame, self.constraint, is_valid, True)
        if valid_sampler is not None:
            self._use_valid_sampler(si, valid_sampler, valid_sampler_near, check_sampled_states)
        css.setup()
        si.setup()
        self.css = css
        self.si = si
        self.motions = self._fallback_motions(
            motion_fallback, fallback_merges_only, fallback_checks
        )
        self.projection = (
            make_projection(projection, css, self.frame, sink) if projection is not None else None
        )

    def _fallback_motions(
        self, fallback: MotionFallback | None, merges_only: bool, checks: bool
    ) -> FallbackMotions | None:
        """The motion fallback's record (None without one), the motion validator if ``checks``."""
        if fallback is None:
            return None
        motions = FallbackMotions(
            self.si,
            self.css.allocState,
            fallback,
            self._spec,
            self.frame,
            self._sink,
            merges_only=bool(merges_only),
        )
        if checks:
            self.si.setMotionValidator(motions)
        return motions

    def _use_valid_sampler(
        self,
        si: Any,
        valid_sampler: Callable[[], Any],
        valid_sampler_near: Callable[[FloatArray, float], Any] | None,
        check_sampled_states: bool,
    ) -> None:
        """Make the Python samplers the space information's ``ValidStateSampler``.

        Raises:
            InvalidInputError: ``valid_sampler`` is not callable.

        """
        if not callable(valid_sampler):
            raise InvalidInputError(f"valid_sampler must be callable, got {valid_sampler!r}")
        accept = Accept(
            self._spec, self.frame, self.constraint, self._is_valid, bool(check_sampled_states)
        )
        si.setValidStateSamplerAllocator(
            make_sampler_allocator(
                valid_sampler, valid_sampler_near, accept, self.frame, self._sink, self.samplers
            )
        )

    # ----------------------------------------------------------------- ambient states

    def _y(self, x: object, name: str) -> FloatArray:
        """An ambient ``(n,)`` argument checked, in planning coordinates."""
        return self.frame.to_y(as_vector(x, name, self._spec.ambient_dim))

    def project(self, x: object) -> FloatArray | None:
        """``x`` projected onto the manifold by OMPL, ambient, or None (see the problem's)."""
        y = np.array(self._y(x, "x"), dtype=np.float64)
        ok = self.constraint.project(y)
        return self.frame.to_x(y) if ok else None

    def check_motion(self, a: object, b: object) -> bool:
        """Whether the motion ``a`` -> ``b`` is valid (see the problem's)."""
        ya, yb = self._y(a, "a"), self._y(b, "b")
        return bool(self.si.checkMotion(self.alloc(ya), self.alloc(yb)))

    def distance(self, a: object, b: object) -> float:
        """OMPL's state-space distance of two ambient states (planning units)."""
        ya, yb = self._y(a, "a"), self._y(b, "b")
        return float(self.css.distance(self.alloc(ya), self.alloc(yb)))

    def interpolate(self, a: object, b: object, t: float) -> FloatArray:
        """OMPL's geodesic interpolation from ``a`` (t = 0) to ``b`` (t = 1), ambient."""
        ya, yb = self._y(a, "a"), self._y(b, "b")
        out = self.alloc(ya)
        self.css.interpolate(self.alloc(ya), self.alloc(yb), float(t), out)
        return self.frame.state_x(out)

    def round_trip(self, x: object) -> FloatArray:
        """A state written into an OMPL state of this space and read back, ambient."""
        return self.frame.state_x(self.alloc(self._y(x, "x")))

    def checked_state(self, x: object, name: str) -> FloatArray:
        """An ambient ``(n,)`` argument ``name`` checked to lie on the manifold.

        Raises:
            InvalidInputError: wrong shape, non-finite, or off the manifold.
        """
        xv = as_vector(x, name, self._spec.ambient_dim)
        residual = float(np.linalg.norm(np.asarray(self._spec.function(xv), dtype=np.float64)))
        if residual > self._spec.tolerance:
            raise InvalidInputError(
                f"{name} is off the manifold: |f(x)| = {residual:.3g} > tolerance "
                f"{self._spec.tolerance:.3g}"
            )
        return xv

    def anchor(self) -> Callable[[Any], None] | None:
        """Anchors a state as an atlas chart (None on the projected space, which has none)."""
        if self._spec.space == "projected":
            return None
        css = self.css

        def anchor(state: Any) -> None:
            css.anchorChart(state)

        return anchor

    @contextmanager
    def motion_deadline(self, limit: float) -> Iterator[None]:
        """The motion fallback stops trying ``limit`` seconds from now, until the block ends."""
        if self.motions is None:
            yield
            return
        self.motions.start(limit)
        try:
            yield
        finally:
            self.motions.stop()

    # ----------------------------------------------------------------- paths

    def alloc(self, y: FloatArray, *, anchor: bool = False) -> Any:
        """A new OMPL state at planning coordinates ``y`` (anchored as a chart when asked)."""
        state = self.css.allocState()
        state.copy(np.asarray(y, dtype=np.float64).tolist())
        if anchor and self._spec.space != "projected":
            self.css.anchorChart(state)
        return state

    def add_start(self, pdef: Any, y: FloatArray, *, readable: bool = False) -> None:
        """Add a start state at planning coordinates ``y`` to the ``ob.ProblemDefinition``.

        The binding hands ``pdef.getStartState(i)`` to Python as an *owned*
        object: the first handle Python frees deletes the problem's start
        state, and the problem's own destructor then frees it again. dexplan
        never calls it. ``readable=True`` (the public :class:`ProblemSetup`,
        whose Python planners read their start that way) takes that handle
        once and keeps it, and the problem definition, alive for the rest of
        the process: nanobind returns the same handle for every later
        ``getStartState`` of the state, so nothing is ever freed twice, and
        no freed state's address stays registered to a live handle (a handle
        kept past its state misleads nanobind into giving a later state at
        the same address the wrong type). The cost is one problem definition
        per :meth:`ProblemSetup.set_start`, never released.
        """
        pdef.addStartState(self.alloc(y, anchor=True))
        if readable:
            handle = pdef.getStartState(pdef.getStartStateCount() - 1)
            for obj in (handle, pdef):
                ctypes.pythonapi.Py_IncRef(ctypes.py_object(obj))

    def geodesic(self, a: Any, b: Any) -> list[FloatArray]:
        """Planning-coordinate states of the motion a -> b (a and b included).

        The fallback's recorded states where it joined the edge, else OMPL's
        discrete geodesic.
        """
        if self.motions is not None:
            read = self.frame.read
            dense = self.motions.recorded(read(a), read(b))
            if dense is not None:
                return list(dense)
        return self.discrete_geodesic(a, b)

    def discrete_geodesic(self, a: Any, b: Any) -> list[FloatArray]:
        """Planning-coordinate states of OMPL's discrete geodesic a -> b (a and b included)."""
        segment = og.PathGeometric(self.si, a, b)
        segment.interpolate()
        read = self.frame.read
        return [read(segment.getState(i)) for i in range(segment.getStateCount())]

    def post_process(self, path: Any, *, interpolate: bool, check: bool) -> PathCheck:
        """Check (``check``) and densify (``interpolate``) an ``og.PathGeometric``, in order."""
        read = self.frame.read
        m = path.getStateCount()
        states = [path.getState(i) for i in range(m)]
        waypoints = np.array([read(s) for s in states]).reshape(m, self._spec.ambient_dim)
        repaired: list[int] = []
        invalid: list[int] = []
        dense: list[FloatArray] = [waypoints[0]]
        # OMPL's ConstrainedMotionValidator does not check a motion's end state (lazy
        # planners such as LBKPIECE1 then return invalid waypoints): check states too.
        ok = [bool(self.si.isValid(s)) for s in states] if check else [True] * m
        for i in range(m - 1):
            a, b = states[i], states[i + 1]
            ends = ok[i] and ok[i + 1]
            forward = (not check) or (ends and bool(self.si.checkMotion(a, b)))
            if forward:
                piece = self.geodesic(a, b) if interpolate else [waypoints[i], waypoints[i + 1]]
            elif ends and self.si.checkMotion(b, a):
                repaired.append(i)
                piece = (
                    self.geodesic(b, a)[::-1] if interpolate else [waypoints[i], waypoints[i + 1]]
                )
            else:
                invalid.append(i)
                piece = [waypoints[i], waypoints[i + 1]]
            dense.extend(piece[1:])
        if len(dense) > 1:
            arr = np.array(dense)
            keep = np.ones(arr.shape[0], dtype=bool)
            keep[1:] = np.linalg.norm(np.diff(arr, axis=0), axis=1) > 1e-12
            arr = arr[keep]
        else:
            arr = np.array(dense)
        steps = np.linalg.norm(np.diff(arr, axis=0), axis=1) if arr.shape[0] > 1 else np.zeros(1)
        max_step = float(steps.max()) if steps.size else 0.0
        valid = check and not invalid and self.states_ok(arr)
        to_x = self.frame.to_x
        return PathCheck(
            path=to_x(arr),
            waypoints=to_x(waypoints),
            path_valid=bool(valid),
            repaired_segments=tuple(repaired),
            invalid_segments=tuple(invalid),
            max_step=max_step,
        )

    def geometric_path(self, waypoints: object) -> Any:
        """An ``og.PathGeometric`` of ``(M, n)`` ambient waypoints, M >= 1 (planning coordinates).

        Raises:
            InvalidInputError: wrong shape or non-finite values.
        """
        arr = np.asarray(waypoints, dtype=np.float64)
        n = self._spec.ambient_dim
        if arr.ndim != 2 or arr.shape[1] != n or arr.shape[0] < 1:
            raise InvalidInputError(f"waypoints must have shape (M, {n}), got {arr.shape}")
        if not np.isfinite(arr).all():
            raise InvalidInputError("waypoints must be finite")
        path = og.PathGeometric(self.si)
        for x in arr:
            path.append(self.alloc(self.frame.to_y(x)))
        return path

    def interpolate_with_fallback(self, path: Any) -> FloatArray:
        """An ``og.PathGeometric`` densified where a motion fallback may have joined segments.

        See :meth:`~dexplan.planning.ompl.problem.PlanningProblem.interpolate_path`.
        """
        motions = self.motions
        assert motions is not None
        read = self.frame.read
        states = [path.getState(i) for i in range(path.getStateCount())]
        dense = [read(states[0])]
        for a, b in itertools.pairwise(states):
            joined = motions.states(read(a), read(b))  # a record first, then OMPL's motion
            piece = list(joined) if joined is not None else self.discrete_geodesic(a, b)
            dense.extend(piece[1:])
        return self.frame.to_x(np.array(dense).reshape(-1, self._spec.ambient_dim))

    def states_ok(self, ys: FloatArray) -> bool:
        """Whether every planning-coordinate state is on the manifold, in bounds, valid."""
        spec = self._spec
        lo = self.frame.to_y(spec.lower)
        up = self.frame.to_y(spec.upper)
        if np.any(ys < lo) or np.any(ys > up):
            return False
        xs = self.frame.to_x(ys)
        tol = spec.tolerance * (1.0 + 1e-9)
        for x in xs:
            if float(np.linalg.norm(np.asarray(spec.function(x), dtype=np.float64))) > tol:
                return False
            if not bool(self._is_valid(x)):
                return False
        return True
