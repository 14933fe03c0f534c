"""The roadmap file (``.npz``): reading and checking it before anything trusts it.

A roadmap file holds four arrays, ``vertices`` ``(V, 7 + nq)`` GSn states,
``edges`` and ``links`` ``(E, 2)`` vertex index pairs, and ``meta`` (a JSON
text: the format, the planner, the scenario key and the build statistics).
:func:`read_roadmap_arrays` checks sizes from the zip headers before loading
anything, then shapes, dtypes, finiteness, unit quaternions and indices, so a
malformed or hostile file fails with one :class:`RoadmapFileError` line.
:class:`dexplan.planning.roadmap.graph.Roadmap` writes and loads it.
"""

from __future__ import annotations

import json
import math
import zipfile
import zlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.lib import format as npy

from dexplan.core.errors import RoadmapFileError, shorten, unknown_field
from dexplan.core.typing import FloatArray
from dexplan.model.objects.factory import field_key
from dexplan.planning.gsn.space import POSE_DIM

ROADMAP_FORMAT = "dexplan-roadmap/1"

MAX_ROADMAP_VERTICES = 10_000_000
"""Most vertices a roadmap file may hold."""

MAX_ROADMAP_NUMBERS = 250_000_000
"""Most numbers in ``vertices`` (2 GB of float64: 10M vertices of a 16-joint hand)."""

MAX_ROADMAP_EDGES = 50_000_000
"""Most rows of ``edges``, and of ``links``, a roadmap file may hold."""

MAX_ROADMAP_JOINTS = 256
"""Most hand joints a vertex may carry (a vertex is ``7 + nq`` numbers)."""

MAX_ROADMAP_META = 100_000
"""Longest ``meta`` JSON text (characters)."""

ROADMAP_QUAT_TOL = 1e-3
"""Largest ``| |quaternion| - 1 |`` of a vertex (GSn states have unit quaternions)."""

_ROADMAP_ARRAYS = ("vertices", "edges", "links", "meta")
_ROADMAP_META_FIELDS = frozenset({"format", "planner", "scenario_key", "build"})
_MAX_BUILD_FIELDS = 64


def _roadmap_error(where: str, msg: str) -> RoadmapFileError:
    return RoadmapFileError(f"{where}: {' '.join(msg.split())}")


_Headers = dict[str, tuple[tuple[int, ...], np.dtype]]


def _read_headers(path: Path, where: str) -> tuple[_Headers, dict[str, tuple[int, int]]]:
    """Shape and dtype of every array, from the ``.npy`` headers only, and their sizes.

    Returns:
        ``{name: (shape, dtype)}`` and ``{name: (header bytes, member bytes)}``.
    """
    out: _Headers = {}
    sizes: dict[str, tuple[int, int]] = {}
    try:
        with zipfile.ZipFile(path) as zf:
            members = {info.filename: info for info in zf.infolist()}
            for member in members:
                name = member.removesuffix(".npy")
                if name not in _ROADMAP_ARRAYS or not member.endswith(".npy"):
                    raise _roadmap_error(
                        where,
                        f"unknown array {shorten(member, 40)} (a roadmap holds "
                        f"{', '.join(_ROADMAP_ARRAYS)})",
                    )
            for name in _ROADMAP_ARRAYS:
                info = members.get(f"{name}.npy")
                if info is None:
                    raise _roadmap_error(where, f"array {name!r} is missing")
                with zf.open(info) as fh:
                    version = npy.read_magic(fh)
                    if version == (1, 0):
                        shape, _, dtype = npy.read_array_header_1_0(fh)
                    elif version == (2, 0):
                        shape, _, dtype = npy.read_array_header_2_0(fh)
                    else:
                        raise _roadmap_error(where, f"{name}: unsupported .npy version {version}")
                    header_bytes = fh.tell()
                out[name] = (tuple(shape), dtype)
                sizes[name] = (header_bytes, info.file_size)
    except (zipfile.BadZipFile, zipfile.LargeZipFile) as exc:
        raise _roadmap_error(
            where, f"not a roadmap: not a complete .npz archive ({str(exc)[:80]})"
        ) from exc
    except (OSError, ValueError, EOFError, zlib.error, NotImplementedError) as exc:
        raise _roadmap_error(where, f"not a roadmap: unreadable .npz ({str(exc)[:80]})") from exc
    return out, sizes


