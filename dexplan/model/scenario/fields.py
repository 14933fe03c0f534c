"""Field checks shared by the scenario and goals parsers.

Each reads one field of a TOML table and raises a one-line
:class:`~dexplan.core.errors.ScenarioError` naming the field (``prefix.key``)
and its shortened value when it is missing, malformed or out of range.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from dexplan.core.errors import InvalidInputError, ScenarioError, one_line, shorten
from dexplan.core.typing import FloatArray
from dexplan.model.objects.factory import check_fields
from dexplan.model.scenario.spec import MAX_NAME, MAX_PATH, MAX_POSITION

__all__ = [
    "as_float",
    "check_only",
    "check_text_file",
    "existing_file",
    "fail",
    "field_name",
    "integer",
    "number",
    "pose",
    "string",
    "table",
    "vector",
]


def fail(msg: str) -> NoReturn:
    """Raise :class:`~dexplan.core.errors.ScenarioError` with ``msg``."""
    raise ScenarioError(msg)


def check_only(table: Mapping[str, Any], prefix: str, allowed: set[str] | frozenset[str]) -> None:
    """Reject a field of ``table`` not in ``allowed``, with a "did you mean" hint."""
    try:
        check_fields(table, prefix, allowed)
    except InvalidInputError as exc:
        raise ScenarioError(str(exc)) from exc


def field_name(prefix: str, key: str) -> str:
    """The dotted name ``prefix.key`` of a field (``key`` at the top level)."""
    return f"{prefix}.{key}" if prefix else key


def table(doc: Mapping[str, Any], key: str, required: bool = True) -> Mapping[str, Any]:
    """The table ``[key]`` of ``doc`` (empty when absent and not ``required``)."""
    if key not in doc:
        if required:
            fail(f"missing table [{key}]")
        return {}
    val = doc[key]
    if not isinstance(val, Mapping):
        fail(f"{key} must be a table, got {shorten(val)}")
    return val


def as_float(val: object) -> float | None:
    """A TOML number as a float (huge ints become +-inf); None for anything else."""
    if isinstance(val, bool) or not isinstance(val, int | float):
        return None
    try:
        return float(val)
    except OverflowError:
        return math.inf if val > 0 else -math.inf


def number(
    table: Mapping[str, Any],
    key: str,
    prefix: str,
    default: float | None = None,
    *,
    lo: float,
    hi: float,
    lo_open: bool = False,
) -> float:
    """A finite number in ``[lo, hi]`` (``(lo, hi]`` with ``lo_open``)."""
    name = field_name(prefix, key)
    if key not in table:
        if default is None:
            fail(f"missing field {name}")
        return float(default)
    val = table[key]
    x = as_float(val)
    if x is None or not math.isfinite(x):
        fail(f"{name} must be a finite number, got {shorten(val)}")
    if x < lo or (lo_open and x == lo) or x > hi:
        fail(f"{name} must be in {'(' if lo_open else '['}{lo:g}, {hi:g}], got {shorten(val)}")
    return x


def integer(
    table: Mapping[str, Any], key: str, prefix: str, default: int, *, lo: int, hi: int
) -> int:
    """An integer in ``[lo, hi]``."""
    name = field_name(prefix, key)
    val = table.get(key, default)
    if isinstance(val, bool) or not isinstance(val, int):
        fail(f"{name} must be an integer in [{lo}, {hi}], got {shorten(val)}")
    if not lo <= val <= hi:
        fail(f"{name} must be an integer in [{lo}, {hi}], got {shorten(val)}")
    return val


def string(table: Mapping[str, Any], key: str, prefix: str, default: str | None = None) -> str:
    """A non-empty string of at most :data:`MAX_NAME` printable characters."""
    name = field_name(prefix, key)
    if key not in table:
        if default is None:
            fail(f"missing field {name}")
        return default
    val = table[key]
    if not isinstance(val, str) or not val or len(val) > MAX_NAME or not val.isprintable():
        fail(
            f"{name} must be a non-empty string of at most {MAX_NAME} printable characters, "
            f"got {shorten(val)}"
        )
    return val


def vector(
    table: Mapping[str, Any],
    key: str,
    prefix: str,
    size: int | None,
    *,
    max_len: int | None = None,
    max_abs: float | None = None,
) -> FloatArray:
    """A list of ``size`` (or 1 to ``max_len``) finite numbers, each ``|x| <= max_abs``."""
    name = field_name(prefix, key)
    if key not in table:
        fail(f"missing field {name}")
    val = table[key]
    want = f"a list of {size} numbers" if size else f"a list of 1 to {max_len} numbers"
    if not isinstance(val, list):
        fail(f"{name} must be {want}, got {shorten(val)}")
    if (size is not None and len(val) != size) or (
        max_len is not None and not 1 <= len(val) <= max_len
    ):
        fail(f"{name} must be {want}, got {len(val)} entries: {shorten(val)}")
    xs = [as_float(v) for v in val]
    if any(x is None for x in xs):
        fail(f"{name} must be {want}, got {shorten(val)}")
    arr = np.array(xs, dtype=float)
    if not np.isfinite(arr).all():
        fail(f"{name} must be finite, got {shorten(val)}")
    if max_abs is not None and np.any(np.abs(arr) > max_abs):
        fail(f"{name} entries must be within +-{max_abs:g}, got {shorten(val)}")
    return arr


def pose(table: Mapping[str, Any], key: str, prefix: str) -> FloatArray:
    """``[x, y, z, qx, qy, qz, qw]``: position within :data:`MAX_POSITION`, unit quaternion."""
    name = field_name(prefix, key)
    pose = vector(table, key, prefix, 7)
    if np.any(np.abs(pose[:3]) > MAX_POSITION):
        fail(
            f"{name} position must be within +-{MAX_POSITION:g} m per axis, "
            f"got {shorten(table[key][:3])}"
        )
    with np.errstate(over="ignore"):  # a norm of inf is rejected below
        norm = float(np.linalg.norm(pose[3:]))
    if not math.isfinite(norm) or abs(norm - 1.0) > 1e-3:
        fail(f"{name} quaternion (XYZW) must have unit norm, got norm {norm:.6g}")
    pose[3:] /= norm
    return pose


def existing_file(table: Mapping[str, Any], key: str, prefix: str, base_dir: Path) -> Path:
    """An existing regular file named by a string field, resolved against ``base_dir``."""
    name = field_name(prefix, key)
    raw = table[key]
    if not isinstance(raw, str) or not raw or "\0" in raw or len(raw) > MAX_PATH:
        fail(
            f"{name} must be a file name (a non-empty string of at most {MAX_PATH} "
            f"characters, no NUL), got {shorten(raw)}"
        )
    try:
        path = (base_dir / raw).resolve()
        ok = path.is_file()
    except (OSError, ValueError, RuntimeError) as exc:  # name too long, symlink loop
        fail(f"{name}: cannot use {shorten(raw)}: {one_line(str(exc), 120)}")
    if not ok:
        fail(f"{name} file not found: {shorten(str(path))}")
    return path


def check_text_file(path: Path, name: str, max_bytes: int) -> None:
    """Check that ``path`` is a readable UTF-8 text file of at most ``max_bytes`` bytes."""
    try:
        size = path.stat().st_size
        if size > max_bytes:
            fail(f"{name} file is {size} bytes, more than {max_bytes}: {shorten(str(path))}")
        data = path.read_bytes()
    except OSError as exc:
        fail(f"{name}: cannot read {shorten(str(path))}: {one_line(exc.strerror or str(exc))}")
    try:
        data.decode("utf-8")
    except UnicodeDecodeError as exc:
        fail(f"{name} is not UTF-8 text ({shorten(str(path))}): byte {exc.start} is invalid")
    if b"\0" in data:
        fail(f"{name} is not a text file (it contains NUL bytes): {shorten(str(path))}")
