"""OMPL's parameter declarations of the registered planners: names, defaults, ranges.

OMPL planners declare their parameters in a ``ParamSet``
(``declareParam<T>(name, this, setter, getter, range)``), with a suggested
range ``"low:step:high"`` (``"0,1"`` for booleans) that OMPL's own tools
(Planner Arena, OMPL.app) show. The ompl 2.0.1 wheel does not bind
``Planner.params()``: names and defaults are read from the planner's
``printSettings()`` (:func:`~dexplan.planning.ompl.registry.declared_params`),
and the ranges, written nowhere a binding can read them, are
:data:`OMPL_RANGES`, transcribed from the ``declareParam`` calls of OMPL
2.0's planner sources (a planner that extends another, such as PRMstar or
InformedRRTstar, inherits its declarations).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from ompl import base as ob

from dexplan.planning.ompl.registry import (
    PLANNERS,
    check_planner_name,
    declared_params,
    settable_params,
)
from dexplan.planning.ompl.spaces import real_vector_space

__all__ = ["OMPL_RANGES", "ParamInfo", "planner_params"]

_RRT = {"range": "0.:1.:10000.", "goal_bias": "0.:.05:1.", "intermediate_states": "0,1"}
_RRTSTAR = {
    "range": "0.:1.:10000.",
    "goal_bias": "0.:.05:1.",
    "rewire_factor": "1.0:0.01:2.0",
    "use_k_nearest": "0,1",
    "delay_collision_checking": "0,1",
    "tree_pruning": "0,1",
    "prune_threshold": "0.:.01:1.",
    "pruned_measure": "0,1",
    "informed_sampling": "0,1",
    "sample_rejection": "0,1",
    "new_state_rejection": "0,1",
    "use_admissible_heuristic": "0,1",
    "ordered_sampling": "0,1",
    "ordering_batch_size": "1:100:1000000",
    "focus_search": "0,1",
    "number_sampling_attempts": "10:10:100000",
}
_KPIECE = {"range": "0.:1.:10000.", "goal_bias": "0.:.05:1.", "border_fraction": "0.:.05:1."}
_FMT = {"num_samples": "10:10:1000000", "radius_multiplier": "0.1:0.05:50."}
_FLAGS = ("use_k_nearest", "nearest_k", "cache_cc", "heuristics", "extended_fmt")

OMPL_RANGES: dict[str, dict[str, str]] = {
    "PRM": {"max_nearest_neighbors": "8:1000"},
    "PRMstar": {"max_nearest_neighbors": "8:1000"},
    "RRT": _RRT,
    "RRTConnect": {"range": "0.:1.:10000.", "intermediate_states": "0,1"},
    "RRTstar": _RRTSTAR,
    "InformedRRTstar": _RRTSTAR,
    "SORRTstar": _RRTSTAR,
    "KPIECE1": _KPIECE,
    "BKPIECE1": {"range": "0.:1.:10000.", "border_fraction": "0.:.05:1."},
    "LBKPIECE1": {"range": "0.:1.:10000.", "border_fraction": "0.:.05:1."},
    "FMT": {**_FMT, **dict.fromkeys(_FLAGS, "0,1")},
    "BFMT": {
        **_FMT,
        **dict.fromkeys((*_FLAGS, "balanced", "optimality"), "0,1"),
    },
    "BITstar": {
        "rewire_factor": "1.0:0.01:3.0",
        "samples_per_batch": "1:1:1000000",
        "prune_threshold_as_fractional_cost_change": "0.0:0.01:1.0",
        **dict.fromkeys(
            (
                "use_k_nearest",
                "use_graph_pruning",
                "delay_rewiring_to_first_solution",
                "use_just_in_time_sampling",
                "drop_unconnected_samples_on_prune",
                "stop_on_each_solution_improvement",
                "use_strict_queue_ordering",
                "find_approximate_solutions",
            ),
            "0,1",
        ),
    },
}
"""Planner -> parameter -> OMPL's suggested range (``low:step:high``, ``0,1``
for booleans); a parameter OMPL declares without one is absent."""


@dataclass(frozen=True)
class ParamInfo:
    """One declared parameter of a planner.

    Attributes:
        name: its OMPL ParamSet name (what ``--param NAME=VALUE`` takes).
        default: its value on a fresh planner, as OMPL prints it (``range = 0``
            means the planner picks one from the space at setup).
        range: OMPL's suggested range (``low:step:high``, ``0,1``), or ``""``
            when OMPL declares none.
        settable: whether the binding can set it (a bound ``setX`` method).
    """

    name: str
    default: str
    range: str
    settable: bool


def planner_params(name: str) -> tuple[ParamInfo, ...]:
    """The declared parameters of registered planner ``name``, sorted by name.

    The planner is built on a throwaway 2-D space to read its declarations.

    Raises:
        PlannerError: unknown planner (with a did-you-mean hint).
    """
    check_planner_name(name)
    planner = PLANNERS[name](ob.SpaceInformation(real_vector_space(-np.ones(2), np.ones(2))))
    declared = declared_params(planner)
    settable = set(settable_params(planner))
    ranges = OMPL_RANGES.get(name, {})
    return tuple(
        ParamInfo(key, declared[key], ranges.get(key, ""), key in settable)
        for key in sorted(declared)
    )
