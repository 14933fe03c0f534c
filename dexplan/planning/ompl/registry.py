"""The planner registry: OMPL geometric planners by name, and their parameters.

Binding facts (ompl 2.0.1 PyPI wheel, nanobind):

- ``Planner.params()`` (``ompl::base::ParamSet``) is not bound: parameters are
  read from ``printSettings()`` and set through the planner's bound ``setX``
  methods, with their OMPL ParamSet names (``range``, ``goal_bias``...).
- ``AORRTC`` hangs in ``solve`` on a constrained space (ignores the termination
  condition) and returns a zero-length "solution" on a plain R^2 problem: it is
  not registered.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

import numpy as np
from ompl import base as ob
from ompl import geometric as og

from dexplan.core.errors import PlannerError, did_you_mean
from dexplan.planning.ompl.spaces import real_vector_space

__all__ = [
    "CAPPED_PLANNERS",
    "FIRST_SOLUTION_PLANNERS",
    "MULTI_QUERY_PLANNERS",
    "PLANNERS",
    "PLANNER_NOTES",
    "PLANNER_TRAITS",
    "RESTARTED_PLANNERS",
    "UNSUPPORTED_PLANNERS",
    "PlannerFamily",
    "PlannerTraits",
    "available_planners",
    "check_planner",
    "check_planner_name",
    "declared_params",
    "planner_traits",
    "planners_with",
    "register_planner",
    "set_planner_param",
    "settable_params",
]


def _factory(name: str) -> Callable[[Any], Any]:
    """Return a factory ``make(si)`` of the ``ompl.geometric`` planner ``name``."""
    cls = getattr(og, name)

    def make(si: Any) -> Any:
        return cls(si)

    make.__name__ = f"make_{name}"
    make.__doc__ = f"Return a new ``ompl.geometric.{name}`` on ``si``."
    return make


class PlannerFamily(StrEnum):
    """How a planner explores: what ``dexplan planners`` groups them by."""

    ROADMAP = "roadmap"
    """A graph of sampled states kept across queries (PRM family)."""
    TREE = "tree"
    """Trees grown from the start (and goal) until they meet."""
    INFORMED = "informed"
    """Optimizing trees whose samples are drawn in the informed set of a solution."""
    BATCH = "batch"
    """A batch of samples drawn up front, searched as a graph (FMT family)."""


@dataclass(frozen=True)
class PlannerTraits:
    """What dexplan must know of one OMPL planner to run it well.

    Attributes:
        family: how it explores (:class:`PlannerFamily`).
        multi_query: its roadmap survives a new start and goal (``clearQuery``);
            it runs a solution-checking thread, so its goal is always one C++
            goal state.
        needs_projection: it uses a
            :class:`~dexplan.planning.ompl.spaces.ProjectionSpec`
            (``setProjectionEvaluator``).
        first_solution: optimizing, stopped at its first solution. Its problem
            gets a path-length objective whose cost threshold every path meets
            (:func:`first_solution_objective`): module 1 needs a GSn path, not a
            short one (the reduction follows the shortcut object trajectory
            whatever path led there), and once these planners have a solution
            their informed samplers (``PathLengthDirectInfSampler``) draw
            ambient states, project them and reject those outside the informed
            ellipsoid in a loop that never checks the termination condition
            (a solve could overrun its time limit by more than half).
        restarted: a batch planner that gets a fresh planner for every
            ``solve`` after the first. FMT and BFMT draw their batch of samples
            inside ``solve``; stopped before the batch is drawn (a module-1
            round's budget), the next ``solve`` of the same planner returns
            ``invalid_start`` at once, every round after. A fresh planner per
            round draws a fresh batch within that round's (doubled) budget.
        r_n_sampler: its informed sampler treats the space as R^n (no
            projection): on the contact chart it gets the chart without
            unit-sphere rows, where every point of the bounds is a state.
        capped: its chart keeps each finger's direction within a cap
            (:class:`~dexplan.planning.gsn.chart.DirectionCaps`). Its states
            come only from the space's uniform sampler (FMT and BFMT: a batch
            drawn up front) or an informed one over the same bounds, so the
            fraction of uniform chart states that are valid grasps decides how
            fast it searches: among obstacles as few as 1 in 2,000 uniform
            chart states are valid, and caps of 75 degrees about each finger's
            mean direction raise that about twentyfold while keeping most of
            the RLG sampler's valid states.
        waypoints: module 2 adds RLG waypoints when it has no link to try.
            BFMT's planner data holds only its two trees (no sample it left
            unconnected), often no other vertex at all: with the straight move
            blocked by an obstacle, module 2 has nothing to link. Given to the
            other planners, waypoints replaced the next round's growth with
            detours through random poses: more regrasps, and failures where
            there were none.
        unsupported: why the planner is deliberately not registered, or empty.
        note: caveats (informational).
    """

    family: PlannerFamily = PlannerFamily.TREE
    multi_query: bool = False
    needs_projection: bool = False
    first_solution: bool = False
    restarted: bool = False
    r_n_sampler: bool = False
    capped: bool = False
    waypoints: bool = False
    unsupported: str = ""
    note: str = ""


_INFORMED = (
    "optimizing, stopped at its first solution; informed sampling treats the "
    "constrained space as R^n (states are re-checked on the returned path)"
)

PLANNER_TRAITS: dict[str, PlannerTraits] = {
    "AORRTC": PlannerTraits(
        unsupported="hangs inside solve() on a constrained state space, ignoring the "
        "termination condition, and returns a zero-length path on a plain R^2 problem "
        "(ompl 2.0.1 wheel)"
    ),
    "BFMT": PlannerTraits(
        family=PlannerFamily.BATCH,
        restarted=True,
        capped=True,
        waypoints=True,
        note="batch of num_samples states; timed out on the tangent-bundle space",
    ),
    "BITstar": PlannerTraits(
        family=PlannerFamily.INFORMED,
        first_solution=True,
        r_n_sampler=True,
        capped=True,
        note=_INFORMED,
    ),
    "BKPIECE1": PlannerTraits(needs_projection=True),
    "FMT": PlannerTraits(
        family=PlannerFamily.BATCH,
        restarted=True,
        capped=True,
        note="batch of num_samples states drawn uniformly up front; timed out on the "
        "tangent-bundle space",
    ),
    "InformedRRTstar": PlannerTraits(
        family=PlannerFamily.INFORMED,
        first_solution=True,
        r_n_sampler=True,
        capped=True,
        note=_INFORMED,
    ),
    "KPIECE1": PlannerTraits(needs_projection=True),
    "LBKPIECE1": PlannerTraits(
        needs_projection=True,
        note="lazy: OMPL's ConstrainedMotionValidator does not check a motion's end "
        "state, so it can return invalid waypoints; the re-check reports them as "
        "path_invalid",
    ),
    "PRM": PlannerTraits(
        family=PlannerFamily.ROADMAP,
        multi_query=True,
        note="multi-query roadmap; uses the custom valid state sampler",
    ),
    "PRMstar": PlannerTraits(
        family=PlannerFamily.ROADMAP,
        multi_query=True,
        note="optimizing: uses the whole time limit; multi-query roadmap",
    ),
    "RRT": PlannerTraits(),
    "RRTConnect": PlannerTraits(),
    "RRTstar": PlannerTraits(first_solution=True, note="optimizing, stopped at its first solution"),
    "SORRTstar": PlannerTraits(
        family=PlannerFamily.INFORMED,
        first_solution=True,
        r_n_sampler=True,
        capped=True,
        note=_INFORMED,
    ),
}
"""The planners of the wheel dexplan knows, with their traits.

