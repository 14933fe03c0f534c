"""OMPL's process-wide state: console log level and the global seed generator.

Binding facts (ompl 2.0.1 PyPI wheel, nanobind):

- ``RNG.setSeed`` after random numbers were drawn logs an error but *does* reseed
  the global seed generator; every ``RNG`` created afterwards is seeded from it.
  See :class:`~dexplan.planning.ompl.problem.PlanningProblem` for what is
  deterministic.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from ompl import util as ou

from dexplan.core.errors import InvalidInputError
from dexplan.core.native_output import hide_leak_report_at_exit

__all__ = ["derived_seed", "get_log_level", "reseed_ompl", "set_log_level"]

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
    outcome is reported through :class:`~dexplan.planning.ompl.results.SolveResult`.
    Raise it to debug a problem.

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
# nanobind's exit report of binding objects still alive is noise to library
# users (dozens of lines after a script that held OMPL objects): dropped
hide_leak_report_at_exit()


def derived_seed(seed: int, stream: int) -> int:
    """Return a positive 31-bit seed derived from ``(seed, stream)``."""
    state = np.random.SeedSequence([seed, stream]).generate_state(1, dtype=np.uint32)[0]
    return int(state) % (2**31 - 2) + 1


def reseed_ompl(value: int) -> None:
    """Reseed OMPL's global seed generator without its "already started" log line."""
    previous = ou.getLogLevel()
    ou.setLogLevel(ou.LOG_NONE)
    try:
        ou.RNG.setSeed(value)
    finally:
        ou.setLogLevel(previous)
