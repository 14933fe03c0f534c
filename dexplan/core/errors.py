"""Exception hierarchy of dexplan.

Every error dexplan raises on purpose derives from :class:`DexplanError`, so a
caller (and the CLI) can catch them all in one place. Messages name the
offending field and value.
"""

from __future__ import annotations

import difflib
import reprlib
from collections.abc import Iterable


class DexplanError(Exception):
    """Root of every error raised by dexplan."""


class InvalidInputError(DexplanError, ValueError):
    """An argument has the wrong shape, a non-finite value or is out of range."""


class ModelError(DexplanError):
    """A robot model cannot be loaded or is inconsistent (bad URDF, unknown frame)."""


class MeshError(DexplanError):
    """A mesh file is missing, unreadable, degenerate or not watertight."""


class GeodesicError(MeshError):
    """Geodesics cannot be computed on a mesh (non-manifold vertex, disconnected parts)."""


class ScenarioError(DexplanError):
    """A scenario file is malformed; the message names the field and value."""


class PlannerError(DexplanError):
    """An unknown planner or planner parameter, or an unusable planner setup."""


class PlanFileError(DexplanError):
    """A plan file cannot be read or does not follow the ``dexplan-plan/2`` format."""


class RoadmapFileError(PlanFileError):
    """A roadmap file cannot be read or does not follow the ``dexplan-roadmap/1`` format."""


class DependencyError(DexplanError):
    """An optional dependency (e.g. ``rerun-sdk`` for ``viz``) is not installed."""


# ---------------------------------------------------------------- messages
#: Longest echo of an offending value in an error message (characters).
MAX_ECHO = 80


def shorten(value: object, limit: int = MAX_ECHO) -> str:
    """``repr(value)`` cut to ``limit`` characters, cheap even for huge values.

    Error messages echo the offending value; a 5M-entry list must not become a
    25 MB line, nor take seconds to format (``reprlib`` bounds the work).
    """
    text = _REPR.repr(value) if isinstance(value, list | tuple | dict | set) else repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def one_line(text: object, limit: int = 300) -> str:
    """``text`` on one line (whitespace runs collapsed), at most ``limit`` characters.

    For texts dexplan does not write itself (a library's error, a planner
    message) that end up in a one-line message.
    """
    flat = " ".join(str(text).split())
    return flat if len(flat) <= limit else flat[: limit - 3] + "..."


def unknown_field(prefix: str, key: str, value: object, allowed: Iterable[str]) -> str:
    """Message for an unknown field, with a "did you mean" hint when one is close.

    Args:
        prefix: path of the table holding it (``object``, ``obstacles[1]``).
        key: the unknown field.
        value: its value.
        allowed: the known fields.
    """
    allowed = sorted(allowed)
    where = f"{prefix}.{key}" if prefix else str(key)
    msg = f"unknown field {where} (= {shorten(value, 40)})"
    close = difflib.get_close_matches(str(key), allowed, n=1, cutoff=0.6)
    if close:
        msg += f"; did you mean {close[0]!r}?"
    return msg + f" (allowed: {', '.join(allowed)})"


def did_you_mean(word: str, choices: Iterable[str]) -> str:
    """A ``"; did you mean 'X'?"`` hint for a misspelt name, or ``""``.

    Case never matters (``rrtconnect`` finds ``RRTConnect``): an exact match
    ignoring case wins, then the closest name by :mod:`difflib`.
    """
    names = sorted(choices)
    folded = {n.lower(): n for n in names}
    close = folded.get(str(word).lower())
    if close is None:
        near = difflib.get_close_matches(str(word).lower(), list(folded), n=1, cutoff=0.6)
        close = folded[near[0]] if near else None
    return f"; did you mean {close!r}?" if close is not None else ""


_REPR = reprlib.Repr()
_REPR.maxlist = _REPR.maxtuple = _REPR.maxdict = _REPR.maxset = 8
_REPR.maxlevel = 3
_REPR.maxstring = _REPR.maxother = MAX_ECHO
