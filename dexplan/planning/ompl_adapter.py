"""Generic adapter between NumPy callables and OMPL constrained planning.

This is the only dexplan module that imports :mod:`ompl`. Everything else hands it
plain callables on NumPy vectors:

- a :class:`ConstraintSpec` (``f(x) = 0`` with an analytic Jacobian and ambient
  bounds) becomes an ``ob.Constraint`` inside an ``ob.ProjectedStateSpace``,
  ``ob.AtlasStateSpace`` or ``ob.TangentBundleStateSpace``, with the matching
  ``ConstrainedSpaceInformation`` / ``TangentBundleSpaceInformation``;
- ``is_valid(x) -> bool`` becomes the state validity checker;
- an optional ``valid_sampler() -> x | None`` becomes an ``ob.ValidStateSampler``
  (used by the PRM family; tree planners sample the ambient space and project);
- a :class:`GoalSpec` (distance, threshold, optional sampler) becomes a goal region,
  or a single goal state given to :meth:`PlanningProblem.set_goal_state`;
- an optional :class:`ProjectionSpec` becomes the ``ob.ProjectionEvaluator`` of the
  KPIECE family.

Coordinates. Callbacks always see **ambient** coordinates ``x`` of shape
``(ambient_dim,)``. When :attr:`ConstraintSpec.scale` is given, OMPL plans in scaled
coordinates ``y = x * scale`` so that its distances, ``delta`` and planner ``range``
weigh metres, radians and quaternion components sensibly; the adapter converts
every callback (``f_y(y) = f(y / scale)``, ``J_y(y) = J(y / scale) / scale``) and
every returned array back to ``x``. ``delta``, ``range`` and the goal-state
threshold of :meth:`PlanningProblem.set_goal_state` are in planning (scaled) units;
``GoalSpec.distance``/``threshold`` are whatever the caller's function measures.

Binding facts this module is built around (ompl 2.0.1 PyPI wheel, nanobind):

- ``Constraint.function(x, out)`` / ``jacobian(x, out)`` receive a read-only NumPy
  view ``x`` and a writable view ``out`` (the Jacobian is Fortran-ordered); a Python
  override costs ~3.3 us per call before any work is done.
- No binding releases the GIL. ``PRM.solve`` runs a solution-checking thread; when
  that thread calls Python (a Python goal, a Python termination condition, or goal
  milestones added while it holds PRM's graph mutex) while the main thread waits
  for that mutex or joins it, the process deadlocks (measured: ``GoalStates`` with
  5 states hung 3/3 runs). The adapter therefore gives the PRM family exactly one
  C++ ``ob.GoalStates`` goal (sampled in Python beforehand) and a C++
  ``timedPlannerTerminationCondition``; the checker thread then never enters
  Python. Roadmap growth without a query (:meth:`PlanningProblem.grow_roadmap`)
  calls ``PRM.growRoadmap`` directly: single-threaded, no deadlock possible.
- ``Planner.params()`` (``ompl::base::ParamSet``) is not bound: parameters are
  read from ``printSettings()`` and set through the planner's bound ``setX``
  methods, with their OMPL ParamSet names (``range``, ``goal_bias``...).
- ``RNG.setSeed`` after random numbers were drawn logs an error but *does* reseed
  the global seed generator; every ``RNG`` created afterwards is seeded from it.
  See :class:`PlanningProblem` for what is deterministic.
- ``AORRTC`` hangs in ``solve`` on a constrained space (ignores the termination
  condition) and returns a zero-length "solution" on a plain R^2 problem: it is
  not registered.
- States of a constrained space are read element by element (``state[i]``;
  ``copyToReals`` is unusable from Python, and indexing past the dimension returns
  garbage, so the adapter never does it) and written with ``state.copy(list)``.
  States from ``allocState`` are freed by Python: ``freeState`` is never called.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components as _csgraph_components

from dexplan.exceptions import InvalidInputError, PlannerError
from dexplan.typing import FloatArray, IntArray, as_vector

__all__ = [
    "MULTI_QUERY_PLANNERS",
    "PLANNERS",
    "PLANNER_NOTES",
    "PROJECTION_PLANNERS",
    "UNSUPPORTED_PLANNERS",
    "ConstraintSpec",
    "GoalSpec",
    "PathCheck",
    "PlanningProblem",
    "ProjectionSpec",
    "RoadmapData",
    "SolveResult",
    "available_planners",
    "connected_components",
    "get_log_level",
    "plan_joint_path",
    "set_log_level",
]

SpaceKind = Literal["projected", "atlas", "tangent_bundle"]

# --------------------------------------------------------------------------- logging

_LOG_LEVELS: dict[str, Any] = {
    "none": ou.LOG_NONE,
    "error": ou.LOG_ERROR,
    "warn": ou.LOG_WARN,
    "info": ou.LOG_INFO,
    "debug": ou.LOG_DEBUG,
}


def set_log_level(level: str) -> None:
    """Set OMPL's console log level.

    The adapter sets ``"none"`` when imported: library use is silent, and every
    outcome is reported through :class:`SolveResult`. Raise it to debug a problem.

    Args:
        level: one of ``"none"``, ``"error"``, ``"warn"``, ``"info"``, ``"debug"``.

    Raises:
        InvalidInputError: unknown level.

    """
    if level not in _LOG_LEVELS:
        raise InvalidInputError(f"log level must be one of {sorted(_LOG_LEVELS)}, got {level!r}")
    ou.setLogLevel(_LOG_LEVELS[level])


def get_log_level() -> str:
    """Return OMPL's current console log level as a name (see :func:`set_log_level`)."""
    current = ou.getLogLevel()
    for name, value in _LOG_LEVELS.items():
        if value == current:
            return name
    return "debug"


set_log_level("none")

# --------------------------------------------------------------------------- seeding


def _derived_seed(seed: int, stream: int) -> int:
    """Return a positive 31-bit seed derived from ``(seed, stream)``."""
    state = np.random.SeedSequence([seed, stream]).generate_state(1, dtype=np.uint32)[0]
    return int(state) % (2**31 - 2) + 1


