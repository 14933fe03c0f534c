"""Shapes from scenario tables and plan-file dictionaries.

The schema (shared by ``[object]`` / ``[[obstacles]]`` in scenarios and
``"object"`` / ``"obstacles"`` in plan files)::

    {"shape": "sphere", "radius": r}
    {"shape": "box", "size": [sx, sy, sz]}
    {"shape": "capsule" | "cylinder", "radius": r, "length": l}
    {"shape": "mesh", "path": "meshes/x.obj", "scale": 1.0, "sha256": "..."}

Lengths are in metres. ``scale`` (default 1.0) and ``sha256`` are optional; a
given ``sha256`` must match the file's bytes. Keys outside the schema (such as
an obstacle's ``pose_xyzquat``) are ignored.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from dexplan.exceptions import InvalidInputError, MeshError, shorten
from dexplan.objects.mesh import Mesh
from dexplan.objects.primitives import Box, Capsule, Cylinder, Sphere
from dexplan.objects.shape import Shape

#: Shape names accepted in the ``shape`` field.
SHAPE_KINDS: tuple[str, ...] = ("sphere", "box", "capsule", "cylinder", "mesh")


def _positive(d: Mapping[str, Any], key: str, field: str, default: float | None = None) -> float:
    """``d[key]`` as a finite float > 0; errors name ``field.key`` and the value."""
    name = f"{field}.{key}"
    if key not in d:
        if default is not None:
            return default
        raise InvalidInputError(f"{name} is missing")
    value = d[key]
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InvalidInputError(f"{name} must be a number, got {shorten(value)}")
    x = float(value)
    if not math.isfinite(x) or x <= 0.0:
        raise InvalidInputError(f"{name} must be finite and > 0, got {x!r}")
    return x


def _size(d: Mapping[str, Any], field: str) -> list[float]:
    name = f"{field}.size"
    if "size" not in d:
        raise InvalidInputError(f"{name} is missing")
    value = d["size"]
    ok = (
        isinstance(value, list | tuple)
        and len(value) == 3
        and all(isinstance(x, int | float) and not isinstance(x, bool) for x in value)
        and all(math.isfinite(x) and x > 0.0 for x in value)
    )
    if not ok:
        raise InvalidInputError(
            f"{name} must be 3 finite numbers > 0 (full edge lengths), got {shorten(value)}"
        )
    return [float(x) for x in value]


def _mesh(d: Mapping[str, Any], base_dir: Path | None, field: str) -> Mesh:
    raw = d.get("path")
    if not isinstance(raw, str) or not raw:
        what = "is missing" if raw is None else f"must be a non-empty string, got {shorten(raw)}"
        raise InvalidInputError(f"{field}.path {what}")
    path = Path(raw)
    if not path.is_absolute() and base_dir is not None:
        path = Path(base_dir) / path
    scale = _positive(d, "scale", field, default=1.0)
    expected = d.get("sha256")
    if expected is not None and not isinstance(expected, str):
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
        InvalidInputError: ``d`` not a mapping, unknown shape, or a missing or
            invalid field, e.g. ``object.radius must be finite and > 0, got -1.0``.
        MeshError: the mesh file is missing, unreadable, not closed, or its
            SHA-256 differs from ``sha256``.

    """
    if not isinstance(d, Mapping):
        raise InvalidInputError(f"{field} must be a table/dict, got {shorten(d)}")
    kind = d.get("shape")
    if kind is None:
        raise InvalidInputError(
            f"{field}.shape is missing; expected one of {', '.join(SHAPE_KINDS)}"
        )
    if kind not in SHAPE_KINDS:
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
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError as exc:
        raise MeshError(f"cannot read {str(path)!r}: {exc}") from exc
