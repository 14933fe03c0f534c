"""State spaces: the constraint and projection specs, bounds, scaling, set-up.

A :class:`ConstraintSpec` (``f(x) = 0`` with an analytic Jacobian and ambient
bounds) becomes an ``ob.Constraint`` inside an ``ob.ProjectedStateSpace``,
``ob.AtlasStateSpace`` or ``ob.TangentBundleStateSpace``, with the matching
``ConstrainedSpaceInformation`` / ``TangentBundleSpaceInformation``
(:func:`constrained_space`); a :class:`ProjectionSpec` becomes the
``ob.ProjectionEvaluator`` of the KPIECE family (:func:`make_projection`).

Coordinates. Callbacks always see **ambient** coordinates ``x`` of shape
``(ambient_dim,)``. When :attr:`ConstraintSpec.scale` is given, OMPL plans in scaled
coordinates ``y = x * scale`` so that its distances, ``delta`` and planner ``range``
weigh metres, radians and quaternion components sensibly; the adapter converts
every callback (``f_y(y) = f(y / scale)``, ``J_y(y) = J(y / scale) / scale``) and
every returned array back to ``x`` (:class:`Frame`). ``delta``, ``range`` and the
goal-state threshold of
:meth:`~dexplan.planning.ompl.problem.PlanningProblem.set_goal_state` are in
planning (scaled) units; ``GoalSpec.distance``/``threshold`` are whatever the
caller's function measures.

Binding facts (ompl 2.0.1 PyPI wheel, nanobind):

- ``Constraint.function(x, out)`` / ``jacobian(x, out)`` receive a read-only NumPy
  view ``x`` and a writable view ``out`` (the Jacobian is Fortran-ordered); a Python
  override costs ~3.3 us per call before any work is done.
- States of a constrained space are read element by element (``state[i]``;
  ``copyToReals`` is unusable from Python, and indexing past the dimension returns
  garbage, so the adapter never does it) and written with ``state.copy(list)``.
  States from ``allocState`` are freed by Python: ``freeState`` is never called.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from ompl import base as ob

from dexplan.core.errors import InvalidInputError
from dexplan.core.typing import FloatArray, as_vector
from dexplan.planning.ompl._checks import as_int, as_pos
from dexplan.planning.ompl.error_sink import ErrorSink

__all__ = [
    "ATLAS_SETTERS",
    "ConstraintSpec",
    "Frame",
    "ProjectionSpec",
    "SpaceKind",
    "constrained_space",
    "make_constraint",
    "make_projection",
    "real_vector_bounds",
    "real_vector_space",
]

SpaceKind = Literal["projected", "atlas", "tangent_bundle"]

# ------------------------------------------------------------------------ specs


@dataclass(frozen=True, eq=False)
class ConstraintSpec:
    """An implicit manifold ``{x : function(x) = 0, lower <= x <= upper}``.

    Attributes:
        ambient_dim: n, the length of the ambient vector ``x``.
        co_dim: k, the number of constraint rows (manifold dimension is n - k).
        function: ``f(x) -> (k,)`` residual; ``x`` is a read-only ``(n,)`` float64
            array valid only during the call (copy it to keep it).
        jacobian: ``J(x) -> (k, n)`` analytic Jacobian of ``function``, or None to
            use OMPL's central finite differences (~100x slower: avoid).
        lower: ``(n,)`` ambient lower bounds.
        upper: ``(n,)`` ambient upper bounds, each > the lower bound.
        tolerance: projection tolerance on ``|f(x)|`` (2-norm).
        max_iterations: Newton iterations allowed per projection.
        space: ``"projected"``, ``"atlas"`` or ``"tangent_bundle"``.
        delta: step of the discrete geodesic (motion checking and interpolation),
            in planning (scaled) units; None keeps OMPL's default (0.05).
        lambda_: maximum wandering ratio of a geodesic (> 1); None keeps OMPL's 2.
        scale: ``(n,)`` positive per-coordinate scale; OMPL plans in ``y = x * scale``.
            None is all ones.
        atlas_params: atlas/tangent-bundle settings by name (``epsilon``, ``rho``,
            ``alpha``, ``exploration``, ``max_charts_per_extension``, ``separated``,
            ``backoff``); ``rho`` defaults to ``5 * delta`` as in OMPL's demos.

    """

    ambient_dim: int
    co_dim: int
    function: Callable[[FloatArray], Any]
    jacobian: Callable[[FloatArray], Any] | None
    lower: FloatArray
    upper: FloatArray
    tolerance: float = 1e-4
    max_iterations: int = 50
    space: SpaceKind = "projected"
    delta: float | None = None
    lambda_: float | None = None
    scale: FloatArray | None = None
    atlas_params: Mapping[str, float | int | bool] = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = as_int(self.ambient_dim, "ambient_dim", 1)
        k = as_int(self.co_dim, "co_dim", 1)
        if k >= n:
            raise InvalidInputError(f"co_dim must be < ambient_dim={n}, got {k}")
        if not callable(self.function):
            raise InvalidInputError(f"function must be callable, got {self.function!r}")
        if self.jacobian is not None and not callable(self.jacobian):
            raise InvalidInputError(f"jacobian must be callable or None, got {self.jacobian!r}")
        lower = as_vector(self.lower, "lower", n)
        upper = as_vector(self.upper, "upper", n)
        if not np.all(lower < upper):
            bad = int(np.argmin(upper - lower))
            raise InvalidInputError(
                f"lower must be < upper in every coordinate; coordinate {bad}: "
                f"{lower[bad]!r} >= {upper[bad]!r}"
            )
        if self.space not in ("projected", "atlas", "tangent_bundle"):
            raise InvalidInputError(
                f"space must be 'projected', 'atlas' or 'tangent_bundle', got {self.space!r}"
            )
        tol = as_pos(self.tolerance, "tolerance")
        as_int(self.max_iterations, "max_iterations", 1)
        if self.delta is not None:
            object.__setattr__(self, "delta", as_pos(self.delta, "delta"))
        if self.lambda_ is not None:
            lam = as_pos(self.lambda_, "lambda_")
            if lam <= 1.0:
                raise InvalidInputError(f"lambda_ must be > 1, got {self.lambda_!r}")
            object.__setattr__(self, "lambda_", lam)
        if self.scale is not None:
            scale = as_vector(self.scale, "scale", n)
            if not np.all(scale > 0.0):
                raise InvalidInputError(f"scale must be > 0 everywhere, got {scale.tolist()!r}")
            object.__setattr__(self, "scale", scale)
        unknown = set(self.atlas_params) - set(ATLAS_SETTERS)
        if unknown:
            raise InvalidInputError(
                f"unknown atlas_params {sorted(unknown)}; valid: {sorted(ATLAS_SETTERS)}"
            )
        object.__setattr__(self, "lower", lower)
        object.__setattr__(self, "upper", upper)
        object.__setattr__(self, "tolerance", tol)
        object.__setattr__(self, "atlas_params", dict(self.atlas_params))

    @property
    def manifold_dim(self) -> int:
        """Dimension of the manifold, ``ambient_dim - co_dim``."""
        return self.ambient_dim - self.co_dim


ATLAS_SETTERS: dict[str, str] = {
    "epsilon": "setEpsilon",
    "rho": "setRho",
    "alpha": "setAlpha",
    "exploration": "setExploration",
    "max_charts_per_extension": "setMaxChartsPerExtension",
    "separated": "setSeparated",
    "backoff": "setBackoff",
}


@dataclass(frozen=True, eq=False)
class ProjectionSpec:
    """A low-dimensional projection for the KPIECE family's grid.

    Attributes:
        dim: m, the projection dimension.
        function: ``p(x) -> (m,)`` for an ambient ``(n,)`` state.
        cell_sizes: ``(m,)`` grid cell sizes, or None to infer them from ``lower``/
            ``upper`` (or from sampled states) as OMPL does: extent / 20.
        lower: ``(m,)`` projection bounds (with ``upper``), or None to estimate them.
        upper: ``(m,)`` projection bounds.

    """

    dim: int
    function: Callable[[FloatArray], Any]
    cell_sizes: FloatArray | None = None
    lower: FloatArray | None = None
    upper: FloatArray | None = None

    def __post_init__(self) -> None:
        m = as_int(self.dim, "dim", 1)
        if not callable(self.function):
            raise InvalidInputError(f"function must be callable, got {self.function!r}")
        if self.cell_sizes is not None:
            cells = as_vector(self.cell_sizes, "cell_sizes", m)
            if not np.all(cells > 0.0):
                raise InvalidInputError(f"cell_sizes must be > 0, got {cells.tolist()!r}")
            object.__setattr__(self, "cell_sizes", cells)
        if (self.lower is None) != (self.upper is None):
            raise InvalidInputError("give both lower and upper projection bounds, or neither")
        if self.lower is not None:
            lower = as_vector(self.lower, "lower", m)
            upper = as_vector(self.upper, "upper", m)
            if not np.all(lower < upper):
                raise InvalidInputError(
                    f"projection lower must be < upper, got {lower.tolist()} / {upper.tolist()}"
                )
            object.__setattr__(self, "lower", lower)
            object.__setattr__(self, "upper", upper)


# ------------------------------------------------------------------ coordinates


def _reader(n: int) -> Callable[[Any], FloatArray]:
    """Return ``read(state) -> (n,)`` planning coordinates of a constrained state."""
    indices = range(n)

    def read(state: Any) -> FloatArray:
        return np.array([state[i] for i in indices], dtype=np.float64)

    return read


class Frame:
    """Conversion between ambient ``x`` and planning ``y = x * scale`` coordinates.

    Args:
        n: the ambient dimension.
        scale: ``(n,)`` positive scale, or None for the identity.

    """

    __slots__ = ("inv", "n", "read", "scale")

    def __init__(self, n: int, scale: FloatArray | None) -> None:
        self.n = n
        self.scale = None if scale is None else scale.copy()
        self.inv = None if scale is None else 1.0 / scale
        self.read = _reader(n)

    def to_x(self, y: FloatArray) -> FloatArray:
        """Return ambient coordinates of planning coordinates ``y`` (``(n,)`` or ``(K, n)``)."""
        return y if self.inv is None else y * self.inv

    def to_y(self, x: FloatArray) -> FloatArray:
        """Return planning coordinates of ambient ``x`` (a new array when unscaled)."""
        return np.array(x, dtype=np.float64) if self.scale is None else x * self.scale

    def state_x(self, state: Any) -> FloatArray:
        """Return the ambient ``(n,)`` coordinates of an OMPL state."""
        y = self.read(state)
        return y if self.inv is None else y * self.inv


# ----------------------------------------------------------------------- set-up


def real_vector_bounds(lower: FloatArray, upper: FloatArray) -> Any:
    """Return ``ob.RealVectorBounds`` with the given ``(n,)`` lower and upper bounds."""
    n = len(lower)
    bounds = ob.RealVectorBounds(n)
    for i in range(n):
        bounds.setLow(i, float(lower[i]))
        bounds.setHigh(i, float(upper[i]))
    return bounds


def real_vector_space(lower: FloatArray, upper: FloatArray) -> Any:
    """Return an ``ob.RealVectorStateSpace`` bounded by ``(n,)`` lower and upper."""
    space = ob.RealVectorStateSpace(len(lower))
    space.setBounds(real_vector_bounds(lower, upper))
    return space


def make_constraint(spec: ConstraintSpec, frame: Frame, sink: ErrorSink) -> Any:
    """Return an ``ob.Constraint`` calling the spec's callbacks in planning coordinates."""
    fun = spec.function
    jac = spec.jacobian
    inv = frame.inv

    class _Constraint(ob.Constraint):
        def function(self, y: FloatArray, out: FloatArray) -> None:
            try:
                out[:] = fun(y if inv is None else y * inv)
            except Exception as exc:  # must not unwind through C++: recorded, re-raised
                sink.record(exc)
                out[:] = np.nan

    class _ConstraintJ(_Constraint):
        def jacobian(self, y: FloatArray, out: FloatArray) -> None:
            try:
                if inv is None:
                    # this class is chosen only when jac is set; mypy does not narrow a closure
                    out[:, :] = jac(y)  # type: ignore[misc]
                else:
                    out[:, :] = np.asarray(jac(y * inv)) * inv  # type: ignore[misc]
            except Exception as exc:  # must not unwind through C++: recorded, re-raised
                sink.record(exc)
                out[:, :] = np.nan

    cls = _Constraint if jac is None else _ConstraintJ
    constraint = cls(spec.ambient_dim, spec.co_dim, spec.tolerance)
    constraint.setMaxIterations(spec.max_iterations)
    return constraint


