"""Argument checks shared by the OMPL adapter's modules (no OMPL here)."""

from __future__ import annotations

import math

import numpy as np

from dexplan.core.errors import InvalidInputError

__all__ = ["as_int", "as_pos"]


def as_int(value: object, name: str, minimum: int) -> int:
    """Return ``value`` as an ``int`` >= ``minimum``.

    Args:
        value: a Python or NumPy integer (not a bool).
        name: argument name for the error message.
        minimum: smallest accepted value.

    Raises:
        InvalidInputError: not an integer, a bool, or below ``minimum``.

    """
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise InvalidInputError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def as_pos(value: object, name: str) -> float:
    """Return ``value`` as a finite ``float`` > 0.

    Args:
        value: anything ``float()`` accepts.
        name: argument name for the error message.

    Raises:
        InvalidInputError: not a number, not finite, or <= 0.

    """
    try:
        # any object: float() raises on the wrong ones, reported below
        real = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{name} must be a number, got {value!r}") from exc
    if not math.isfinite(real) or real <= 0.0:
        raise InvalidInputError(f"{name} must be finite and > 0, got {value!r}")
    return real
