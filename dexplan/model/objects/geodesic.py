"""Geodesic paths on mesh surfaces (paper, section VI), computed by potpourri3d.

On a triangulated object a contact is ``(triangle, u, v)`` and a contact that
moves between two grasps follows a geodesic of the surface, a sequence of line
segments (the paper's section VI). This module wraps potpourri3d's
``EdgeFlipGeodesicSolver`` (Sharp and Crane, "You Can Find Geodesic Paths in
Triangle Meshes by Just Flipping Edges", SIGGRAPH Asia 2020), which shortens a
vertex-to-vertex edge path into a locally shortest (geodesic) polyline on the
surface. Nothing geodesic is written here: the module snaps points to the
surface, stitches the ends and reads positions along the polyline.

The solver joins mesh vertices only, so a path between two surface points
``p`` (in triangle ``T_p``) and ``q`` (in ``T_q``) is

- the straight segment ``p q`` when both lie in one triangle (exact);
- otherwise ``p``, a corner ``a`` of ``T_p``, the geodesic from ``a`` to a
  corner ``b`` of ``T_q``, then ``q``: the shortest of the 9 corner pairs
  (pairs whose straight-line bound cannot beat the best are not solved). The segments
  ``p a`` and ``b q`` lie inside their triangles, so the polyline is on the
  surface and continuous; it is at most ``2 (|p a| + |b q|)`` longer than the
  geodesic from ``p`` to ``q`` (triangle inequality), i.e. within a few edge
  lengths of it: the error scales with the mesh resolution.

One solver is built per mesh and cached (``surface_geodesics(mesh)``; about
15 ms for 5k triangles, then 1-15 ms a path, ``scripts/bench_geodesic.py``).
Like the mesh's own queries, a solver must not be used from several threads
at once. The solver
restores its triangulation after every query, so a path depends on its two
end points only, not on the queries made before it.

Degenerate meshes: :class:`~dexplan.model.objects.Mesh` already refuses open,
non-manifold-edge and zero-area meshes. A mesh that passes those checks but
that the solver cannot use (a non-manifold *vertex*, where two sheets touch at
one point, or end points on two disconnected shells) raises
:class:`~dexplan.core.errors.GeodesicError` naming the mesh; callers that can
do without geodesics (the planner's contact interpolation) catch it and fall
back to what they did before (documented where they do).
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import potpourri3d as pp3d

from dexplan.core.errors import GeodesicError, one_line
from dexplan.core.typing import FloatArray, IntArray, as_vector
from dexplan.model.objects.mesh import Mesh

__all__ = ["MeshGeodesics", "SurfacePath", "surface_geodesics"]

#: Consecutive polyline points closer than this fraction of the mesh's
#: bounding radius are merged (the stitched ends may repeat a corner).
_SAME_POINT_REL = 1e-12


#: Vertex-to-vertex geodesics remembered per mesh (bisections ask for the same
#: corners again).
_CACHE_SIZE = 4096


@dataclass(frozen=True)
class SurfacePath:
    """A polyline on a mesh surface, in the object frame.

    Attributes:
        points: (k, 3) polyline points on the surface, object frame (m),
            ``k >= 1`` (one point when both ends are the same point).
        triangles: (k,) index of the triangle each point lies in; a point on
            an edge or a vertex gets the triangle of the segment leaving it
            (the last point: the triangle of its end).
        normals_out: (k, 3) outward unit normals of those triangles, object frame.
    """

    points: FloatArray
    triangles: IntArray
    normals_out: FloatArray

    @property
    def cumulative(self) -> FloatArray:
        """(k,) arc length from the first point to each point (m)."""
        seg = np.linalg.norm(np.diff(self.points, axis=0), axis=1)
        return np.concatenate([[0.0], np.cumsum(seg)])

    @property
    def length(self) -> float:
        """Polyline length (m)."""
        return float(self.cumulative[-1])

    def at(self, fraction: float) -> tuple[FloatArray, int, FloatArray]:
        """The surface point at a fraction of the arc length.

        Args:
            fraction: 0 (first point) to 1 (last point); clipped to [0, 1].

        Returns:
            ``(point (3,), triangle, normal_out (3,))``, object frame.
        """
        s = float(np.clip(fraction, 0.0, 1.0))
        cum = self.cumulative
        if cum[-1] <= 0.0 or len(cum) == 1:
            return self.points[0].copy(), int(self.triangles[0]), self.normals_out[0].copy()
        target = s * cum[-1]
        i = int(np.searchsorted(cum, target, side="right")) - 1
        i = min(max(i, 0), len(cum) - 2)
        seg = cum[i + 1] - cum[i]
        w = 0.0 if seg <= 0.0 else (target - cum[i]) / seg
        if w >= 1.0:
            i, w = i + 1, 0.0
            if i == len(cum) - 1:
                return self.points[-1].copy(), int(self.triangles[-1]), self.normals_out[-1].copy()
        p = self.points[i] + w * (self.points[i + 1] - self.points[i])
        return p, int(self.triangles[i]), self.normals_out[i].copy()

    def resample(self, max_step: float) -> FloatArray:
        """(m, 3) points along the path, ends included, at most ``max_step`` (m) apart.

        Every polyline point is kept (the path bends only there) and each
        segment is split evenly.
        """
        step = float(max_step)
        if not math.isfinite(step) or step <= 0.0:
            raise GeodesicError(f"max_step must be a positive length, got {max_step!r}")
        out = [self.points[0]]
        for a, b in zip(self.points[:-1], self.points[1:], strict=True):
            k = max(1, math.ceil(float(np.linalg.norm(b - a)) / step))
            out.extend(a + (b - a) * (j / k) for j in range(1, k + 1))
        return np.array(out).reshape(-1, 3)


class MeshGeodesics:
    """Geodesic paths between surface points of one mesh (potpourri3d edge flips).

    Build it with :func:`surface_geodesics` (one per mesh, cached).

    Args:
        mesh: the mesh (object frame).

    Raises:
        GeodesicError: potpourri3d cannot use the mesh (e.g. a non-manifold
            vertex); the message names the mesh.
    """

    def __init__(self, mesh: Mesh) -> None:
        self.mesh = mesh
        self._name = _mesh_name(mesh)
        try:
            self._solver = pp3d.EdgeFlipGeodesicSolver(
                np.ascontiguousarray(mesh.vertices, dtype=np.float64),
                np.ascontiguousarray(mesh.faces, dtype=np.int64),
            )
        except Exception as exc:  # geometry-central raises RuntimeError, validation ValueError
            raise GeodesicError(
                f"cannot compute geodesics on {self._name}: {one_line(exc)}"
            ) from exc
        self._cache: dict[tuple[int, int], FloatArray] = {}
        self._eps = _SAME_POINT_REL * max(mesh.bounding_radius, 1e-300)

    def snap(self, point: object) -> tuple[FloatArray, int]:
        """Closest surface point of ``point: (3,)`` (object frame) and its triangle."""
        p = as_vector(point, "point", 3)
        tri, u, v = self.mesh.contact_params(p)
        return self.mesh.contact_points(tri, u, v), int(tri)

    def path(self, p_a: object, p_b: object) -> SurfacePath:
        """Geodesic polyline from ``p_a`` to ``p_b`` on the surface.

        Args:
            p_a: (3,) start point, object frame; snapped to the surface.
            p_b: (3,) end point, object frame; snapped to the surface.

        Returns:
            The :class:`SurfacePath` from the snapped ``p_a`` to the snapped
            ``p_b`` (see the module docstring for its accuracy).

        Raises:
            InvalidInputError: a point is not a finite (3,) vector.
            GeodesicError: the points lie on disconnected parts of the surface,
                or potpourri3d fails; the message names the mesh.
        """
        a, tri_a = self.snap(p_a)
        b, tri_b = self.snap(p_b)
        pts = np.array([a, b]) if tri_a == tri_b else self._stitched(a, tri_a, b, tri_b)
        pts = self._dedupe(pts)
        tris = self._triangles(pts, tri_b)
        return SurfacePath(pts, tris, self.mesh.face_normals[tris])

    def distance(self, p_a: object, p_b: object) -> float:
        """Length (m) of :meth:`path` from ``p_a`` to ``p_b``."""
        return self.path(p_a, p_b).length

    # ---------------------------------------------------------------- helpers
    def _stitched(self, a: FloatArray, tri_a: int, b: FloatArray, tri_b: int) -> FloatArray:
        """Shortest of ``a``, corner of ``tri_a``, geodesic, corner of ``tri_b``, ``b``.

        Of the 9 corner pairs (a shared corner gives ``a``, it, ``b``), those
        whose straight-line bound ``|a va| + |va vb| + |vb b|`` (no longer
        than the stitched path) beats the best so far are solved, lowest
        bound first: the shortest of all 9, for a few solver queries.
        """
        verts = self.mesh.vertices
        pairs = [
            (va, vb) for va in self.mesh.faces[tri_a].tolist() for vb in self.mesh.faces[tri_b]
        ]
        bounds = [
            float(
                np.linalg.norm(verts[va] - a)
                + np.linalg.norm(verts[vb] - verts[va])
                + np.linalg.norm(b - verts[vb])
            )
            for va, vb in pairs
        ]
        best: FloatArray | None = None
        best_len = math.inf
        for k in np.argsort(bounds, kind="stable").tolist():
            if bounds[k] >= best_len:
                break
            va, vb = pairs[k]
            middle = verts[va][None] if va == vb else self._vertex_path(va, vb, a, b)
            pts = np.vstack([a[None], middle, b[None]])
            length = float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())
            if length < best_len:
                best, best_len = pts, length
        assert best is not None
        return best

    def _vertex_path(self, va: int, vb: int, a: FloatArray, b: FloatArray) -> FloatArray:
        """(m, 3) geodesic polyline from vertex ``va`` to vertex ``vb`` (potpourri3d)."""
        key = (va, vb)
        hit = self._cache.get(key)
        if hit is not None:
            return hit
        try:
            path = np.asarray(self._solver.find_geodesic_path(va, vb), dtype=np.float64)
        except Exception as exc:  # RuntimeError from geometry-central
            raise GeodesicError(
                f"no geodesic on {self._name} from {a.tolist()} to {b.tolist()}: {one_line(exc)}"
            ) from exc
        path = path.reshape(-1, 3)
        path.flags.writeable = False
        if len(self._cache) >= _CACHE_SIZE:
            self._cache.pop(next(iter(self._cache)))
        self._cache[key] = path
        return path

    def _dedupe(self, pts: FloatArray) -> FloatArray:
        keep = np.ones(len(pts), dtype=bool)
        keep[1:] = np.linalg.norm(np.diff(pts, axis=0), axis=1) > self._eps
        out = pts[keep]
        if len(out) > 1 and np.linalg.norm(out[-1] - pts[-1]) > 0.0:
            out[-1] = pts[-1]  # keep the exact end point
        return out

    def _triangles(self, pts: FloatArray, tri_b: int) -> IntArray:
        """(k,) triangle of each polyline point: the one its outgoing segment crosses.

        A segment of the polyline lies in one triangle (the solver's points
        are where it crosses edges), so its midpoint's closest triangle is it.
        """
        tris = np.empty(len(pts), dtype=np.int64)
        tris[-1] = tri_b
        if len(pts) > 1:
            seg_tri, _, _ = self.mesh.contact_params(0.5 * (pts[:-1] + pts[1:]))
            tris[:-1] = np.atleast_1d(seg_tri)
        return tris


def _mesh_name(mesh: Mesh) -> str:
    if mesh.path is not None:
        return f"mesh {str(mesh.path)!r}"
    return f"mesh ({len(mesh.vertices)} vertices, {len(mesh.faces)} faces, built from arrays)"


_SOLVERS: dict[int, tuple[weakref.ref[Mesh], MeshGeodesics | GeodesicError]] = {}


def _forget_solver(key: int) -> Callable[[weakref.ref[Mesh]], None]:
    """The weakref callback dropping ``key``'s solver when its mesh is collected.

    Only its own entry: a new mesh may reuse the id before the callback runs.
    At interpreter exit the module's globals may already be gone (None).
    """

    def forget(ref: weakref.ref[Mesh]) -> None:
        solvers = _SOLVERS
        if solvers is not None and key in solvers and solvers[key][0] is ref:
            del solvers[key]

    return forget


def surface_geodesics(mesh: Mesh) -> MeshGeodesics:
    """The geodesic solver of ``mesh``, built on first use and cached while the mesh lives.

    Raises:
        GeodesicError: potpourri3d cannot use the mesh (raised again on every
            call; the failure is cached too).
    """
    key = id(mesh)
    entry = _SOLVERS.get(key)
    if entry is None or entry[0]() is not mesh:
        try:
            value: MeshGeodesics | GeodesicError = MeshGeodesics(mesh)
        except GeodesicError as exc:
            value = exc
        _SOLVERS[key] = (weakref.ref(mesh, _forget_solver(key)), value)
        entry = _SOLVERS[key]
    value = entry[1]
    if isinstance(value, GeodesicError):
        raise GeodesicError(str(value))
    return value