def _reseed_ompl(value: int) -> None:
    """Reseed OMPL's global seed generator without its "already started" log line."""
    previous = ou.getLogLevel()
    ou.setLogLevel(ou.LOG_NONE)
    try:
        ou.RNG.setSeed(value)
    finally:
        ou.setLogLevel(previous)


# --------------------------------------------------------------------------- registry


def _factory(name: str) -> Callable[[Any], Any]:
    cls = getattr(og, name)

    def make(si: Any) -> Any:
        return cls(si)

    make.__name__ = f"make_{name}"
    make.__doc__ = f"Return a new ``ompl.geometric.{name}`` on ``si``."
    return make


PLANNERS: dict[str, Callable[[Any], Any]] = {
    name: _factory(name)
    for name in (
        "BFMT",
        "BITstar",
        "BKPIECE1",
        "FMT",
        "InformedRRTstar",
        "KPIECE1",
        "LBKPIECE1",
        "PRM",
        "PRMstar",
        "RRT",
        "RRTConnect",
        "RRTstar",
        "SORRTstar",
    )
    if hasattr(og, name)
}
"""Planner name -> factory ``f(space_information) -> ompl planner``.

Every entry solved the unit-sphere test problem on the projected, atlas and
tangent-bundle spaces (FMT/BFMT only timed out on the tangent bundle, cleanly)."""

UNSUPPORTED_PLANNERS: dict[str, str] = {
    "AORRTC": (
        "hangs inside solve() on a constrained state space, ignoring the termination "
        "condition, and returns a zero-length path on a plain R^2 problem (ompl 2.0.1 wheel)"
    ),
}
"""Geometric planners of the wheel that are deliberately not registered, with the reason."""

PLANNER_NOTES: dict[str, str] = {
    "BITstar": "optimizing: uses the whole time limit; informed sampling treats the "
    "constrained space as R^n (states are re-checked on the returned path)",
    "InformedRRTstar": "optimizing: uses the whole time limit; informed sampling treats the "
    "constrained space as R^n (states are re-checked on the returned path)",
    "SORRTstar": "optimizing: uses the whole time limit; informed sampling treats the "
    "constrained space as R^n (states are re-checked on the returned path)",
    "RRTstar": "optimizing: uses the whole time limit",
    "PRMstar": "optimizing: uses the whole time limit; multi-query roadmap",
    "PRM": "multi-query roadmap; uses the custom valid state sampler",
    "LBKPIECE1": "lazy: OMPL's ConstrainedMotionValidator does not check a motion's end "
    "state, so it can return invalid waypoints; the re-check reports them as path_invalid",
    "FMT": "batch of num_samples states; timed out on the tangent-bundle space",
    "BFMT": "batch of num_samples states; timed out on the tangent-bundle space",
}
"""Caveats per registered planner (informational)."""

MULTI_QUERY_PLANNERS: frozenset[str] = frozenset({"PRM", "PRMstar"})
"""Planners whose roadmap survives a new start/goal (``clearQuery``); they run a
solution-checking thread, so their goal is always one C++ goal state."""

PROJECTION_PLANNERS: frozenset[str] = frozenset({"KPIECE1", "BKPIECE1", "LBKPIECE1"})
"""Planners that use a :class:`ProjectionSpec` (``setProjectionEvaluator``)."""


def available_planners() -> list[str]:
    """Return the sorted names of the registered planners (keys of :data:`PLANNERS`)."""
    return sorted(PLANNERS)


def _check_planner_name(name: str) -> None:
    if name in PLANNERS:
        return
    if name in UNSUPPORTED_PLANNERS:
        raise PlannerError(
            f"planner {name!r} is not supported: {UNSUPPORTED_PLANNERS[name]}; "
            f"valid planners: {', '.join(available_planners())}"
        )
    raise PlannerError(
        f"unknown planner {name!r}; valid planners: {', '.join(available_planners())}"
    )


# --------------------------------------------------------------------------- parameters

# OMPL ParamSet names whose setter is not "set" + CamelCase(name); candidates in order.
_SETTER_ALIASES: dict[str, tuple[str, ...]] = {
    "failed_expansion_score_factor": ("FailedExpansionCellScoreFactor",),
    "use_k_nearest": ("KNearest", "NearestK", "UseKNearest"),
    "nearest_k": ("NearestK",),
    "number_sampling_attempts": ("NumSamplingAttempts",),
    "ordering_batch_size": ("BatchSize",),
    "delay_collision_checking": ("DelayCC",),
    "use_admissible_heuristic": ("AdmissibleCostToCome",),
    "cache_cc": ("CacheCC",),
    "extended_fmt": ("ExtendedFMT",),
    "drop_unconnected_samples_on_prune": ("DropSamplesOnPrune",),
    "find_approximate_solutions": ("ConsiderApproximateSolutions",),
    "prune_threshold_as_fractional_cost_change": ("PruneThresholdFraction",),
    "stop_on_each_solution_improvement": ("StopOnSolnImprovement",),
    "use_graph_pruning": ("Pruning",),
    "use_just_in_time_sampling": ("JustInTimeSampling",),
    "use_strict_queue_ordering": ("StrictQueueOrdering",),
    "delay_rewiring_to_first_solution": ("DelayRewiringUntilInitialSolution",),
}

_TRUE_WORDS = frozenset({"1", "true", "yes", "on"})
_FALSE_WORDS = frozenset({"0", "false", "no", "off"})


def _declared_params(planner: Any) -> dict[str, str]:
    """Return OMPL's declared parameters of ``planner`` as ``{name: value text}``."""
    params: dict[str, str] = {}
    for line in planner.printSettings().splitlines()[1:]:
        name, sep, value = line.partition(" = ")
        if sep:
            params[name.strip()] = value.strip()
    return params


