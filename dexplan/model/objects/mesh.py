"""Closed triangle meshes: exact signed distance through a coal BVH.

Queries are exact, not approximations:

- the nearest triangle comes from a coal distance query between the mesh's
  ``BVHModelOBBRSS`` (the same one :meth:`Mesh.to_coal` returns) and a point
  (a zero-radius sphere); coal's point-triangle distance is exact and its BVH
  traversal prunes with exact bounds (checked against brute force in the tests);
- the closest point on that triangle and its feature (face, edge or vertex) come
  from Ericson's Voronoi-region test (*Real-Time Collision Detection*, 5.1.5);
- the sign comes from the angle-weighted pseudo-normal of that feature
  (Baerentzen and Aanaes, IEEE TVCG 2005), exact for closed, consistently
  oriented meshes.

A single-point query costs a few microseconds to a few tens of microseconds for
points near the surface, even for 100k triangles. Deep inside a mesh whose
triangles are all nearly equidistant (the centre of a finely tessellated sphere)
the BVH cannot prune and the cost grows with the triangle count.

A mesh keeps the origin of its file: the object frame is the file's frame, scaled
by ``scale`` about that origin (no recentring).

Queries reuse per-instance coal request/result objects: a :class:`Mesh` must not
be queried from several threads at once.
"""

from __future__ import annotations

import hashlib
import io
import math
import os
from pathlib import Path
from typing import Any, cast

import coal
import numpy as np
import numpy.typing as npt
import trimesh

from dexplan.core.errors import InvalidInputError, MeshError
from dexplan.core.files import read_input_file
from dexplan.core.typing import FloatArray, IntArray, as_points, as_positive
from dexplan.model.objects.mesh_features import SharpFeatures, sharp_features
from dexplan.model.objects.mesh_surface import closed_surface, face_indices, pseudo_normals
from dexplan.model.objects.shape import SCALAR_LOOP_MAX, Shape, ShapeKind, check_sample_args
from dexplan.model.objects.triangles import (
    EAB,
    EAC,
    EBC,
    FACE,
    VA,
    VB,
    VC,
    closest_on_triangle,
    closest_on_triangles,
)

#: Directory of the meshes shipped with dexplan (package data).
BUILTIN_MESH_DIR = Path(__file__).resolve().parents[2] / "data" / "meshes"

#: File units a mesh's coordinates may be in, with the scale that makes them metres.
UNIT_SCALES: tuple[tuple[str, float], ...] = (
    ("millimetres", 0.001),
    ("centimetres", 0.01),
    ("inches", 0.0254),
)


def unit_scale_hint(across_m: float, scale: float, max_across: float) -> str:
    """A hint for a mesh too large to be an in-hand object: the scale of its file's units.

    CAD and 3D-printing tools write millimetres; a hand-sized object read
    as metres is a thousand times too large. The first unit (millimetres,
    centimetres, inches) that brings it within ``max_across`` and above 1 cm
    is suggested, with the size it would then have.

    Args:
        across_m: the mesh's size (m) at ``scale`` (e.g. its bounding sphere's diameter).
        scale: the scale it was read with.
        max_across: the largest size allowed (m).

    Returns:
        ``"; in millimetres? scale = 0.001 makes it 0.104 m across"``, or "".
    """
    for unit, factor in UNIT_SCALES:
        size = across_m * factor
        if 0.01 <= size <= max_across:
            return f"; in {unit}? scale = {scale * factor:g} makes it {size:.3g} m across"
    return ""


#: Query points closer to the surface than this fraction of the bounding radius
#: are on the surface: their gradient is the feature's unit pseudo-normal.
_ON_SURFACE_REL = 1e-12


