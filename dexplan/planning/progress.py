"""Typed results vocabulary of a query: its status and its progress events.

The planner reports progress as :class:`ProgressEvent` values (a stage, a
human-readable message, the elapsed time and the counts the stage knows);
the CLI renders the message, bench records the stage. Nobody parses text.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from enum import IntEnum, StrEnum


class PlanStatus(StrEnum):
    """How a query ended. A ``str``: it compares equal to its value and is JSON text."""

    SOLVED = "solved"
    """A plan was found and passed the verifier."""
    NO_START_GRASP = "no_start_grasp"
    """No valid grasp at the start pose (``start.q`` absent), within the time limit."""
    NO_GOAL_GRASP = "no_goal_grasp"
    """The goal region was sampled but no valid grasp exists there (none found)."""
    NO_GSN_PATH = "no_gsn_path"
    """Start and goal were not connected in GSn (module 1 + module 2) in time."""
    REDUCTION_FAILED = "reduction_failed"
    """A GSn path was found but not reduced to transfers and regrasps."""
    INVALID_PLAN = "invalid_plan"
    """The reduced plan failed the final verification (kept for inspection)."""


class Stage(IntEnum):
    """Stages of a query, in order (the numbers are bench's ``progress`` stages)."""

    STARTING = 0
    START_GRASP = 1
    MODULE1 = 2
    MODULE2 = 3
    REDUCTION = 4
    VERIFICATION = 5
    DONE = 6


@dataclass(frozen=True)
class ProgressEvent:
    """One progress report of a query.

    Attributes:
        stage: the stage it belongs to.
        message: a short human-readable line (what the CLI prints).
        elapsed_s: seconds since the query started.
        counts: figures the stage knows at this point (e.g. ``nodes``,
            ``components``, ``rounds``, ``attempt``).
    """

    stage: Stage
    message: str
    elapsed_s: float
    counts: Mapping[str, int] = field(default_factory=dict)


Progress = Callable[[ProgressEvent], None]
"""A progress callback."""