def _check_sizes(headers: _Headers, sizes: Mapping[str, tuple[int, int]], where: str) -> None:
    """Every member holds as many bytes as its header promises (no read past a short one)."""
    for name, (shape, dtype) in headers.items():
        header_bytes, member_bytes = sizes[name]
        claimed = header_bytes + math.prod(shape) * dtype.itemsize
        if member_bytes != claimed:
            raise _roadmap_error(
                where,
                f"{name}: the header claims shape {shape} ({claimed} bytes) but the archive "
                f"holds {member_bytes} bytes",
            )


def _check_headers(headers: _Headers, where: str, ambient_dim: int | None) -> None:
    """Bound shapes and dtypes before any array is read (a header can claim 1e9 rows)."""
    shape, dtype = headers["vertices"]
    if dtype.kind != "f" or len(shape) != 2:
        raise _roadmap_error(
            where, f"vertices must be a 2-D float array, got {dtype.str} of shape {shape}"
        )
    rows, cols = shape
    lo, hi = POSE_DIM + 1, POSE_DIM + MAX_ROADMAP_JOINTS
    if ambient_dim is not None and cols != ambient_dim:
        raise _roadmap_error(
            where, f"vertices have {cols} columns, the hand's states have {ambient_dim} (7 + nq)"
        )
    if not lo <= cols <= hi:
        raise _roadmap_error(
            where, f"vertices must have {lo} to {hi} columns (7 pose + nq joints), got {cols}"
        )
    if rows > MAX_ROADMAP_VERTICES or rows * cols > MAX_ROADMAP_NUMBERS:
        raise _roadmap_error(
            where,
            f"vertices has {rows} rows of {cols}; at most {MAX_ROADMAP_VERTICES} vertices and "
            f"{MAX_ROADMAP_NUMBERS} numbers are read",
        )
    for name in ("edges", "links"):
        shape, dtype = headers[name]
        if dtype.kind not in "iu" or not (
            (len(shape) == 2 and shape[1] == 2) or shape in ((0,), (0, 0))
        ):
            raise _roadmap_error(
                where,
                f"{name} must be an (n, 2) integer array of vertex indices, "
                f"got {dtype.str} of shape {shape}",
            )
        if shape[0] > MAX_ROADMAP_EDGES:
            raise _roadmap_error(
                where, f"{name} has {shape[0]} rows; at most {MAX_ROADMAP_EDGES} are read"
            )
    shape, dtype = headers["meta"]
    if dtype.kind != "U" or shape != () or dtype.itemsize // 4 > MAX_ROADMAP_META:
        raise _roadmap_error(
            where,
            f"meta must be one JSON string of at most {MAX_ROADMAP_META} characters, "
            f"got {dtype.str} of shape {shape}",
        )


def _check_meta(text: str, where: str) -> dict[str, Any]:
    try:
        meta = json.loads(text)
    except (ValueError, RecursionError) as exc:
        raise _roadmap_error(where, f"meta is not JSON ({str(exc)[:80]})") from exc
    if not isinstance(meta, dict):
        raise _roadmap_error(where, f"meta must be a JSON object, got {shorten(meta)}")
    if meta.get("format") != ROADMAP_FORMAT:
        raise _roadmap_error(
            where, f"meta.format must be {ROADMAP_FORMAT!r}, got {shorten(meta.get('format'))}"
        )
    for key, value in meta.items():
        if key not in _ROADMAP_META_FIELDS:
            raise _roadmap_error(
                where, unknown_field("meta", field_key(key), value, _ROADMAP_META_FIELDS)
            )
    _check_build(meta.get("build", {}), where)
    for key, limit in (("planner", 256), ("scenario_key", 64)):
        value = meta.get(key)
        if not isinstance(value, str) or not value or len(value) > limit or not value.isprintable():
            raise _roadmap_error(
                where,
                f"meta.{key} must be a non-empty string of at most {limit} printable "
                f"characters, got {shorten(value)}",
            )
    return meta


def _check_build(build: object, where: str) -> None:
    """``meta.build`` (optional): a flat object of numbers, strings, booleans and nulls."""
    if not isinstance(build, dict) or len(build) > _MAX_BUILD_FIELDS:
        raise _roadmap_error(
            where,
            f"meta.build must be a JSON object of at most {_MAX_BUILD_FIELDS} fields, "
            f"got {shorten(build)}",
        )
    for key, value in build.items():
        if not isinstance(value, int | float | str | bool | type(None)) or (
            isinstance(value, str) and len(value) > 256
        ):
            raise _roadmap_error(
                where,
                f"meta.build.{field_key(key)} must be a number, string or null, got "
                f"{shorten(value)}",
            )


