"""Array types and input checks shared by every module.

The checks turn wrong shapes and non-finite numbers into
:class:`~dexplan.core.errors.InvalidInputError` naming the argument and value,
instead of a NumPy broadcasting error deep inside a computation.
"""

from __future__ import annotations

import math
from typing import TypeAlias

import numpy as np
import numpy.typing as npt

from dexplan.core.errors import InvalidInputError, shorten

FloatArray: TypeAlias = npt.NDArray[np.float64]
IntArray: TypeAlias = npt.NDArray[np.int64]


def as_vector(value: object, name: str, size: int | None = None) -> FloatArray:
    """Return ``value`` as a finite float64 vector.

    Args:
        value: anything NumPy converts to a 1-D array.
        name: argument name used in the error message.
        size: required length, or None for any length.

    Raises:
        InvalidInputError: wrong shape or a NaN/inf entry.
    """
    arr = _float_array(value, name)
    if arr.ndim != 1 or (size is not None and arr.shape[0] != size):
        want = f"({size},)" if size is not None else "a 1-D array"
        raise InvalidInputError(f"{name} must have shape {want}, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise InvalidInputError(f"{name} must be finite, got {shorten(arr.tolist())}")
    return arr


def as_points(value: object, name: str, width: int = 3) -> FloatArray:
    """Return ``value`` as a finite float64 array of shape ``(N, width)``.

    A single row of shape ``(width,)`` is accepted and returned as ``(1, width)``.

    Raises:
        InvalidInputError: wrong shape or a NaN/inf entry.
    """
    arr = _float_array(value, name)
    if arr.ndim == 1 and arr.shape[0] == width:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != width:
        raise InvalidInputError(f"{name} must have shape (N, {width}), got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise InvalidInputError(f"{name} must be finite, got {shorten(arr.tolist())}")
    return arr


def as_positive(value: object, name: str, *, allow_zero: bool = False) -> float:
    """Return ``value`` as a finite float that is > 0 (or >= 0 with ``allow_zero``).

    Raises:
        InvalidInputError: not a number, not finite, or out of range.
    """
    try:
        x = float(value)  # type: ignore[arg-type]  # any object: float() raises on the wrong ones
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{name} must be a number, got {shorten(value)}") from exc
    if not math.isfinite(x) or x < 0.0 or (x == 0.0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise InvalidInputError(f"{name} must be finite and {bound}, got {x!r}")
    return x


def _float_array(value: object, name: str) -> FloatArray:
    """``value`` as a float64 array, or InvalidInputError naming ``name``."""
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{name} must be numeric, got {shorten(value)}") from exc
