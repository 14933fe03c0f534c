"""Paths in a constrained space: re-checked in travel direction, densified.

:class:`SpacePaths` holds what a path needs of a
:class:`~dexplan.planning.ompl.problem.PlanningProblem`'s space (the space
information, the constrained space, the coordinate frame, the constraint,
the validity test and the motion fallback) and turns OMPL paths into
:class:`~dexplan.planning.ompl.results.PathCheck` records of ambient states.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from typing import Any

import numpy as np
from ompl import geometric as og

from dexplan.core.errors import InvalidInputError
from dexplan.core.typing import FloatArray
from dexplan.planning.ompl.motions import FallbackMotions
from dexplan.planning.ompl.results import PathCheck
from dexplan.planning.ompl.spaces import ConstraintSpec, Frame

__all__ = ["SpacePaths"]


class SpacePaths:
    """State allocation, geodesics and path checks of one constrained space.

    Args:
        si: the OMPL space information (validity checker, motion validator).
        css: the OMPL constrained state space.
        frame: ambient <-> planning coordinates.
        spec: the constraint (manifold, bounds, tolerance).
        is_valid: ``is_valid(x) -> bool`` for an ambient ``(n,)`` state.
        motions: the motion fallback's record, or None.
    """

    def __init__(
        self,
        si: Any,
        css: Any,
        frame: Frame,
        spec: ConstraintSpec,
        is_valid: Callable[[FloatArray], Any],
        motions: FallbackMotions | None,
    ) -> None:
        self._si = si
        self._css = css
        self._frame = frame
        self._spec = spec
        self._is_valid = is_valid
        self._motions = motions

    def alloc(self, y: FloatArray, *, anchor: bool = False) -> Any:
        """A new OMPL state at planning coordinates ``y`` (anchored as a chart when asked)."""
        state = self._css.allocState()
        state.copy(np.asarray(y, dtype=np.float64).tolist())
        if anchor and self._spec.space != "projected":
            self._css.anchorChart(state)
        return state

    def geodesic(self, a: Any, b: Any) -> list[FloatArray]:
        """Planning-coordinate states of the motion a -> b (a and b included).

        The fallback's recorded states where it joined the edge, else OMPL's
        discrete geodesic.
        """
        if self._motions is not None:
            read = self._frame.read
            dense = self._motions.recorded(read(a), read(b))
            if dense is not None:
                return list(dense)
        return self.discrete_geodesic(a, b)

    def discrete_geodesic(self, a: Any, b: Any) -> list[FloatArray]:
        """Planning-coordinate states of OMPL's discrete geodesic a -> b (a and b included)."""
        segment = og.PathGeometric(self._si, a, b)
        segment.interpolate()
        read = self._frame.read
        return [read(segment.getState(i)) for i in range(segment.getStateCount())]

    def post_process(self, path: Any, *, interpolate: bool, check: bool) -> PathCheck:
        """Check (``check``) and densify (``interpolate``) an ``og.PathGeometric``, in order."""
        read = self._frame.read
        m = path.getStateCount()
        states = [path.getState(i) for i in range(m)]
        waypoints = np.array([read(s) for s in states]).reshape(m, self._spec.ambient_dim)
        repaired: list[int] = []
        invalid: list[int] = []
        dense: list[FloatArray] = [waypoints[0]]
        # OMPL's ConstrainedMotionValidator does not check a motion's end state (lazy
        # planners such as LBKPIECE1 then return invalid waypoints): check states too.
        ok = [bool(self._si.isValid(s)) for s in states] if check else [True] * m
        for i in range(m - 1):
            a, b = states[i], states[i + 1]
            ends = ok[i] and ok[i + 1]
            forward = (not check) or (ends and bool(self._si.checkMotion(a, b)))
            if forward:
                piece = self.geodesic(a, b) if interpolate else [waypoints[i], waypoints[i + 1]]
            elif ends and self._si.checkMotion(b, a):
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
        to_x = self._frame.to_x
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
        if not np.all(np.isfinite(arr)):
            raise InvalidInputError("waypoints must be finite")
        path = og.PathGeometric(self._si)
        for x in arr:
            path.append(self.alloc(self._frame.to_y(x)))
        return path

    def interpolate_with_fallback(self, path: Any) -> FloatArray:
        """An ``og.PathGeometric`` densified where a motion fallback may have joined segments.

        See :meth:`~dexplan.planning.ompl.problem.PlanningProblem.interpolate_path`.
        """
        motions = self._motions
        assert motions is not None
        read = self._frame.read
        states = [path.getState(i) for i in range(path.getStateCount())]
        dense = [read(states[0])]
        for a, b in itertools.pairwise(states):
            joined = motions.states(read(a), read(b))  # a record first, then OMPL's motion
            piece = list(joined) if joined is not None else self.discrete_geodesic(a, b)
            dense.extend(piece[1:])
        return self._frame.to_x(np.array(dense).reshape(-1, self._spec.ambient_dim))

    def states_ok(self, ys: FloatArray) -> bool:
        """Whether every planning-coordinate state is on the manifold, in bounds, valid."""
        spec = self._spec
        lo = self._frame.to_y(spec.lower)
        up = self._frame.to_y(spec.upper)
        if np.any(ys < lo) or np.any(ys > up):
            return False
        xs = self._frame.to_x(ys)
        tol = spec.tolerance * (1.0 + 1e-9)
        for x in xs:
            if float(np.linalg.norm(np.asarray(spec.function(x), dtype=np.float64))) > tol:
                return False
            if not bool(self._is_valid(x)):
                return False
        return True
