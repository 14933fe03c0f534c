"""Closed mesh surfaces: face checks, outward winding, pseudo-normals.

A :class:`~dexplan.model.objects.mesh.Mesh` must bound a solid: at least 4
faces, none of zero area, every edge shared by exactly two oppositely wound
faces, and a non-zero volume. The angle-weighted pseudo-normals (Baerentzen
and Aanaes, IEEE TVCG 2005) give the sign of the signed distance.
"""

from __future__ import annotations

import numpy as np

from dexplan.core.errors import InvalidInputError, MeshError
from dexplan.core.typing import FloatArray, IntArray
from dexplan.model.objects.shape import normalize_rows

__all__ = ["check_closed", "closed_surface", "face_indices", "pseudo_normals"]

#: Faces whose area is below this fraction of the squared bounding-box diagonal
#: are degenerate (zero area).
_DEGENERATE_AREA_REL = 1e-14
#: A mesh whose |volume| is below this fraction of the cubed diagonal is flat.
_FLAT_VOLUME_REL = 1e-12


def face_indices(faces: object, n_vertices: int) -> IntArray:
    """(F, 3) int64 face indices, checked for shape, type, count and range.

    Raises:
        InvalidInputError: not an (F, 3) integer array, or indices out of range.
        MeshError: fewer than 4 faces.
    """
    try:
        f_raw = np.asarray(faces)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"faces must be an (F, 3) integer array: {exc}") from exc
    if f_raw.ndim != 2 or f_raw.shape[1] != 3:
        raise InvalidInputError(f"faces must have shape (F, 3), got shape {f_raw.shape}")
    if f_raw.size and not np.issubdtype(f_raw.dtype, np.integer):
        raise InvalidInputError(f"faces must be integers, got dtype {f_raw.dtype}")
    f = np.ascontiguousarray(f_raw, dtype=np.int64)
    if len(f) < 4:
        raise MeshError(f"a closed mesh needs at least 4 faces, got {len(f)}")
    if f.min() < 0 or f.max() >= n_vertices:
        raise InvalidInputError(
            f"faces index vertices 0..{n_vertices - 1}, got indices in [{f.min()}, {f.max()}]"
        )
    return f


def closed_surface(
    v: FloatArray, f: IntArray, diag: float
) -> tuple[IntArray, FloatArray, FloatArray, FloatArray, float]:
    """Check that the faces bound a solid and wind them outwards.

    Args:
        v: (V, 3) vertices, object frame (m).
        f: (F, 3) face indices.
        diag: bounding-box diagonal of the used vertices (m), the size the
            degeneracy tolerances are relative to.

    Returns:
        ``(f, tris, cross, area2, volume)``: the faces wound counter-clockwise
        seen from outside, (F, 3, 3) triangles, (F, 3) edge cross products
        (outward, twice the area), (F,) their norms, the enclosed volume (> 0).

    Raises:
        MeshError: a zero-area face, an open or non-manifold edge, inconsistent
            winding, or zero volume.
    """
    tris = v[f]
    cross = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    area2 = np.sqrt(np.einsum("ij,ij->i", cross, cross))
    bad = np.flatnonzero(area2 / 2.0 <= _DEGENERATE_AREA_REL * diag * diag)
    if len(bad):
        raise MeshError(
            f"mesh has {len(bad)} degenerate (zero-area) faces, e.g. face {bad[0]} "
            f"with vertices {f[bad[0]].tolist()}"
        )
    check_closed(f, len(v))
    vol = float(np.einsum("ij,ij->i", tris[:, 0], cross).sum()) / 6.0
    if abs(vol) <= _FLAT_VOLUME_REL * diag**3:
        raise MeshError(f"mesh encloses zero volume ({vol!r} m^3)")
    if vol < 0.0:  # inward-facing: flip every face
        f = np.ascontiguousarray(f[:, [0, 2, 1]])
        tris = v[f]
        cross = -cross
        vol = -vol
    return f, tris, cross, area2, vol


def check_closed(f: IntArray, nv: int) -> None:
    """Raise MeshError unless every edge is shared by exactly two oppositely wound faces."""
    a = f.reshape(-1)
    b = f[:, [1, 2, 0]].reshape(-1)
    directed = a * nv + b
    uniq, counts = np.unique(directed, return_counts=True)
    if np.any(counts > 1):
        code = int(uniq[np.argmax(counts > 1)])
        raise MeshError(
            f"mesh is non-manifold or inconsistently oriented: directed edge "
            f"{code // nv}->{code % nv} is used by {int(counts.max())} faces"
        )
    reverse = b * nv + a
    missing = ~np.isin(reverse, uniq, assume_unique=False)
    if np.any(missing):
        i = int(np.flatnonzero(missing)[0])
        raise MeshError(
            f"mesh is not watertight: {int(missing.sum())} edges belong to one face only, "
            f"e.g. edge {int(a[i])}-{int(b[i])} of face {i // 3}"
        )


def pseudo_normals(
    v: FloatArray, f: IntArray, tris: FloatArray, fn: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Compute unit vertex pseudo-normals (V, 3, angle-weighted) and edge ones (F, 3, 3).

    Edge ``k`` of face ``i`` joins corners ``k`` and ``(k + 1) % 3``; its
    pseudo-normal is the normalized sum of the two adjacent face normals.
    """
    vpn = np.zeros_like(v)
    for k in range(3):
        e1 = tris[:, (k + 1) % 3] - tris[:, k]
        e2 = tris[:, (k + 2) % 3] - tris[:, k]
        cos = np.einsum("ij,ij->i", e1, e2)
        sin = np.linalg.norm(np.cross(e1, e2), axis=1)
        np.add.at(vpn, f[:, k], np.arctan2(sin, cos)[:, None] * fn)
    vpn = normalize_rows(vpn, (0.0, 0.0, 1.0))

    nv = len(v)
    a = f.reshape(-1)
    b = f[:, [1, 2, 0]].reshape(-1)
    key = np.minimum(a, b) * nv + np.maximum(a, b)
    _, inv = np.unique(key, return_inverse=True)
    esum = np.zeros((int(inv.max()) + 1, 3))
    np.add.at(esum, inv, np.repeat(fn, 3, axis=0))
    epn = normalize_rows(esum, (0.0, 0.0, 1.0))[inv].reshape(len(f), 3, 3)
    return vpn, np.ascontiguousarray(epn)
