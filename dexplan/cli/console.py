"""What the command line writes: exit codes, stderr lines, progress.

Progress and errors go to stderr, one ``dexplan: ...`` line each; results go
to stdout. Library code never prints: the command modules write through here.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from enum import IntEnum
from importlib import metadata
from typing import Protocol

from dexplan.cli import interrupt

__all__ = ["ExitCode", "Message", "dist_version", "err", "plan_progress", "quiet_progress"]


class ExitCode(IntEnum):
    """The exit codes of every ``dexplan`` command (listed in ``--help``)."""

    OK = 0
    FAILED = 1
    BAD_INPUT = 2
    INTERNAL = 3
    INTERRUPTED = 130


class Message(Protocol):
    """A progress event as the command line reads it (a planner ``ProgressEvent``)."""

    @property
    def message(self) -> str:
        """One line saying what happened."""
        ...


def err(msg: str) -> None:
    """Write ``dexplan: MSG`` on stderr, at once."""
    sys.stderr.write(f"dexplan: {msg}\n")
    sys.stderr.flush()


def dist_version(dist: str) -> str:
    """The installed version of the distribution ``dist``, or ``not installed``."""
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "not installed"


def plan_progress(quiet: bool) -> Callable[[Message], None]:
    """The planner's progress callback: a stderr line per event, and the interrupt check."""

    def say(event: Message) -> None:
        interrupt.check()
        if not quiet:
            err(event.message)

    return say


def quiet_progress(_event: object) -> None:
    """A progress callback that only checks for Ctrl-C."""
    interrupt.check()