def _accessors(planner: Any, name: str) -> tuple[Callable[..., Any], Callable[[], Any]] | None:
    """Return the bound ``(setter, getter)`` for the ParamSet name, or None."""
    camel = "".join(part[:1].upper() + part[1:] for part in name.split("_"))
    for suffix in (*_SETTER_ALIASES.get(name, ()), camel):
        setter = getattr(planner, "set" + suffix, None)
        getter = getattr(planner, "get" + suffix, None)
        if callable(setter) and callable(getter):
            return setter, getter
    return None


def _settable_params(planner: Any) -> list[str]:
    return sorted(n for n in _declared_params(planner) if _accessors(planner, n) is not None)


def _coerce_param(planner_name: str, name: str, value: object, current: object) -> object:
    """Convert ``value`` to the type of the parameter's current value, or raise."""
    where = f"parameter {name!r} of planner {planner_name}"
    if isinstance(current, bool):
        if isinstance(value, bool | np.bool_):
            return bool(value)
        if isinstance(value, int | np.integer) and int(value) in (0, 1):
            return bool(value)
        if isinstance(value, str) and value.strip().lower() in _TRUE_WORDS | _FALSE_WORDS:
            return value.strip().lower() in _TRUE_WORDS
        raise PlannerError(f"{where} must be a boolean, got {value!r}")
    if isinstance(current, int):
        number: float
        if isinstance(value, bool | np.bool_):
            raise PlannerError(f"{where} must be an integer, got {value!r}")
        if isinstance(value, int | np.integer) or (
            isinstance(value, float | np.floating) and float(value).is_integer()
        ):
            number = int(value)
        elif isinstance(value, str):
            try:
                number = int(value.strip())
            except ValueError as exc:
                raise PlannerError(f"{where} must be an integer, got {value!r}") from exc
        else:
            raise PlannerError(f"{where} must be an integer, got {value!r}")
        if number < 0:
            raise PlannerError(f"{where} must be >= 0, got {value!r}")
        return number
    if isinstance(value, bool | np.bool_):
        raise PlannerError(f"{where} must be a number, got {value!r}")
    try:
        real = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise PlannerError(f"{where} must be a number, got {value!r}") from exc
    if not math.isfinite(real) or real < 0.0:
        raise PlannerError(f"{where} must be finite and >= 0, got {value!r}")
    if ("bias" in name or "fraction" in name) and real > 1.0:
        raise PlannerError(f"{where} must be in [0, 1], got {value!r}")
    return real


def _set_planner_param(planner: Any, planner_name: str, name: str, value: object) -> None:
    declared = _declared_params(planner)
    if name not in declared:
        raise PlannerError(
            f"unknown parameter {name!r} for planner {planner_name}; valid parameters: "
            f"{', '.join(_settable_params(planner)) or '(none)'}"
        )
    access = _accessors(planner, name)
    if access is None:
        raise PlannerError(
            f"parameter {name!r} of planner {planner_name} is declared by OMPL but has no "
            f"setter in the ompl Python binding; settable parameters: "
            f"{', '.join(_settable_params(planner)) or '(none)'}"
        )
    setter, getter = access
    wanted = _coerce_param(planner_name, name, value, getter())
    try:
        setter(wanted)
    except (RuntimeError, ValueError, TypeError) as exc:
        raise PlannerError(
            f"OMPL rejected {value!r} for parameter {name!r} of planner {planner_name}: {exc}"
        ) from exc
    got = getter()
    same = (
        math.isclose(got, wanted, rel_tol=1e-12, abs_tol=0.0)
        if isinstance(got, float)
        else (got == wanted)
    )
    if not same:
        raise PlannerError(
            f"OMPL ignored {value!r} for parameter {name!r} of planner {planner_name} "
            f"(value is {got!r})"
        )


def check_planner(name: str, params: Mapping[str, object] | None = None) -> None:
    """Fail fast on an unknown planner or parameter, before any planning work.

    The planner is built on a throwaway 2-D space and given ``params``, so the
    same checks as :class:`PlanningProblem` apply.

    Raises:
        PlannerError: unknown or unsupported planner, unknown parameter, bad value.
    """
    _check_planner_name(name)
    space = ob.RealVectorStateSpace(2)
    bounds = ob.RealVectorBounds(2)
    bounds.setLow(-1.0)
    bounds.setHigh(1.0)
    space.setBounds(bounds)
    planner = PLANNERS[name](ob.SpaceInformation(space))
    for key, value in (params or {}).items():
        _set_planner_param(planner, name, str(key), value)


# --------------------------------------------------------------------------- specs