def constrained_space(spec: ConstraintSpec, frame: Frame, constraint: Any) -> tuple[Any, Any, Any]:
    """Build the constrained state space of ``spec`` (not yet set up).

    The ambient ``RealVectorStateSpace`` is bounded by the spec's bounds in planning
    coordinates; ``delta``, ``lambda_`` and the atlas parameters (``rho`` defaults to
    ``delta * ATLAS_STATE_SPACE_RHO_MULTIPLIER``) are applied.

    Args:
        spec: the manifold.
        frame: its coordinate frame.
        constraint: the ``ob.Constraint`` of :func:`make_constraint`.

    Returns:
        ``(ambient, css, si)``: the ambient space, the constrained state space and
        its (constrained or tangent-bundle) space information.

    Raises:
        InvalidInputError: OMPL rejected an atlas parameter.

    """
    ambient = real_vector_space(frame.to_y(spec.lower), frame.to_y(spec.upper))
    if spec.space == "projected":
        css = ob.ProjectedStateSpace(ambient, constraint)
        si = ob.ConstrainedSpaceInformation(css)
    elif spec.space == "atlas":
        css = ob.AtlasStateSpace(ambient, constraint)
        si = ob.ConstrainedSpaceInformation(css)
    else:
        css = ob.TangentBundleStateSpace(ambient, constraint)
        si = ob.TangentBundleSpaceInformation(css)
    if spec.delta is not None:
        css.setDelta(spec.delta)
    if spec.lambda_ is not None:
        css.setLambda(spec.lambda_)
    if spec.space != "projected":
        atlas = dict(spec.atlas_params)
        atlas.setdefault("rho", css.getDelta() * ob.ATLAS_STATE_SPACE_RHO_MULTIPLIER)
        for key, value in atlas.items():
            try:
                getattr(css, ATLAS_SETTERS[key])(value)
            except (RuntimeError, ValueError, TypeError) as exc:
                raise InvalidInputError(f"atlas_params[{key!r}] = {value!r}: {exc}") from exc
    return ambient, css, si


