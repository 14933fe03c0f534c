"""Scenario files: the hand, object, obstacles, start, goal and planner; goal lists.

Modules: :mod:`.spec` (the dataclasses, the fields each table accepts, the
limits), :mod:`.fields` (the field checks), :mod:`.scenario` (the scenario
file parser), :mod:`.identity` (what a scenario plans, and its hash),
:mod:`.goals` (goal lists for multi-query runs), :mod:`.catalog` (the builtin
scenarios, and a scenario argument resolved: a path or a builtin name).
"""

from dexplan.model.scenario.catalog import (
    BuiltinScenario,
    builtin_scenario_folder,
    builtin_scenarios,
    resolve_scenario_path,
)
from dexplan.model.scenario.identity import COSMETIC_FIELDS, scenario_description, scenario_hash
from dexplan.model.scenario.scenario import (
    builtin_scenario_path,
    checked_scenario,
    default_scenario,
    load_scenario,
    parse_scenario,
)
from dexplan.model.scenario.spec import (
    DEFAULT_SCENARIO,
    MAX_HALF_EXTENT,
    MAX_JOINTS,
    MAX_POSITION,
    MAX_SCENARIO_BYTES,
    MAX_TIME_LIMIT,
    OBSTACLE_OWN_FIELDS,
    SCENARIO_FIELDS,
    SEED_LIMIT,
    SPACES,
    GoalSpec,
    HandSpec,
    PlannerSpec,
    Scenario,
    StartSpec,
)

__all__ = [
    "COSMETIC_FIELDS",
    "DEFAULT_SCENARIO",
    "MAX_HALF_EXTENT",
    "MAX_JOINTS",
    "MAX_POSITION",
    "MAX_SCENARIO_BYTES",
    "MAX_TIME_LIMIT",
    "OBSTACLE_OWN_FIELDS",
    "SCENARIO_FIELDS",
    "SEED_LIMIT",
    "SPACES",
    "BuiltinScenario",
    "GoalSpec",
    "HandSpec",
    "PlannerSpec",
    "Scenario",
    "StartSpec",
    "builtin_scenario_folder",
    "builtin_scenario_path",
    "builtin_scenarios",
    "checked_scenario",
    "default_scenario",
    "load_scenario",
    "parse_scenario",
    "resolve_scenario_path",
    "scenario_description",
    "scenario_hash",
]