def _as_int(value: object, name: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise InvalidInputError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _as_pos(value: object, name: str) -> float:
    try:
        real = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{name} must be a number, got {value!r}") from exc
    if not math.isfinite(real) or real <= 0.0:
        raise InvalidInputError(f"{name} must be finite and > 0, got {value!r}")
    return real


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
        n = _as_int(self.ambient_dim, "ambient_dim", 1)
        k = _as_int(self.co_dim, "co_dim", 1)
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
        tol = _as_pos(self.tolerance, "tolerance")
        _as_int(self.max_iterations, "max_iterations", 1)
        if self.delta is not None:
            object.__setattr__(self, "delta", _as_pos(self.delta, "delta"))
        if self.lambda_ is not None:
            lam = _as_pos(self.lambda_, "lambda_")
            if lam <= 1.0:
                raise InvalidInputError(f"lambda_ must be > 1, got {self.lambda_!r}")
            object.__setattr__(self, "lambda_", lam)
        if self.scale is not None:
            scale = as_vector(self.scale, "scale", n)
            if not np.all(scale > 0.0):
                raise InvalidInputError(f"scale must be > 0 everywhere, got {scale.tolist()!r}")
            object.__setattr__(self, "scale", scale)
        unknown = set(self.atlas_params) - set(_ATLAS_SETTERS)
        if unknown:
            raise InvalidInputError(
                f"unknown atlas_params {sorted(unknown)}; valid: {sorted(_ATLAS_SETTERS)}"
            )
        object.__setattr__(self, "lower", lower)
        object.__setattr__(self, "upper", upper)
        object.__setattr__(self, "tolerance", tol)
        object.__setattr__(self, "atlas_params", dict(self.atlas_params))

    @property
    def manifold_dim(self) -> int:
        """Dimension of the manifold, ``ambient_dim - co_dim``."""
        return self.ambient_dim - self.co_dim


_ATLAS_SETTERS: dict[str, str] = {
    "epsilon": "setEpsilon",
    "rho": "setRho",
    "alpha": "setAlpha",
    "exploration": "setExploration",
    "max_charts_per_extension": "setMaxChartsPerExtension",
    "separated": "setSeparated",
    "backoff": "setBackoff",
}


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
        _as_int(self.max_samples, "max_samples", 1)
        _as_int(self.sample_attempts, "sample_attempts", 1)


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
        m = _as_int(self.dim, "dim", 1)
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


@dataclass(frozen=True, eq=False)
class RoadmapData:
    """A planner's graph, extracted from ``ob.PlannerData``.

    Attributes:
        vertices: ``(N, n)`` ambient states.
        edges: ``(E, 2)`` int64 vertex indices ``(from, to)`` as OMPL reports them
            (the PRM family reports each undirected edge in both directions).
        start_ids: ``(S,)`` int64 indices of start vertices.
        goal_ids: ``(G,)`` int64 indices of goal vertices.

    """

    vertices: FloatArray
    edges: IntArray
    start_ids: IntArray
    goal_ids: IntArray

    @property
    def num_vertices(self) -> int:
        """N, the number of vertices."""
        return int(self.vertices.shape[0])

    def components(self) -> tuple[IntArray, IntArray]:
        """Return :func:`connected_components` of this graph (edges undirected)."""
        return connected_components(self.num_vertices, self.edges)


def connected_components(n: int, edges: object) -> tuple[IntArray, IntArray]:
    """Label the connected components of an undirected graph.

    Args:
        n: number of vertices N (vertices are ``0..N-1``).
        edges: ``(E, 2)`` integer vertex pairs; direction is ignored, self-loops and
            duplicates are allowed.

    Returns:
        ``(labels, sizes)``: ``labels`` ``(N,)`` int64, the component of each vertex,
        numbered ``0..C-1`` by first appearance; ``sizes`` ``(C,)`` int64 vertex counts.

    Raises:
        InvalidInputError: negative ``n``, wrong edge shape or an index out of range.

    """
    n = _as_int(n, "n", 0)
    arr = np.asarray(edges)
    if arr.size == 0:
        arr = np.zeros((0, 2), dtype=np.int64)
    if arr.ndim != 2 or arr.shape[1] != 2 or not np.issubdtype(arr.dtype, np.integer):
        raise InvalidInputError(f"edges must be an (E, 2) integer array, got shape {arr.shape}")
    arr = arr.astype(np.int64, copy=False)
    if arr.size and (arr.min() < 0 or arr.max() >= n):
        raise InvalidInputError(
            f"edges index vertices outside 0..{n - 1}: min {arr.min()}, max {arr.max()}"
        )
    if n == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    graph = coo_matrix(
        (np.ones(arr.shape[0], dtype=np.int8), (arr[:, 0], arr[:, 1])), shape=(n, n)
    ).tocsr()
    _, raw = _csgraph_components(graph, directed=False)
    # renumber by first appearance so labels do not depend on scipy's internals
    _, first, inverse = np.unique(raw, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    labels = rank[inverse].astype(np.int64)
    sizes = np.bincount(labels, minlength=order.size).astype(np.int64)
    return labels, sizes


@dataclass(frozen=True, eq=False)
class PathCheck:
    """A path re-checked in travel direction (see :meth:`PlanningProblem.check_path`).

    Attributes:
        path: ``(K, n)`` ambient states: the densified discrete geodesics when
            interpolating, else the waypoints.
        waypoints: ``(M, n)`` ambient waypoints that were checked.
        path_valid: every state of ``path`` is on the manifold (within tolerance), in
            bounds and valid, and every segment is a valid motion in travel direction
            (directly or after repair).
        repaired_segments: segments ``i`` (``i -> i+1``) whose forward motion failed
            but whose reverse motion was valid; their states are the reversed reverse
            geodesic.
        invalid_segments: segments that failed both ways, or with an invalid end.
        max_step: largest planning-space distance between consecutive path states.

    """

    path: FloatArray
    waypoints: FloatArray
    path_valid: bool
    repaired_segments: tuple[int, ...]
    invalid_segments: tuple[int, ...]
    max_step: float


@dataclass(frozen=True, eq=False)
class SolveResult:
    """Outcome of :meth:`PlanningProblem.solve`.

    Attributes:
        status: ``"exact"``, ``"approximate"``, ``"timeout"``, ``"invalid_start"``,
            ``"invalid_goal"``, ``"unrecognized_goal"``, ``"crash"``, ``"abort"``,
            ``"infeasible"``, ``"unknown"`` (OMPL's statuses), or ``"path_invalid"``:
            OMPL reported an exact solution that fails the travel-direction re-check.
        solved: exact solution whose every state and segment passed the re-check.
        path: ``(K, n)`` ambient states in travel order (densified along the
            discrete geodesics when ``interpolate``), or None without a path.
        waypoints: ``(M, n)`` ambient states the planner returned, or None.
        time_s: wall time of the call.
        planner: planner name.
        path_valid: every path state satisfies the constraint within tolerance, the
            bounds and ``is_valid``, and every segment is a valid motion in travel
            direction (directly or after repair). False without a path.
        repaired_segments: waypoint segments ``i`` (``i -> i+1``) whose forward motion
            failed but whose reverse motion was valid; their states are the reversed
            geodesic (direction-dependent projection).
        invalid_segments: waypoint segments that failed both ways.
        max_step: largest planning-space distance between consecutive path states.
        goal_distance: OMPL's solution difference (0 for exact), NaN without a path.
        message: short human-readable detail.

    """

    status: str
    solved: bool
    path: FloatArray | None
    waypoints: FloatArray | None
    time_s: float
    planner: str
    path_valid: bool
    repaired_segments: tuple[int, ...] = ()
    invalid_segments: tuple[int, ...] = ()
    max_step: float = math.nan
    goal_distance: float = math.nan
    message: str = ""


_STATUS_NAMES: dict[int, str] = {
    0: "unknown",
    1: "invalid_start",
    2: "invalid_goal",
    3: "unrecognized_goal",
    4: "timeout",
    5: "approximate",
    6: "exact",
    7: "crash",
    8: "abort",
    9: "infeasible",
}

# --------------------------------------------------------------------------- callbacks


class _ErrorSink:
    """First exception raised by a Python callback during a solve.

    Exceptions must not unwind through OMPL's C++ frames (or its threads): callbacks
    record them here, answer "invalid", and terminate the running solve.
    """

    __slots__ = ("error", "ptc")

    def __init__(self) -> None:
        self.error: BaseException | None = None
        self.ptc: Any = None

    def record(self, exc: BaseException) -> None:
        if self.error is None:
            self.error = exc
        if self.ptc is not None:
            self.ptc.terminate()


def _reader(n: int) -> Callable[[Any], FloatArray]:
    """Return ``read(state) -> (n,)`` planning coordinates of a constrained state."""
    indices = range(n)

    def read(state: Any) -> FloatArray:
        return np.array([state[i] for i in indices], dtype=np.float64)

    return read


class _Frame:
    """Conversion between ambient ``x`` and planning ``y = x * scale`` coordinates."""

    __slots__ = ("inv", "n", "read", "scale")

    def __init__(self, n: int, scale: FloatArray | None) -> None:
        self.n = n
        self.scale = None if scale is None else scale.copy()
        self.inv = None if scale is None else 1.0 / scale
        self.read = _reader(n)

    def to_x(self, y: FloatArray) -> FloatArray:
        return y if self.inv is None else y * self.inv

    def to_y(self, x: FloatArray) -> FloatArray:
        return np.array(x, dtype=np.float64) if self.scale is None else x * self.scale

    def state_x(self, state: Any) -> FloatArray:
        y = self.read(state)
        return y if self.inv is None else y * self.inv


def _make_constraint(spec: ConstraintSpec, frame: _Frame, sink: _ErrorSink) -> Any:
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


def _make_validity(
    is_valid: Callable[[FloatArray], Any], frame: _Frame, sink: _ErrorSink
) -> Callable[[Any], bool]:
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


class _Accept:
    """Turn a candidate ambient state into an on-manifold, in-bounds, valid one."""

    __slots__ = ("check_valid", "constraint", "frame", "fun", "is_valid", "lo", "tol", "up")

    def __init__(
        self,
        spec: ConstraintSpec,
        frame: _Frame,
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
        if x.shape != (self.frame.n,) or not np.all(np.isfinite(x)):
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


def _make_sampler_allocator(
    sample: Callable[[], Any],
    sample_near: Callable[[FloatArray, float], Any] | None,
    accept: _Accept,
    frame: _Frame,
    sink: _ErrorSink,
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


def _make_projection(spec: ProjectionSpec, space: Any, frame: _Frame, sink: _ErrorSink) -> Any:
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
        bounds = ob.RealVectorBounds(dim)
        for i in range(dim):
            bounds.setLow(i, float(spec.lower[i]))
            bounds.setHigh(i, float(spec.upper[i]))
        projection.setBounds(bounds)
    if spec.cell_sizes is not None:
        projection.inferCellSizes()  # sizes the cell vector (bounds estimated if not given)
        for i in range(dim):
            projection.setCellSizes(i, float(spec.cell_sizes[i]))
    return projection


def _make_goal_region(
    si: Any,
    spec: GoalSpec,
    frame: _Frame,
    accept: _Accept,
    sink: _ErrorSink,
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
                    y = _draw_goal(sample, attempts, accept, distance, spec.threshold, frame)
                except Exception as exc:  # must not unwind through C++: recorded, re-raised
                    sink.record(exc)
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


def _draw_goal(
    sample: Callable[[], Any] | None,
    attempts: int,
    accept: _Accept,
    distance: Callable[[FloatArray], float],
    threshold: float,
    frame: _Frame,
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


# --------------------------------------------------------------------------- problem


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
    ) -> None:
        if not isinstance(constraint, ConstraintSpec):
            raise InvalidInputError(f"constraint must be a ConstraintSpec, got {constraint!r}")
        if not callable(is_valid):
            raise InvalidInputError(f"is_valid must be callable, got {is_valid!r}")
        _check_planner_name(planner)
        if seed is not None:
            seed = _as_int(seed, "seed", 0)
        self._spec = constraint
        self._planner_name = planner
        self._seed = seed
        self._solve_count = 0
        self._is_valid = is_valid
        self._projection_spec = projection
        self._sink = _ErrorSink()
        self._frame = _Frame(constraint.ambient_dim, constraint.scale)
        self._samplers: list[Any] = []
        if seed is not None:
            _reseed_ompl(_derived_seed(seed, 0))

        n = constraint.ambient_dim
        lo = self._frame.to_y(constraint.lower)
        up = self._frame.to_y(constraint.upper)
        ambient = ob.RealVectorStateSpace(n)
        bounds = ob.RealVectorBounds(n)
        for i in range(n):
            bounds.setLow(i, float(lo[i]))
            bounds.setHigh(i, float(up[i]))
        ambient.setBounds(bounds)
        self._ambient = ambient
        self._constraint = _make_constraint(constraint, self._frame, self._sink)
        if constraint.space == "projected":
            css = ob.ProjectedStateSpace(ambient, self._constraint)
            si = ob.ConstrainedSpaceInformation(css)
        elif constraint.space == "atlas":
            css = ob.AtlasStateSpace(ambient, self._constraint)
            si = ob.ConstrainedSpaceInformation(css)
        else:
            css = ob.TangentBundleStateSpace(ambient, self._constraint)
            si = ob.TangentBundleSpaceInformation(css)
        if constraint.delta is not None:
            css.setDelta(constraint.delta)
        if constraint.lambda_ is not None:
            css.setLambda(constraint.lambda_)
        if constraint.space != "projected":
            atlas = dict(constraint.atlas_params)
            atlas.setdefault("rho", css.getDelta() * ob.ATLAS_STATE_SPACE_RHO_MULTIPLIER)
            for key, value in atlas.items():
                try:
                    getattr(css, _ATLAS_SETTERS[key])(value)
                except (RuntimeError, ValueError, TypeError) as exc:
                    raise InvalidInputError(f"atlas_params[{key!r}] = {value!r}: {exc}") from exc
        si.setStateValidityChecker(_make_validity(is_valid, self._frame, self._sink))
        self._accept = _Accept(constraint, self._frame, self._constraint, is_valid, True)
        if valid_sampler is not None:
            if not callable(valid_sampler):
                raise InvalidInputError(f"valid_sampler must be callable, got {valid_sampler!r}")
            accept = _Accept(
                constraint, self._frame, self._constraint, is_valid, bool(check_sampled_states)
            )
            si.setValidStateSamplerAllocator(
                _make_sampler_allocator(
                    valid_sampler,
                    valid_sampler_near,
                    accept,
                    self._frame,
                    self._sink,
                    self._samplers,
                )
            )
        css.setup()
        si.setup()
        self._css = css
        self._si = si
        self._projection = (
            _make_projection(projection, css, self._frame, self._sink)
            if projection is not None
            else None
        )
        self._params: dict[str, object] = {}
        self._starts: list[FloatArray] = []
        self._goal: GoalSpec | None = None
        self._goal_state: tuple[FloatArray, float] | None = None
        self._query_dirty = True
        self._pdef = ob.ProblemDefinition(si)
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
        return self._planner_name in MULTI_QUERY_PLANNERS

    # ----------------------------------------------------------------- planner

    def _new_planner(self) -> Any:
        planner = PLANNERS[self._planner_name](self._si)
        if self._projection is not None and self._planner_name in PROJECTION_PLANNERS:
            planner.setProjectionEvaluator(self._projection)
        if self._spec.space != "projected" and callable(getattr(planner, "setRange", None)):
            planner.setRange(float(self._css.getRho_s()))  # as OMPL's demos; params override
        for name, value in self._params.items():
            _set_planner_param(planner, self._planner_name, name, value)
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
        _set_planner_param(self._planner, self._planner_name, name, value)
        self._params[name] = value

    def parameters(self) -> dict[str, str]:
        """Return the planner's settable parameters and their current values (text)."""
        declared = _declared_params(self._planner)
        return {name: declared[name] for name in _settable_params(self._planner)}

    # ----------------------------------------------------------------- query

    def _checked_state(self, x: object, name: str) -> FloatArray:
        xv = as_vector(x, name, self._spec.ambient_dim)
        residual = float(np.linalg.norm(np.asarray(self._spec.function(xv), dtype=np.float64)))
        if residual > self._spec.tolerance:
            raise InvalidInputError(
                f"{name} is off the manifold: |f(x)| = {residual:.3g} > tolerance "
                f"{self._spec.tolerance:.3g}"
            )
        return xv

    def set_start(self, x: object) -> None:
        """Replace the start states by ``x`` ``(n,)`` (on the manifold)."""
        self._starts = [self._checked_state(x, "start")]
        self._query_dirty = True

    def add_start(self, x: object) -> None:
        """Add a start state ``x`` ``(n,)`` (on the manifold)."""
        self._starts.append(self._checked_state(x, "start"))
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
        xv = self._checked_state(x, "goal")
        thr = float(threshold)
        if not math.isfinite(thr) or thr < 0.0:
            raise InvalidInputError(f"threshold must be finite and >= 0, got {threshold!r}")
        self._goal_state = (xv, thr)
        self._goal = None
        self._query_dirty = True

    def _alloc(self, y: FloatArray, *, anchor: bool = False) -> Any:
        state = self._css.allocState()
        state.copy(np.asarray(y, dtype=np.float64).tolist())
        if anchor and self._spec.space != "projected":
            self._css.anchorChart(state)
        return state

    def _anchor(self) -> Callable[[Any], None] | None:
        if self._spec.space == "projected":
            return None
        css = self._css

        def anchor(state: Any) -> None:
            css.anchorChart(state)

        return anchor

    def _build_query(self) -> str | None:
        """Build a fresh ProblemDefinition; return a status name if impossible."""
        pdef = ob.ProblemDefinition(self._si)
        for x in self._starts:
            pdef.addStartState(self._alloc(self._frame.to_y(x), anchor=True))
        if self._goal_state is not None:
            goal = ob.GoalStates(self._si)
            goal.addState(self._alloc(self._frame.to_y(self._goal_state[0]), anchor=True))
            goal.setThreshold(self._goal_state[1])
        else:
            spec = self._goal
            assert spec is not None
            first = _draw_goal(
                spec.sample,
                spec.sample_attempts,
                self._accept,
                spec.distance,
                spec.threshold,
                self._frame,
            )
            if self._sink.error is not None:
                return None
            if self.is_multi_query:
                if first is None:
                    return "invalid_goal"
                goal = ob.GoalStates(self._si)  # C++ goal: PRM's checker thread stays C++
                goal.addState(self._alloc(first, anchor=True))
                goal.setThreshold(1e-9)
            else:
                goal = _make_goal_region(
                    self._si, spec, self._frame, self._accept, self._sink, first, self._anchor()
                )
        pdef.setGoal(goal)
        self._pdef = pdef
        if self.is_multi_query:
            self._planner.setProblemDefinition(pdef)
            self._planner.clearQuery()
        else:
            self._planner = self._new_planner()
        self._planner.setup()
        self._query_dirty = False
        return None

    # ----------------------------------------------------------------- solving

    def _raise_callback_error(self) -> None:
        error = self._sink.error
        if error is not None:
            self._sink.error = None
            raise PlannerError(
                f"a callback raised during planning with {self._planner_name}: "
                f"{type(error).__name__}: {error}"
            ) from error

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
        limit = _as_pos(time_limit, "time_limit")
        self._solve_count += 1
        if self._seed is not None:
            _reseed_ompl(_derived_seed(self._seed, self._solve_count))
        ptc = ob.timedPlannerTerminationCondition(limit)
        if max_milestones is not None:
            target = _as_int(max_milestones, "max_milestones", 1)
            planner = self._planner
            sink = self._sink

            def reached() -> bool:
                return sink.error is not None or planner.milestoneCount() >= target

            ptc = ob.plannerOrTerminationCondition(ptc, ob.PlannerTerminationCondition(reached))
        self._sink.ptc = ptc
        try:
            self._planner.growRoadmapPtc(ptc)
        finally:
            self._sink.ptc = None
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
                (steps <= ``lambda_ * delta`` in planning units).
            check_path: re-check the path in travel direction (motions, constraint,
                bounds, validity); with False, ``path_valid`` is False.

        Returns:
            The :class:`SolveResult`; "no path" is a status, not an exception.

        Raises:
            PlannerError: no start or goal set, or a callback raised during planning.

        """
        limit = _as_pos(time_limit, "time_limit")
        if not self._starts:
            raise PlannerError("no start state: call set_start() before solve()")
        if self._goal is None and self._goal_state is None:
            raise PlannerError("no goal: call set_goal() or set_goal_state() before solve()")
        t0 = time.perf_counter()
        self._solve_count += 1
        if self._seed is not None:
            _reseed_ompl(_derived_seed(self._seed, self._solve_count))
        if self._query_dirty:
            early = self._build_query()
            self._raise_callback_error()
            if early is not None:
                return SolveResult(
                    status=early,
                    solved=False,
                    path=None,
                    waypoints=None,
                    time_s=time.perf_counter() - t0,
                    planner=self._planner_name,
                    path_valid=False,
                    message="no acceptable goal sample",
                )
        ptc = ob.timedPlannerTerminationCondition(limit)
        if max_iterations is not None:
            if self.is_multi_query:
                raise PlannerError(
                    f"max_iterations is for single-query planners, not {self._planner_name} "
                    "(its solution checker runs in a second thread)"
                )
            budget = _as_int(max_iterations, "max_iterations", 1)
            count = [0]

            def spent() -> bool:
                count[0] += 1
                return count[0] > budget

            ptc = ob.plannerOrTerminationCondition(ptc, ob.PlannerTerminationCondition(spent))
        self._sink.ptc = ptc
        try:
            status = self._planner.solve(ptc)
        finally:
            self._sink.ptc = None
        self._raise_callback_error()
        name = _STATUS_NAMES.get(status.getStatus().value, "unknown")
        if name not in ("exact", "approximate") or not self._pdef.hasSolution():
            return SolveResult(
                status=name,
                solved=False,
                path=None,
                waypoints=None,
                time_s=time.perf_counter() - t0,
                planner=self._planner_name,
                path_valid=False,
                message=status.asString(),
            )
        path = og.PathGeometric(self._pdef.getSolutionPath())
        checked = self._post_process(path, interpolate=interpolate, check=check_path)
        self._raise_callback_error()
        goal_distance = 0.0 if name == "exact" else float(self._pdef.getSolutionDifference())
        valid = checked.path_valid
        final = "path_invalid" if (name == "exact" and check_path and not valid) else name
        return SolveResult(
            status=final,
            solved=final == "exact" and valid,
            path=checked.path,
            waypoints=checked.waypoints,
            time_s=time.perf_counter() - t0,
            planner=self._planner_name,
            path_valid=valid,
            repaired_segments=checked.repaired_segments,
            invalid_segments=checked.invalid_segments,
            max_step=checked.max_step,
            goal_distance=goal_distance,
            message=status.asString(),
        )

    def _geodesic(self, a: Any, b: Any) -> list[FloatArray]:
        """Planning-coordinate states of the discrete geodesic a -> b (a and b included)."""
        segment = og.PathGeometric(self._si, a, b)
        segment.interpolate()
        read = self._frame.read
        return [read(segment.getState(i)) for i in range(segment.getStateCount())]

    def _post_process(self, path: Any, *, interpolate: bool, check: bool) -> PathCheck:
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
                piece = self._geodesic(a, b) if interpolate else [waypoints[i], waypoints[i + 1]]
            elif ends and self._si.checkMotion(b, a):
                repaired.append(i)
                piece = (
                    self._geodesic(b, a)[::-1] if interpolate else [waypoints[i], waypoints[i + 1]]
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
        valid = check and not invalid and self._states_ok(arr)
        to_x = self._frame.to_x
        return PathCheck(
            path=to_x(arr),
            waypoints=to_x(waypoints),
            path_valid=bool(valid),
            repaired_segments=tuple(repaired),
            invalid_segments=tuple(invalid),
            max_step=max_step,
        )

    def check_path(self, waypoints: object, *, interpolate: bool = True) -> PathCheck:
        """Re-check (and densify) any path of ambient states in travel direction.

        Each segment ``i -> i+1`` must be a valid motion along the space's discrete
        geodesic; when only the reverse motion is valid (projection is
        direction-dependent) the reversed reverse geodesic replaces it. Every
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
        arr = np.asarray(waypoints, dtype=np.float64)
        n = self._spec.ambient_dim
        if arr.ndim != 2 or arr.shape[1] != n or arr.shape[0] < 1:
            raise InvalidInputError(f"waypoints must have shape (M, {n}), got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise InvalidInputError("waypoints must be finite")
        path = og.PathGeometric(self._si)
        for x in arr:
            path.append(self._alloc(self._frame.to_y(x)))
        result = self._post_process(path, interpolate=interpolate, check=True)
        self._raise_callback_error()
        return result

    def _states_ok(self, ys: FloatArray) -> bool:
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

    # ----------------------------------------------------------------- data

    def planner_data(self) -> RoadmapData:
        """Return the planner's current graph (roadmap or trees) in ambient coordinates."""
        pd = ob.PlannerData(self._si)
        self._planner.getPlannerData(pd)
        n = self._spec.ambient_dim
        count = int(pd.numVertices())
        read = self._frame.read
        vertices = np.empty((count, n), dtype=np.float64)
        pairs: list[tuple[int, int]] = []
        for i in range(count):
            vertices[i] = read(pd.getVertex(i).getState())
            pairs.extend((i, int(j)) for j in pd.getEdges(i))
        edges = np.array(pairs, dtype=np.int64).reshape(-1, 2)
        starts = np.array(
            [pd.getStartIndex(k) for k in range(pd.numStartVertices())], dtype=np.int64
        )
        goals = np.array([pd.getGoalIndex(k) for k in range(pd.numGoalVertices())], dtype=np.int64)
        return RoadmapData(
            vertices=self._frame.to_x(vertices), edges=edges, start_ids=starts, goal_ids=goals
        )

    def clear(self) -> None:
        """Forget everything the planner built (roadmap, trees, atlas charts)."""
        self._planner.clear()
        self._css.clear()
        self._query_dirty = True

    def project(self, x: object) -> FloatArray | None:
        """Project an ambient ``(n,)`` point onto the manifold with OMPL's projection.

        Returns:
            The projected ``(n,)`` ambient point, or None if projection failed.

        """
        xv = as_vector(x, "x", self._spec.ambient_dim)
        y = np.array(self._frame.to_y(xv), dtype=np.float64)
        ok = self._constraint.project(y)
        self._raise_callback_error()
        return self._frame.to_x(y) if ok else None

    def check_motion(self, a: object, b: object) -> bool:
        """Whether the discrete geodesic from ``a`` to ``b`` (ambient ``(n,)``) is valid."""
        ya = self._frame.to_y(as_vector(a, "a", self._spec.ambient_dim))
        yb = self._frame.to_y(as_vector(b, "b", self._spec.ambient_dim))
        ok = bool(self._si.checkMotion(self._alloc(ya), self._alloc(yb)))
        self._raise_callback_error()
        return ok

    def distance(self, a: object, b: object) -> float:
        """OMPL's state-space distance of two ambient ``(n,)`` states (planning units)."""
        ya = self._frame.to_y(as_vector(a, "a", self._spec.ambient_dim))
        yb = self._frame.to_y(as_vector(b, "b", self._spec.ambient_dim))
        return float(self._css.distance(self._alloc(ya), self._alloc(yb)))

    def interpolate(self, a: object, b: object, t: float) -> FloatArray:
        """OMPL's geodesic interpolation from ``a`` (t = 0) to ``b`` (t = 1), ambient."""
        ya = self._frame.to_y(as_vector(a, "a", self._spec.ambient_dim))
        yb = self._frame.to_y(as_vector(b, "b", self._spec.ambient_dim))
        out = self._alloc(ya)
        self._css.interpolate(self._alloc(ya), self._alloc(yb), float(t), out)
        self._raise_callback_error()
        return self._frame.state_x(out)

    def round_trip(self, x: object) -> FloatArray:
        """A state written into an OMPL state of this space and read back, ambient.

        (The binding's ``serialize`` takes a raw capsule and ``copyFromReals`` a
        ``std::vector`` that Python lists do not convert to, so this is the
        state I/O the binding offers.)
        """
        y = self._frame.to_y(as_vector(x, "x", self._spec.ambient_dim))
        return self._frame.state_x(self._alloc(y))

    def valid_sampler_count(self) -> int:
        """Return how many Python valid-state samplers OMPL allocated (diagnostics)."""
        return len(self._samplers)


# ------------------------------------------------------------ unconstrained paths


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
        planner: a single-query planner of :data:`PLANNERS`.

    Returns:
        (K, n) waypoints from ``start`` to ``goal`` (K >= 2) whose straight
        legs are valid at ``resolution``, or None when none was found.

    Raises:
        InvalidInputError: bad shapes, bounds, caps or planner name.
        PlannerError: ``is_valid`` raised.
    """
    _check_planner_name(planner)
    if planner in MULTI_QUERY_PLANNERS:
        raise InvalidInputError(f"plan_joint_path needs a single-query planner, not {planner}")
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
    step = _as_pos(resolution, "resolution")
    limit = _as_pos(time_limit, "time_limit")
    budget = _as_int(max_iterations, "max_iterations", 1)
    if seed is not None:
        _reseed_ompl(_derived_seed(int(seed), 0))

    space = ob.RealVectorStateSpace(n)
    bounds = ob.RealVectorBounds(n)
    for i in range(n):
        bounds.setLow(i, float(lo[i]))
        bounds.setHigh(i, float(hi[i]))
    space.setBounds(bounds)
    si = ob.SpaceInformation(space)
    sink = _ErrorSink()
    frame = _Frame(n, None)
    si.setStateValidityChecker(_make_validity(is_valid, frame, sink))
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
    count = [0]

    def spent() -> bool:
        count[0] += 1
        return count[0] > budget

    ptc = ob.plannerOrTerminationCondition(
        ob.timedPlannerTerminationCondition(limit), ob.PlannerTerminationCondition(spent)
    )
    sink.ptc = ptc
    status = solver.solve(ptc)
    sink.ptc = None
    if sink.error is not None:
        raise PlannerError(
            f"is_valid raised during plan_joint_path: {type(sink.error).__name__}: {sink.error}"
        ) from sink.error
    if _STATUS_NAMES.get(status.getStatus().value) != "exact":
        return None
    path = og.PathGeometric(pdef.getSolutionPath())
    simplifier = og.PathSimplifier(si)
    # one pass of vertex reduction and rope shortcutting: most of simplifyMax's
    # gain on these short paths, at a fraction of its collision checks
    simplifier.reduceVertices(path)
    simplifier.ropeShortcutPath(path)
    if sink.error is not None or not path.check():
        return None
    return np.array([frame.read(path.getState(k)) for k in range(path.getStateCount())])
