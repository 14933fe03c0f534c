"""Exception hierarchy of dexplan.

Every error dexplan raises on purpose derives from :class:`DexplanError`, so a
caller (and the CLI) can catch them all in one place. Messages name the
offending field and value.
"""

from __future__ import annotations


class DexplanError(Exception):
    """Root of every error raised by dexplan."""


class InvalidInputError(DexplanError, ValueError):
    """An argument has the wrong shape, a non-finite value or is out of range."""


class ModelError(DexplanError):
    """A robot model cannot be loaded or is inconsistent (bad URDF, unknown frame)."""


class MeshError(DexplanError):
    """A mesh file is missing, unreadable, degenerate or not watertight."""


class ScenarioError(DexplanError):
    """A scenario file is malformed; the message names the field and value."""


class PlannerError(DexplanError):
    """An unknown planner or planner parameter, or an unusable planner setup."""


class PlanFileError(DexplanError):
    """A plan file cannot be read or does not follow the ``dexplan-plan/1`` format."""


class DependencyError(DexplanError):
    """An optional dependency (e.g. ``rerun-sdk`` for ``viz``) is not installed."""
