"""Shapes from scenario tables and plan-file dictionaries.

The schema (shared by ``[object]`` / ``[[obstacles]]`` in scenarios and
``"object"`` / ``"obstacles"`` in plan files)::

    {"shape": "sphere", "radius": r}
    {"shape": "box", "size": [sx, sy, sz]}
    {"shape": "capsule" | "cylinder", "radius": r, "length": l}
    {"shape": "mesh", "path": "meshes/x.obj", "scale": 1.0, "sha256": "..."}

Lengths are in metres. ``scale`` (default 1.0) and ``sha256`` are optional; a
given ``sha256`` must match the file's bytes. Keys outside the schema of the
shape kind are rejected with a "did you mean" hint (:data:`SHAPE_FIELDS`);
callers strip their own keys (an obstacle's ``name`` and ``pose_xyzquat``)
before calling :func:`shape_from_dict`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any, cast

from dexplan.core import files
from dexplan.core.errors import InvalidInputError, MeshError, shorten, unknown_field
from dexplan.model.objects.mesh import Mesh
from dexplan.model.objects.primitives import Box, Capsule, Cylinder, Sphere
from dexplan.model.objects.shape import Shape, ShapeKind

#: Shape names accepted in the ``shape`` field.
SHAPE_KINDS: tuple[ShapeKind, ...] = tuple(ShapeKind)

#: Longest mesh ``path`` (characters).
MAX_PATH_CHARS = 4096

#: The fields each shape kind accepts (``sha256`` is optional, written by plan files).
SHAPE_FIELDS: Mapping[str, frozenset[str]] = {
    "sphere": frozenset({"shape", "radius"}),
    "box": frozenset({"shape", "size"}),
    "capsule": frozenset({"shape", "radius", "length"}),
    "cylinder": frozenset({"shape", "radius", "length"}),
    "mesh": frozenset({"shape", "path", "scale", "sha256"}),
}

#: Every field of some shape kind (checked when the kind itself is missing or unknown).
ALL_SHAPE_FIELDS: frozenset[str] = frozenset().union(*SHAPE_FIELDS.values())


def field_key(key: object) -> str:
    """A table key as it may appear in a one-line message: itself, or a short repr."""
    text = str(key)
    return text if text.isprintable() and 0 < len(text) <= 40 else shorten(text, 40)


def check_fields(d: Mapping[str, Any], field: str, allowed: frozenset[str] | set[str]) -> None:
    """Reject the first key of ``d`` outside ``allowed`` (file order), with a hint.

    Raises:
        InvalidInputError: e.g. ``unknown field object.radiuss (= 0.05); did you
            mean 'radius'? (allowed: radius, shape)``.
    """
    for key, value in d.items():
        if key not in allowed:
            raise InvalidInputError(unknown_field(field, field_key(key), value, allowed))


def _as_float(value: object) -> float | None:
    """``value`` as a float (ints beyond the float range become inf); None if not a number."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    try:
        return float(value)
    except OverflowError:  # a huge int
        return math.inf if value > 0 else -math.inf


def _positive(d: Mapping[str, Any], key: str, field: str, default: float | None = None) -> float:
    """``d[key]`` as a finite float > 0; errors name ``field.key`` and the value."""
    name = f"{field}.{key}"
    if key not in d:
        if default is not None:
            return default
        raise InvalidInputError(f"{name} is missing")
    value = d[key]
    x = _as_float(value)
    if x is None:
        raise InvalidInputError(f"{name} must be a number, got {shorten(value)}")
    if not math.isfinite(x) or x <= 0.0:
        raise InvalidInputError(f"{name} must be finite and > 0, got {shorten(value)}")
    return x


def _size(d: Mapping[str, Any], field: str) -> list[float]:
    name = f"{field}.size"
    if "size" not in d:
        raise InvalidInputError(f"{name} is missing")
    value = d["size"]
    three = isinstance(value, list | tuple) and len(value) == 3
    xs = [_as_float(x) for x in value] if three else []
    if len(xs) != 3 or not all(x is not None and math.isfinite(x) and x > 0.0 for x in xs):
        raise InvalidInputError(
            f"{name} must be 3 finite numbers > 0 (full edge lengths), got {shorten(value)}"
        )
    # the checks above let only finite real numbers through
    return [float(x) for x in xs]  # type: ignore[arg-type]