def make_projection(spec: ProjectionSpec, space: Any, frame: Frame, sink: ErrorSink) -> Any:
    """Return an ``ob.ProjectionEvaluator`` on ``space`` calling the spec's projection.

    Args:
        spec: the projection.
        space: the constrained state space it projects.
        frame: the space's coordinate frame (the projection sees ambient ``x``).
        sink: where a raising projection records its exception.

    Returns:
        The evaluator, with the spec's bounds and cell sizes when given.

    """
    fun = spec.function
    dim = spec.dim
    state_x = frame.state_x

    class _Projection(ob.ProjectionEvaluator):
        def getDimension(self) -> int:  # noqa: N802
            return dim

        def project(self, state: Any, projection: FloatArray) -> None:
            try:
                projection[:] = fun(state_x(state))
            except Exception as exc:  # must not unwind through C++: recorded, re-raised
                sink.record(exc)
                projection[:] = 0.0

    projection = _Projection(space)
    if spec.lower is not None and spec.upper is not None:
        projection.setBounds(real_vector_bounds(spec.lower, spec.upper))
    if spec.cell_sizes is not None:
        projection.inferCellSizes()  # sizes the cell vector (bounds estimated if not given)
        for i in range(dim):
            projection.setCellSizes(i, float(spec.cell_sizes[i]))
    return projection