def _check_indices(arr: np.ndarray, name: str, n: int, where: str) -> np.ndarray:
    arr = arr.reshape(-1, 2)
    if len(arr) == 0:
        return arr.astype(np.int64)
    bad = np.flatnonzero(((arr < 0) | (arr >= n)).any(axis=1))
    if len(bad):
        k = int(bad[0])
        raise _roadmap_error(
            where,
            f"{name}[{k}] = {arr[k].tolist()} refers to a missing vertex "
            f"(the roadmap has {n} vertices; {len(bad)} bad rows)",
        )
    return arr.astype(np.int64)


def read_roadmap_arrays(
    path: str | Path, *, ambient_dim: int | None = None
) -> tuple[FloatArray, np.ndarray, np.ndarray, dict[str, Any]]:
    """Read a roadmap file's arrays and metadata, checking everything first.

    Checks, in order: the file is a complete ``.npz`` archive holding exactly
    ``vertices``, ``edges``, ``links`` and ``meta``; their ``.npy`` headers
    (read before any data, so a header claiming 1e9 rows costs nothing) give a
    2-D float ``vertices`` of ``7 + nq`` columns with at most
    :data:`MAX_ROADMAP_VERTICES` rows and :data:`MAX_ROADMAP_NUMBERS` numbers,
    ``(n, 2)`` integer ``edges`` and ``links`` of at most
    :data:`MAX_ROADMAP_EDGES` rows, and a JSON string ``meta``; then the data:
    ``meta`` is an object with ``format`` (= :data:`ROADMAP_FORMAT`),
    ``planner``, ``scenario_key`` and optionally ``build`` (a flat object of
    numbers, strings and nulls: the learning phase's statistics), every vertex is finite with a unit
    quaternion (within :data:`ROADMAP_QUAT_TOL`), and every index refers to a
    vertex. Arrays are read with ``allow_pickle=False``.

    Args:
        path: the ``.npz`` file.
        ambient_dim: when given, the exact vertex width.

    Returns:
        ``(vertices (N, 7 + nq) float64, edges (E, 2) int64, links (L, 2) int64, meta)``.

    Raises:
        RoadmapFileError: the first check that fails, naming the array or field.
    """
    path = Path(path)
    where = shorten(str(path))
    try:
        exists = path.is_file()
    except (OSError, ValueError) as exc:
        raise _roadmap_error(where, f"cannot use this roadmap file name ({exc})") from exc
    if not exists:
        raise RoadmapFileError(f"roadmap file not found: {where}")
    headers, sizes = _read_headers(path, where)
    _check_headers(headers, where, ambient_dim)
    _check_sizes(headers, sizes, where)
    try:
        with np.load(path, allow_pickle=False) as data:
            raw = {name: data[name] for name in _ROADMAP_ARRAYS}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error) as exc:
        raise _roadmap_error(
            where, f"not a roadmap: unreadable data ({shorten(str(exc), 80)})"
        ) from exc
    for name in _ROADMAP_ARRAYS:  # what the headers promised (they were read above)
        shape, dtype = headers[name]
        if raw[name].shape != shape or raw[name].dtype != dtype:
            raise _roadmap_error(where, f"{name} changed while it was read")
    meta = _check_meta(str(raw["meta"]), where)
    vertices = np.asarray(raw["vertices"], dtype=np.float64)
    finite = np.isfinite(vertices).all(axis=1)
    if not finite.all():
        k = int(np.flatnonzero(~finite)[0])
        raise _roadmap_error(where, f"vertices[{k}] is not finite: {shorten(vertices[k].tolist())}")
    with np.errstate(over="ignore"):  # a huge quaternion has norm inf: rejected below
        norms = np.linalg.norm(vertices[:, 3:POSE_DIM], axis=1)
    bad = np.flatnonzero(np.abs(norms - 1.0) > ROADMAP_QUAT_TOL)
    if len(bad):
        k = int(bad[0])
        raise _roadmap_error(
            where,
            f"vertices[{k}] quaternion (columns 3-6, XYZW) has norm {norms[k]:.6g}, must be 1 "
            f"({len(bad)} such vertices)",
        )
    n = len(vertices)
    edges = _check_indices(raw["edges"], "edges", n, where)
    links = _check_indices(raw["links"], "links", n, where)
    return vertices, edges, links, meta