def _mesh(d: Mapping[str, Any], base_dir: Path | None, field: str) -> Mesh:
    raw = d.get("path")
    if not isinstance(raw, str) or not raw or "\0" in raw or len(raw) > MAX_PATH_CHARS:
        what = (
            "is missing"
            if raw is None
            else f"must be a non-empty string (a file name of at most {MAX_PATH_CHARS} "
            f"characters, no NUL), got {shorten(raw)}"
        )
        raise InvalidInputError(f"{field}.path {what}")
    path = Path(raw)
    if not path.is_absolute() and base_dir is not None:
        path = Path(base_dir) / path
    scale = _positive(d, "scale", field, default=1.0)
    expected = d.get("sha256")
    if expected is not None and (not isinstance(expected, str) or len(expected) > 128):
        raise InvalidInputError(f"{field}.sha256 must be a hex string, got {shorten(expected)}")
    try:
        mesh = Mesh.from_file(path, scale=scale)
    except MeshError as exc:
        raise MeshError(f"{field}.path: {exc}") from exc
    if expected is not None and mesh.sha256 != expected.strip().lower():
        raise MeshError(
            f"{field}.sha256 mismatch for {str(path)!r}: the file has {mesh.sha256}, "
            f"expected {expected}"
        )
    return mesh


def shape_from_dict(
    d: Mapping[str, Any], base_dir: Path | None = None, *, field: str = "object"
) -> Shape:
    """Build a shape from its scenario/plan-file description.

    Args:
        d: e.g. ``{"shape": "box", "size": [0.05, 0.05, 0.1]}`` (see module doc).
        base_dir: directory relative mesh paths are resolved against (the
            scenario or plan file's directory); None means the working directory.
        field: name of ``d`` in error messages, e.g. ``"obstacles[2]"``.

    Returns:
        A :class:`Sphere`, :class:`Box`, :class:`Capsule`, :class:`Cylinder` or
        :class:`Mesh`.

    Raises:
        InvalidInputError: ``d`` not a mapping, unknown shape, an unknown field
            (not in :data:`SHAPE_FIELDS` of its kind), or a missing or invalid
            field, e.g. ``object.radius must be finite and > 0, got -1.0``.
        MeshError: the mesh file is missing, unreadable, not closed, or its
            SHA-256 differs from ``sha256``.

    """
    if not isinstance(d, Mapping):
        raise InvalidInputError(f"{field} must be a table/dict, got {shorten(d)}")
    kind = d.get("shape")
    known = isinstance(kind, str) and kind in SHAPE_KINDS
    # a typo of "shape" itself is reported as such, not as a missing shape
    check_fields(d, field, SHAPE_FIELDS[cast(str, kind)] if known else ALL_SHAPE_FIELDS)
    if kind is None:
        raise InvalidInputError(
            f"{field}.shape is missing; expected one of {', '.join(SHAPE_KINDS)}"
        )
    if not known:
        raise InvalidInputError(
            f"{field}.shape must be one of {', '.join(SHAPE_KINDS)}, got {shorten(kind)}"
        )
    if kind == "sphere":
        return Sphere(_positive(d, "radius", field))
    if kind == "box":
        return Box(_size(d, field))
    if kind == "capsule":
        return Capsule(_positive(d, "radius", field), _positive(d, "length", field))
    if kind == "cylinder":
        return Cylinder(_positive(d, "radius", field), _positive(d, "length", field))
    return _mesh(d, base_dir, field)


def file_sha256(path: str | Path) -> str:
    """SHA-256 hex digest of a file's bytes (as stored in mesh ``sha256`` fields).

    Raises:
        MeshError: the file cannot be read.

    """
    try:
        return files.file_sha256(path)
    except OSError as exc:
        raise MeshError(f"cannot read {str(path)!r}: {exc}") from exc
