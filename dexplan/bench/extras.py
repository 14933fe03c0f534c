"""The benchmark's optional dependencies: matplotlib (plots), Ray (clusters)."""

from __future__ import annotations

import importlib
from types import ModuleType

from dexplan.core.errors import DependencyError
from dexplan.core.ray_cluster import import_ray


def _import_extra(module: str, message: str) -> ModuleType:
    """Import an optional module, or raise :class:`DependencyError` with ``message``."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise DependencyError(message) from exc


def require_matplotlib() -> None:
    """Raise a clear error when matplotlib (the ``bench`` extra) is missing.

    Raises:
        DependencyError: matplotlib is not installed.
    """
    _import_extra(
        "matplotlib",
        "benchmark plots need matplotlib: pip install 'dexplan[bench]' (or pass --no-plots)",
    )


def require_ray() -> ModuleType:
    """The ``ray`` module.

    Raises:
        DependencyError: Ray is not installed.
    """
    return import_ray()