Every registered one solved the unit-sphere test problem on the projected,
atlas and tangent-bundle spaces (FMT/BFMT only timed out on the tangent
bundle, cleanly)."""

_NO_TRAITS = PlannerTraits()


def planner_traits(name: str) -> PlannerTraits:
    """The :class:`PlannerTraits` of planner ``name`` (none set for an unknown name)."""
    return PLANNER_TRAITS.get(name, _NO_TRAITS)


def planners_with(trait: str) -> frozenset[str]:
    """The registered planners whose boolean ``trait`` (a :class:`PlannerTraits` field) is set."""
    return frozenset(n for n in PLANNERS if getattr(planner_traits(n), trait))


PLANNERS: dict[str, Callable[[Any], Any]] = {
    name: _factory(name)
    for name, traits in PLANNER_TRAITS.items()
    if not traits.unsupported and hasattr(og, name)
}
"""Planner name -> factory ``f(space_information) -> ompl planner``."""

UNSUPPORTED_PLANNERS: dict[str, str] = {
    name: t.unsupported for name, t in PLANNER_TRAITS.items() if t.unsupported
}
"""Geometric planners of the wheel that are deliberately not registered, with the reason."""

PLANNER_NOTES: dict[str, str] = {name: t.note for name, t in PLANNER_TRAITS.items() if t.note}
"""Caveats per registered planner (informational)."""

FIRST_SOLUTION_PLANNERS = planners_with("first_solution")
"""Planners with :attr:`PlannerTraits.first_solution`."""

RESTARTED_PLANNERS = planners_with("restarted")
"""Planners with :attr:`PlannerTraits.restarted`."""

MULTI_QUERY_PLANNERS = planners_with("multi_query")
"""Planners with :attr:`PlannerTraits.multi_query` (the PRM family)."""

CAPPED_PLANNERS = planners_with("capped")
"""Planners with :attr:`PlannerTraits.capped`."""


def first_solution_objective(si: Any) -> Any:
    """A path-length objective that every path satisfies (cost threshold +inf).

    OMPL's optimizing planners stop as soon as their best cost satisfies the
    objective; see :attr:`PlannerTraits.first_solution`.
    """
    objective = ob.PathLengthOptimizationObjective(si)
    objective.setCostThreshold(ob.Cost(math.inf))
    return objective


def available_planners() -> list[str]:
    """Return the sorted names of the registered planners (keys of :data:`PLANNERS`)."""
    return sorted(PLANNERS)


def check_planner_name(name: str) -> None:
    """Raise unless ``name`` is a registered planner.

    Raises:
        PlannerError: unsupported (the message says why) or unknown planner; the
            message lists the valid ones, with a case-insensitive "did you
            mean" hint (``rrtconnect``: ``RRTConnect``).

    """
    if name in PLANNERS:
        return
    valid = ", ".join(available_planners())
    if name in UNSUPPORTED_PLANNERS:
        raise PlannerError(
            f"planner {name!r} is not supported: {UNSUPPORTED_PLANNERS[name]}; "
            f"valid planners: {valid}"
        )
    hint = did_you_mean(str(name), PLANNERS)
    raise PlannerError(f"unknown planner {name!r}{hint} (valid planners: {valid})")


def register_planner(
    name: str,
    factory: Callable[[Any], Any],
    params: Mapping[str, object] | None = None,
    *,
    traits: PlannerTraits | None = None,
    replace: bool = False,
) -> None:
    """Make a planner available by name wherever dexplan takes one.

    Once registered, ``name`` works in :func:`dexplan.plan`, a scenario's
    ``[planner] name``, :class:`~dexplan.planning.ompl.problem.PlanningProblem`
    and the benchmarks of this process (not in ``bench --jobs`` worker
    processes, nor on the command line: they start without it).

    Args:
        name: the planner's name (a Python identifier).
        factory: ``factory(si) -> ob.Planner`` on an ``ob.SpaceInformation``;
            an OMPL planner (``og.RRT``) or a Python subclass of ``ob.Planner``.
        params: parameters by OMPL ParamSet name set on every planner the
            factory makes (checked now, like ``--param``). A Python planner
            declares none: give it its settings in the factory instead.
        traits: what dexplan must know to run it (:class:`PlannerTraits`);
            default: a single-query tree planner without special needs.
        replace: allow replacing a planner registered under ``name``.

    Raises:
        PlannerError: a bad name, a name taken, a factory that raises or does
            not return an ``ob.Planner``, or a bad parameter.
    """
    if not isinstance(name, str) or not name.isidentifier():
        raise PlannerError(f"planner name must be a Python identifier, got {name!r}")
    if name in UNSUPPORTED_PLANNERS or (name in PLANNERS and not replace):
        raise PlannerError(
            f"planner {name!r} is already registered (pass replace=True to replace it)"
        )
    if not callable(factory):
        raise PlannerError(f"factory of planner {name!r} must be callable, got {factory!r}")
    traits = traits if traits is not None else PlannerTraits(note="registered by the user")
    if not isinstance(traits, PlannerTraits) or traits.unsupported:
        raise PlannerError(f"traits of planner {name!r} must be PlannerTraits without unsupported")
    defaults = dict(params or {})

    def make(si: Any) -> Any:
        planner = factory(si)
        if not isinstance(planner, ob.Planner):
            raise PlannerError(
                f"factory of planner {name!r} returned {type(planner).__name__}, "
                "not an ompl.base.Planner"
            )
        for key, value in defaults.items():
            set_planner_param(planner, name, str(key), value)
        return planner

    make.__name__ = f"make_{name}"
    space = real_vector_space(-np.ones(2), np.ones(2))
    try:
        sample = make(ob.SpaceInformation(space))  # fails now, not in the middle of a query
    except PlannerError:
        raise
    except Exception as exc:  # a user's factory: any failure is reported as bad input
        raise PlannerError(
            f"factory of planner {name!r} raised {type(exc).__name__}: {exc}"
        ) from exc
    _check_traits(name, sample, traits)
    PLANNERS[name] = make
    PLANNER_TRAITS[name] = traits
    if traits.note:
        PLANNER_NOTES[name] = traits.note


# What module 1 calls on a planner whose traits say so (multi_query: PlanningProblem's
# grow_roadmap and planner_data; needs_projection: the KPIECE grid).
_TRAIT_METHODS = {
    "multi_query": ("growRoadmapPtc", "milestoneCount", "clearQuery"),
    "needs_projection": ("setProjectionEvaluator",),
}


def _check_traits(name: str, planner: Any, traits: PlannerTraits) -> None:
    """Raise unless ``planner`` has the methods its ``traits`` make module 1 call."""
    for trait, methods in _TRAIT_METHODS.items():
        missing = [m for m in methods if not callable(getattr(planner, m, None))]
        if getattr(traits, trait) and missing:
            raise PlannerError(
                f"planner {name!r} has traits {trait}=True but no {', '.join(missing)}"
            )


# ------------------------------------------------------------------- parameters

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


def declared_params(planner: Any) -> dict[str, str]:
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


def settable_params(planner: Any) -> list[str]:
    """Return the sorted declared parameters of ``planner`` the binding can set."""
    return sorted(n for n in declared_params(planner) if _accessors(planner, n) is not None)


def _coerce_param(
    planner_name: str, name: str, value: object, current: object
) -> bool | int | float:
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
        # any object: float() raises on the wrong ones, reported below
        real = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise PlannerError(f"{where} must be a number, got {value!r}") from exc
    if not math.isfinite(real) or real < 0.0:
        raise PlannerError(f"{where} must be finite and >= 0, got {value!r}")
    if ("bias" in name or "fraction" in name) and real > 1.0:
        raise PlannerError(f"{where} must be in [0, 1], got {value!r}")
    return real


def set_planner_param(planner: Any, planner_name: str, name: str, value: object) -> None:
    """Set a parameter of ``planner`` by its OMPL ParamSet name, checked.

    The value is converted to the parameter's type (see :func:`_coerce_param`) and
    must read back unchanged.

    Args:
        planner: an OMPL planner.
        planner_name: its registry name (for messages).
        name: the ParamSet name (``range``, ``goal_bias``...).
        value: the new value (bool, int, float or text).

    Raises:
        PlannerError: unknown name, a name without a bound setter, or a value that
            is malformed, rejected or ignored by OMPL.

    """
    declared = declared_params(planner)
    if name not in declared:
        hint = did_you_mean(name, declared)
        raise PlannerError(
            f"unknown parameter {name!r} for planner {planner_name}{hint} (valid parameters: "
            f"{', '.join(settable_params(planner)) or 'none'})"
        )
    access = _accessors(planner, name)
    if access is None:
        raise PlannerError(
            f"parameter {name!r} of planner {planner_name} is declared by OMPL but has no "
            f"setter in the ompl Python binding; settable parameters: "
            f"{', '.join(settable_params(planner)) or '(none)'}"
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
    same checks as :class:`~dexplan.planning.ompl.problem.PlanningProblem` apply.

    Raises:
        PlannerError: unknown or unsupported planner, unknown parameter, bad value.
    """
    check_planner_name(name)
    space = real_vector_space(-np.ones(2), np.ones(2))
    planner = PLANNERS[name](ob.SpaceInformation(space))
    for key, value in (params or {}).items():
        set_planner_param(planner, name, str(key), value)