class Mesh(Shape):
    """A closed, consistently oriented triangle mesh.

    The signed distance is exact; its gradient is the face normal when the
    closest point is inside a face, else the unit vector from the closest edge
    or vertex point towards the query point (away from it inside). Exactly on
    an edge or vertex, where the distance is not differentiable, the gradient
    is the feature's unit angle-weighted pseudo-normal.

    Args:
        vertices: (V, 3) vertex positions in the object frame (m).
        faces: (F, 3) vertex indices per triangle; vertices must be shared
            between adjacent triangles. Faces wound clockwise (inward normals,
            negative volume) are flipped.

    Raises:
        InvalidInputError: wrong array shapes, non-finite vertices, bad indices.
        MeshError: fewer than 4 faces, a zero-area face, an open or non-manifold
            edge, inconsistent winding, or zero volume.

    """

    kind = ShapeKind.MESH

    def __init__(self, vertices: object, faces: object) -> None:
        v = np.ascontiguousarray(as_points(vertices, "vertices"))
        f = face_indices(faces, len(v))
        used = v[np.unique(f)]
        diag = float(np.linalg.norm(used.max(axis=0) - used.min(axis=0)))
        f, tris, cross, area2, vol = closed_surface(v, f, diag)

        self._v = v
        self._f = f
        self._tris = np.ascontiguousarray(tris)
        self._fn = cross / area2[:, None]
        self._areas = area2 / 2.0
        self._area = float(self._areas.sum())
        self._volume = vol
        self._cdf = np.cumsum(self._areas)
        self._vpn, self._fepn = pseudo_normals(v, f, self._tris, self._fn)
        self._radius = float(np.sqrt(np.einsum("ij,ij->i", used, used)).max())
        self._eps = _ON_SURFACE_REL * max(self._radius, diag)
        for arr in (self._v, self._f, self._tris, self._fn, self._areas):
            arr.flags.writeable = False

        self._path: Path | None = None
        self._scale = 1.0
        self._sha256: str | None = None
        self._bvh: Any = None
        self._point = coal.Sphere(0.0)
        self._identity = coal.Transform3s()
        self._tf = coal.Transform3s()
        self._req = coal.DistanceRequest()
        self._res = coal.DistanceResult()
        self._dist_fn: Any = None
        self._sharp: SharpFeatures | None = None

    # ------------------------------------------------------------ construction
    @classmethod
    def from_file(cls, path: str | os.PathLike[str], scale: float = 1.0) -> Mesh:
        """Load a closed mesh with trimesh (OBJ, STL, PLY, ... by file extension).

        Coincident vertices are merged and an inconsistent winding is repaired
        when possible; the file's origin is kept and the vertices are multiplied
        by ``scale``.

        Args:
            path: mesh file.
            scale: uniform scale applied to the vertices (e.g. 0.001 for mm files).

        Raises:
            InvalidInputError: bad scale.
            MeshError: missing or unreadable file, no triangles, or a mesh that is
                not closed (see :class:`Mesh`); the message names the path.

        """
        scale = as_positive(scale, "scale")
        p = Path(path)
        data = read_input_file(p, "mesh", MeshError)
        file_type = p.suffix.lower().lstrip(".")
        try:
            tm = trimesh.load(io.BytesIO(data), file_type=file_type, force="mesh", process=True)
        except Exception as exc:  # trimesh raises many types on bad input
            raise MeshError(f"cannot load mesh file {str(p)!r}: {exc}") from exc
        if not isinstance(tm, trimesh.Trimesh) or len(tm.faces) == 0:
            raise MeshError(f"mesh file {str(p)!r} contains no triangles")
        if tm.is_watertight and not tm.is_winding_consistent:
            trimesh.repair.fix_winding(tm)
        try:
            mesh = cls(np.asarray(tm.vertices, dtype=np.float64) * scale, tm.faces)
        except (MeshError, InvalidInputError) as exc:
            raise MeshError(f"mesh file {str(p)!r}: {exc}") from exc
        mesh._path = p.resolve()
        mesh._scale = scale
        mesh._sha256 = hashlib.sha256(data).hexdigest()
        return mesh

    # -------------------------------------------------------------- attributes
    @property
    def vertices(self) -> FloatArray:
        """(V, 3) vertices in the object frame (read-only)."""
        return self._v

    @property
    def faces(self) -> IntArray:
        """(F, 3) vertex indices, counter-clockwise seen from outside (read-only)."""
        return self._f

    @property
    def face_normals(self) -> FloatArray:
        """(F, 3) outward unit face normals in the object frame (read-only)."""
        return self._fn

    @property
    def face_areas(self) -> FloatArray:
        """(F,) triangle areas (m^2, read-only)."""
        return self._areas

    @property
    def path(self) -> Path | None:
        """Absolute path of the source file, or None for a mesh built from arrays."""
        return self._path

    @property
    def scale(self) -> float:
        """Scale applied to the file's vertices (1.0 for a mesh built from arrays)."""
        return self._scale

    @property
    def sha256(self) -> str | None:
        """SHA-256 hex digest of the source file's bytes, or None."""
        return self._sha256

    @property
    def bounding_radius(self) -> float:
        """Largest vertex distance from the object-frame origin (m)."""
        return self._radius

    @property
    def surface_area(self) -> float:
        """Total triangle area (m^2)."""
        return self._area

    @property
    def volume(self) -> float:
        """Enclosed volume (m^3, > 0)."""
        return self._volume

    def __repr__(self) -> str:
        src = f", path={str(self._path)!r}, scale={self._scale!r}" if self._path else ""
        return f"Mesh(n_vertices={len(self._v)}, n_faces={len(self._f)}{src})"

    def __eq__(self, other: object) -> bool:
        return (
            type(other) is Mesh
            and np.array_equal(other._v, self._v)
            and np.array_equal(other._f, self._f)
        )

    # compared by value: unhashable, as Python makes a class that defines __eq__; the
    # base class declares __hash__ as a method, so mypy wants an ignore here
    __hash__ = None  # type: ignore[assignment]

    def to_coal(self) -> coal.BVHModelOBBRSS:
        """Return the mesh as a ``coal.BVHModelOBBRSS`` (built once, cached, used by queries)."""
        if self._bvh is None:
            bvh = coal.BVHModelOBBRSS()
            bvh.beginModel(len(self._f), len(self._v))
            bvh.addVertices(self._v)
            bvh.addTriangles(self._f)
            bvh.endModel()
            self._bvh = bvh
            self._dist_fn = coal.ComputeDistance(bvh, self._point)
        return self._bvh

    def to_dict(self, base_dir: Path | None = None) -> dict[str, Any]:
        """``{"shape": "mesh", "path": ..., "scale": s, "sha256": ...}``.

        Args:
            base_dir: write ``path`` relative to this directory (POSIX
                separators); None writes the absolute path.

        Raises:
            InvalidInputError: the mesh was built from arrays and has no file.

        """
        if self._path is None:
            raise InvalidInputError(
                "a Mesh built from arrays has no file to reference; write it to a file "
                "and use Mesh.from_file"
            )
        path = self._path
        text = path.as_posix()
        if base_dir is not None:
            try:
                text = Path(os.path.relpath(path, Path(base_dir).resolve())).as_posix()
            except ValueError:  # different drives on Windows
                text = path.as_posix()
        return {"shape": "mesh", "path": text, "scale": self._scale, "sha256": self._sha256}

    # ----------------------------------------------------------------- queries
    def _nearest_triangle(self, p: FloatArray) -> int:
        """Index of a triangle closest to ``p: (3,)`` (coal BVH query)."""
        if self._dist_fn is None:
            self.to_coal()
        self._tf.setTranslation(p)
        self._res.clear()
        self._dist_fn(self._identity, self._tf, self._req, self._res)
        t = self._res.b1
        if not 0 <= t < len(self._f):
            raise MeshError(f"coal returned no triangle (index {t}) for the point {p.tolist()}")
        return t

    def _nearest_triangles(self, p: FloatArray) -> IntArray:
        """(N,) triangle indices closest to ``p: (N, 3)``."""
        p = np.ascontiguousarray(p)
        return np.fromiter((self._nearest_triangle(row) for row in p), np.int64, len(p))

    def _feature_normals(self, tri: IntArray, region: IntArray) -> FloatArray:
        """(N, 3) unit pseudo-normals of the features (vertex, edge, face) found."""
        pn = self._fn[tri].copy()
        for r in (VA, VB, VC):
            m = region == r
            pn[m] = self._vpn[self._f[tri[m], r]]
        for r, k in ((EAB, 0), (EBC, 1), (EAC, 2)):
            m = region == r
            pn[m] = self._fepn[tri[m], k]
        return pn

    def _feature_normal(self, tri: int, region: int) -> list[float]:
        if region == FACE:
            return self._fn[tri].tolist()
        if region <= VC:
            return self._vpn[self._f[tri, region]].tolist()
        k = 0 if region == EAB else (1 if region == EBC else 2)
        return self._fepn[tri, k].tolist()

    def _query_batch(
        self, p: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray, IntArray, FloatArray, FloatArray]:
        """Signed distance, gradient, closest point, triangle and (u, v) of (N, 3) points."""
        tri = self._nearest_triangles(p)
        t = self._tris[tri]
        q, u, v, region = closest_on_triangles(p, t[:, 0], t[:, 1], t[:, 2])
        diff = p - q
        dist = np.sqrt(np.einsum("ij,ij->i", diff, diff))
        pn = self._feature_normals(tri, region)
        sign = np.where(np.einsum("ij,ij->i", diff, pn) >= 0.0, 1.0, -1.0)
        on_face = region == FACE
        off = (dist > self._eps) & ~on_face
        g = pn  # faces and on-surface edge/vertex points: the pseudo-normal
        g[off] = sign[off, None] * diff[off] / dist[off, None]
        d = sign * dist
        # on a face the signed distance is the plane distance (more accurate)
        d[on_face] = np.einsum("ij,ij->i", p[on_face] - t[on_face, 0], self._fn[tri[on_face]])
        return d, g, q, tri, u, v

    def _sdf_grad_batch(self, p: FloatArray) -> tuple[FloatArray, FloatArray]:
        d, g, *_ = self._query_batch(p)
        return d, g

    def _closest_batch(self, p: FloatArray) -> tuple[FloatArray, FloatArray]:
        _, g, q, *_ = self._query_batch(p)
        return q, g

    def _query_xyz(
        self, x: float, y: float, z: float
    ) -> tuple[float, float, float, float, float, float, float, int, float, float]:
        """Scalar fast path: ``(d, gx, gy, gz, qx, qy, qz, tri, u, v)`` of one point."""
        t = self._nearest_triangle(np.array((x, y, z)))
        qx, qy, qz, u, v, region = closest_on_triangle(x, y, z, self._tris[t].tolist())
        nx, ny, nz = self._feature_normal(t, region)
        dx, dy, dz = x - qx, y - qy, z - qz
        s = dx * nx + dy * ny + dz * nz
        if region == FACE:
            return s, nx, ny, nz, qx, qy, qz, t, u, v
        dist = math.sqrt(dx * dx + dy * dy + dz * dz)
        sign = 1.0 if s >= 0.0 else -1.0
        if dist > self._eps:
            k = sign / dist
            return sign * dist, k * dx, k * dy, k * dz, qx, qy, qz, t, u, v
        return sign * dist, nx, ny, nz, qx, qy, qz, t, u, v

    def _sdf_grad_xyz(self, x: float, y: float, z: float) -> tuple[float, float, float, float]:
        r = self._query_xyz(x, y, z)
        return r[0], r[1], r[2], r[3]

    def _closest_xyz(
        self, x: float, y: float, z: float
    ) -> tuple[float, float, float, float, float, float]:
        r = self._query_xyz(x, y, z)
        return r[4], r[5], r[6], r[1], r[2], r[3]

    # ---------------------------------------------------------------- contacts
    def contact_params(self, points: object) -> tuple[IntArray, FloatArray, FloatArray]:
        """Surface parameters ``(tri, u, v)`` of the closest surface points.

        The closest point is ``(1 - u - v) A + u B + v C`` for triangle
        ``faces[tri] = (A, B, C)``, with ``u, v >= 0`` and ``u + v <= 1``.

        Args:
            points: (N, 3) or (3,) points in the object frame (usually on the surface).

        Returns:
            ``(tri (N,) int, u (N,), v (N,))``, or an int and two floats for (3,).

        Raises:
            InvalidInputError: wrong shape or a non-finite coordinate.

        """
        single = np.ndim(cast("npt.ArrayLike", points)) == 1
        p = as_points(points, "points")
        if len(p) <= SCALAR_LOOP_MAX:
            rows = [self._query_xyz(x, y, z)[7:] for x, y, z in p.tolist()]
            if single:
                # one point: the scalar (int, float, float) the docstring promises
                return rows[0]  # type: ignore[return-value]
            tri = np.array([r[0] for r in rows], dtype=np.int64)
            u = np.array([r[1] for r in rows], dtype=np.float64)
            v = np.array([r[2] for r in rows], dtype=np.float64)
            return tri, u, v
        tri = self._nearest_triangles(p)
        t = self._tris[tri]
        _, u, v, _ = closest_on_triangles(p, t[:, 0], t[:, 1], t[:, 2])
        return tri, u, v

    def contact_points(self, tri: object, u: object, v: object) -> FloatArray:
        """Surface points ``(1 - u - v) A + u B + v C`` of triangles ``faces[tri]``.

        Args:
            tri: (N,) triangle indices (or an int).
            u: (N,) barycentric weights of B (or a float), ``u >= 0``.
            v: (N,) barycentric weights of C (or a float), ``v >= 0``,
                ``u + v <= 1`` (up to 1e-9).

        Returns:
            (N, 3) points in the object frame, or (3,) for scalar inputs.

        Raises:
            InvalidInputError: index out of range, mismatched lengths, or (u, v)
                outside the triangle.

        """
        tri_a, u_a, v_a, single = self._check_params(tri, u, v)
        t = self._tris[tri_a]
        p = t[:, 0] + u_a[:, None] * (t[:, 1] - t[:, 0]) + v_a[:, None] * (t[:, 2] - t[:, 0])
        return p[0] if single else p

    def contact_normals(self, tri: object) -> FloatArray:
        """Outward unit normals (N, 3) (or (3,)) of triangles ``tri``, object frame."""
        tri_a = np.asarray(tri)
        t = tri_a.reshape(-1)
        if not np.issubdtype(t.dtype, np.integer) or (
            len(t) and (t.min() < 0 or t.max() >= len(self._f))
        ):
            raise InvalidInputError(
                f"tri must be integers in [0, {len(self._f) - 1}], got {tri_a.tolist()!r}"
            )
        n = self._fn[t]
        return n[0] if tri_a.ndim == 0 else n

    def _check_params(
        self, tri: object, u: object, v: object
    ) -> tuple[IntArray, FloatArray, FloatArray, bool]:
        t = np.asarray(tri)
        single = t.ndim == 0
        t = t.reshape(-1)
        uu = np.asarray(u, dtype=np.float64).reshape(-1)
        vv = np.asarray(v, dtype=np.float64).reshape(-1)
        if not (len(t) == len(uu) == len(vv)):
            raise InvalidInputError(
                f"tri, u, v must have the same length, got {len(t)}, {len(uu)}, {len(vv)}"
            )
        if len(t) and (
            not np.issubdtype(t.dtype, np.integer) or t.min() < 0 or t.max() >= len(self._f)
        ):
            raise InvalidInputError(
                f"tri must be integers in [0, {len(self._f) - 1}], got {t[:8].tolist()!r}"
            )
        tol = 1e-9
        bad = ~(np.isfinite(uu) & np.isfinite(vv) & (uu >= -tol) & (vv >= -tol))
        bad |= uu + vv > 1.0 + tol
        if np.any(bad):
            i = int(np.flatnonzero(bad)[0])
            raise InvalidInputError(
                f"(u, v) must satisfy u, v >= 0 and u + v <= 1, got ({uu[i]!r}, {vv[i]!r}) "
                f"at index {i}"
            )
        return t.astype(np.int64, copy=False), uu, vv, single

    def sample_surface_params(
        self, n: int, rng: np.random.Generator
    ) -> tuple[IntArray, FloatArray, FloatArray]:
        """Area-uniform surface samples as ``(tri, u, v)``.

        A triangle is drawn with probability proportional to its area, then a
        uniform point in it (folded unit square).

        Args:
            n: number of samples (>= 0).
            rng: random generator.

        Returns:
            ``(tri (n,) int, u (n,), v (n,))``; see :meth:`contact_points`.

        Raises:
            InvalidInputError: bad ``n`` or ``rng``.

        """
        n = check_sample_args(n, rng)
        tri = np.searchsorted(self._cdf, rng.random(n) * self._cdf[-1], side="right")
        tri = np.minimum(tri, len(self._f) - 1).astype(np.int64)
        uv = rng.random((n, 2))
        fold = uv.sum(axis=1) > 1.0
        uv[fold] = 1.0 - uv[fold]
        return tri, uv[:, 0].copy(), uv[:, 1].copy()

    def _sample(self, n: int, rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
        tri, u, v = self.sample_surface_params(n, rng)
        t = self._tris[tri]
        p = t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + v[:, None] * (t[:, 2] - t[:, 0])
        return p, self._fn[tri]

    def _sharp_features(self) -> SharpFeatures:
        """The sharp convex edges and vertices (found once, on first use)."""
        if self._sharp is None:
            self._sharp = sharp_features(self._v, self._f, self._vpn)
        return self._sharp

    def sample_edges(self, n: int, rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
        """Points on the sharp convex edges, normals between the two faces' normals.

        See :meth:`~dexplan.model.objects.mesh_features.SharpFeatures.sample_edges`:
        edges whose faces' normals differ by at least 20 degrees, on the convex
        side; a smooth mesh has none and returns empty arrays.
        """
        n = check_sample_args(n, rng)
        return self._sharp_features().sample_edges(n, rng)

    def sample_vertices(self, n: int, rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
        """Points at the sharp convex vertices, normals inside the incident faces' cone.

        See :meth:`~dexplan.model.objects.mesh_features.SharpFeatures.sample_vertices`;
        a smooth mesh has none and returns empty arrays.
        """
        n = check_sample_args(n, rng)
        return self._sharp_features().sample_vertices(n, rng)
