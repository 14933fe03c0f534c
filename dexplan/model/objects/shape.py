"""The :class:`Shape` base class: signed distance, closest points and sampling.

Every query takes points in the **object frame** (the shape is fixed there) and
returns results in that frame. The signed distance is negative inside the
object; its gradient is the outward unit normal of the closest surface point,
well defined away from the medial axis (where the closest surface point is not
unique and an arbitrary but deterministic choice is made).

Input conventions shared by every query method:

- a single point ``(3,)`` (NumPy array, list or tuple) gives scalar-shaped
  results: a ``float`` distance and ``(3,)`` vectors. A ``(3,)`` NumPy array
  takes a fast path written for the planner's constraint function (one call per
  finger, thousands of calls a second);
- ``(N, 3)`` points give ``(N,)`` distances and ``(N, 3)`` vectors.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from enum import StrEnum
from pathlib import Path
from typing import Any, cast

import numpy as np
import numpy.typing as npt

from dexplan.core.errors import InvalidInputError
from dexplan.core.typing import FloatArray, as_points

#: Up to this many points, queries loop over the scalar fast path (cheaper than
#: the vectorized code's fixed cost); above it they run vectorized.
SCALAR_LOOP_MAX = 16


def _single_xyz(p_obj: object) -> tuple[float, float, float] | None:
    """Return ``(x, y, z)`` floats if ``p_obj`` is a finite ``(3,)`` float array, else None.

    Raises:
        InvalidInputError: a ``(3,)`` array with a NaN or infinite entry.

    """
    if type(p_obj) is np.ndarray and p_obj.shape == (3,) and p_obj.dtype == np.float64:
        x, y, z = p_obj.tolist()
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
            raise InvalidInputError(f"p_obj must be finite, got {[x, y, z]!r}")
        return x, y, z
    return None


def query_points(p_obj: object) -> tuple[FloatArray, bool]:
    """Validate query points.

    Args:
        p_obj: (3,) or (N, 3) points in the object frame.

    Returns:
        ``(points, single)``: (N, 3) float64 points and whether the input was a
        single ``(3,)`` point.

    Raises:
        InvalidInputError: wrong shape or a non-finite coordinate.

    """
    single = np.ndim(cast("npt.ArrayLike", p_obj)) == 1
    return as_points(p_obj, "p_obj"), single


def check_sample_args(n: object, rng: object) -> int:
    """Validate the arguments of :meth:`Shape.sample_surface` and return ``n``.

    Raises:
        InvalidInputError: ``n`` not a non-negative integer or ``rng`` not a
            ``numpy.random.Generator``.

    """
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 0:
        raise InvalidInputError(f"n must be an integer >= 0, got {n!r}")
    if not isinstance(rng, np.random.Generator):
        raise InvalidInputError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    return int(n)


def normalize_rows(v: FloatArray, fallback: tuple[float, float, float]) -> FloatArray:
    """Return the rows of ``v: (N, 3)`` scaled to unit length.

    Zero rows become ``fallback`` (a deterministic choice on the medial axis).
    """
    n = np.sqrt(np.einsum("ij,ij->i", v, v))
    if n.all():
        return v / n[:, None]
    out = np.empty_like(v)
    ok = n > 0.0
    out[ok] = v[ok] / n[ok, None]
    out[~ok] = fallback
    return out


class ShapeKind(StrEnum):
    """Shape names of the ``shape`` field (members equal their strings, as files hold them)."""

    SPHERE = "sphere"
    BOX = "box"
    CAPSULE = "capsule"
    CYLINDER = "cylinder"
    MESH = "mesh"


class Shape(ABC):
    """A rigid closed object described in its own frame (the object frame).

    Subclasses implement the batch queries ``_sdf_grad_batch`` and
    ``_sample``, and usually the scalar fast path ``_sdf_grad_xyz``.
    """

    #: Name of the shape in scenario and plan files (``{"shape": kind, ...}``);
    #: every concrete shape sets its own.
    kind: ShapeKind

    # ----------------------------------------------------------- subclass hooks
    @abstractmethod
    def _sdf_grad_batch(self, p: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Signed distance (N,) and gradient (N, 3) of validated (N, 3) points."""

    def _sdf_batch(self, p: FloatArray) -> FloatArray:
        """Signed distance (N,) of validated (N, 3) points."""
        return self._sdf_grad_batch(p)[0]

    def _sdf_grad_xyz(self, x: float, y: float, z: float) -> tuple[float, float, float, float]:
        """Scalar fast path: ``(d, gx, gy, gz)`` of one point."""
        d, g = self._sdf_grad_batch(np.array([[x, y, z]]))
        gx, gy, gz = g[0].tolist()
        return float(d[0]), gx, gy, gz

    def _closest_batch(self, p: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Closest surface points (N, 3) and outward normals (N, 3) of (N, 3) points."""
        d, g = self._sdf_grad_batch(p)
        return p - d[:, None] * g, g

    def _closest_xyz(
        self, x: float, y: float, z: float
    ) -> tuple[float, float, float, float, float, float]:
        """Scalar fast path: closest point ``(qx, qy, qz)`` and normal ``(nx, ny, nz)``."""
        d, gx, gy, gz = self._sdf_grad_xyz(x, y, z)
        return x - d * gx, y - d * gy, z - d * gz, gx, gy, gz

    @abstractmethod
    def _sample(self, n: int, rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
        """Area-uniform surface samples: points (n, 3) and outward normals (n, 3)."""

    # ------------------------------------------------------------ public API
    def signed_distance(self, p_obj: object) -> FloatArray | float:
        """Signed distance from points to the surface (negative inside).

        Args:
            p_obj: (3,) or (N, 3) points in the object frame.

        Returns:
            A float for a single (3,) point, else (N,) distances (m).

        Raises:
            InvalidInputError: wrong shape or a non-finite coordinate.

        """
        xyz = _single_xyz(p_obj)
        if xyz is not None:
            return self._sdf_grad_xyz(*xyz)[0]
        p, single = query_points(p_obj)
        if single:
            return self._sdf_grad_xyz(*p[0].tolist())[0]
        if len(p) <= SCALAR_LOOP_MAX:
            f = self._sdf_grad_xyz
            return np.array([f(x, y, z)[0] for x, y, z in p.tolist()], dtype=np.float64)
        return self._sdf_batch(p)

    def signed_distance_and_gradient(self, p_obj: object) -> tuple[FloatArray | float, FloatArray]:
        """Signed distance and its gradient (the outward normal of the closest point).

        The gradient is a unit vector. It is the exact gradient of the signed
        distance wherever that is differentiable (everywhere but the medial axis,
        and for meshes the surface itself at edges and vertices); on the medial
        axis one of the closest surface points is chosen deterministically.

        Args:
            p_obj: (3,) or (N, 3) points in the object frame.

        Returns:
            ``(d, grad)``: a float and a (3,) array for a single (3,) point, else
            (N,) distances and (N, 3) unit gradients, object frame.

        Raises:
            InvalidInputError: wrong shape or a non-finite coordinate.

        """
        xyz = _single_xyz(p_obj)
        if xyz is not None:
            d, gx, gy, gz = self._sdf_grad_xyz(*xyz)
            return d, np.array((gx, gy, gz))
        p, single = query_points(p_obj)
        if single:
            d, gx, gy, gz = self._sdf_grad_xyz(*p[0].tolist())
            return d, np.array((gx, gy, gz))
        if len(p) <= SCALAR_LOOP_MAX:
            f = self._sdf_grad_xyz
            rows = np.array([f(x, y, z) for x, y, z in p.tolist()], dtype=np.float64)
            rows = rows.reshape(len(p), 4)
            return rows[:, 0].copy(), rows[:, 1:].copy()
        return self._sdf_grad_batch(p)

    def closest_point(self, p_obj: object) -> tuple[FloatArray, FloatArray]:
        """Closest surface points and the outward unit normals there.

        The normal is the signed-distance gradient at the query point: the face
        normal when the closest point lies inside a face; at an edge or corner,
        the direction from the closest point to an outside query point (away from
        an inside one), which lies in the cone of normals there.

        Args:
            p_obj: (3,) or (N, 3) points in the object frame.

        Returns:
            ``(points, normals_out)``: (3,) each for a single (3,) point, else
            (N, 3) each, object frame.

        Raises:
            InvalidInputError: wrong shape or a non-finite coordinate.

        """
        xyz = _single_xyz(p_obj)
        if xyz is not None:
            r = self._closest_xyz(*xyz)
            return np.array(r[:3]), np.array(r[3:])
        p, single = query_points(p_obj)
        if len(p) <= SCALAR_LOOP_MAX:
            f = self._closest_xyz
            rows = np.array([f(x, y, z) for x, y, z in p.tolist()], dtype=np.float64)
            rows = rows.reshape(len(p), 6)
            c, n = rows[:, :3].copy(), rows[:, 3:].copy()
        else:
            c, n = self._closest_batch(p)
        if single:
            return c[0], n[0]
        return c, n

    def sample_surface(self, n: int, rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
        """Sample points uniformly with respect to surface area.

        Args:
            n: number of samples (>= 0).
            rng: random generator (the only source of randomness).

        Returns:
            ``(points, normals_out)``: (n, 3) surface points and (n, 3) outward
            unit normals, object frame.

        Raises:
            InvalidInputError: bad ``n`` or ``rng``.

        """
        n = check_sample_args(n, rng)
        return self._sample(n, rng)

    def sample_contacts(
        self, n: int, rng: np.random.Generator, edges: int = 0, vertices: int = 0
    ) -> tuple[FloatArray, FloatArray]:
        """Fingertip contact candidates: surface, edge and vertex points.

        ``n`` points of :meth:`sample_surface`, ``edges`` of
        :meth:`sample_edges` and ``vertices`` of :meth:`sample_vertices`
        (none on shapes without them), shuffled together: callers that take
        the first candidates that work (the landing search, the GSn sampler's
        per-finger pools) then see every kind. A fingertip on an edge pushes
        along any direction between the faces' normals, one on a vertex along
        any direction inside the cone of the faces that meet there, which no
        face point offers.

        Args:
            n: surface points (>= 0).
            rng: random generator (the only source of randomness).
            edges: edge points (>= 0).
            vertices: vertex points (>= 0); 0 draws nothing from ``rng`` for
                them, so the other candidates are those drawn without.

        Returns:
            ``(points, normals_out)``: (m, 3) each, object frame; m = n plus
            the edge and vertex points of shapes that have them.

        Raises:
            InvalidInputError: bad ``n``, ``edges``, ``vertices`` or ``rng``.
        """
        pts, nrm = self.sample_surface(n, rng)
        e_pts, e_nrm = self.sample_edges(edges, rng)
        if vertices:
            v_pts, v_nrm = self.sample_vertices(vertices, rng)
            e_pts, e_nrm = np.vstack([e_pts, v_pts]), np.vstack([e_nrm, v_nrm])
        if len(e_pts) == 0:
            return pts, nrm
        order = rng.permutation(len(pts) + len(e_pts))
        return np.vstack([pts, e_pts])[order], np.vstack([nrm, e_nrm])[order]

    def sample_edges(self, n: int, rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
        """Points on the shape's edges, with outward normals inside their cones.

        A fingertip sphere on an edge pushes along any direction between the
        normals of the faces that meet there; such contacts are landings no
        face point offers (on a box held on two opposite faces, the way onto
        a third one). :class:`~dexplan.model.objects.primitives.Box` samples its
        12 edges, :class:`~dexplan.model.objects.mesh.Mesh` its sharp convex
        edges (none on a smooth mesh); the others (a cylinder's rims too)
        return empty arrays, and ``n == 0`` or no edges leaves ``rng`` untouched.

        Args:
            n: number of samples (>= 0).
            rng: random generator.

        Returns:
            ``(points, normals_out)``: (m, 3) each, object frame (m = n on
            shapes with edges, else 0).
        """
        check_sample_args(n, rng)
        return np.zeros((0, 3)), np.zeros((0, 3))

    def sample_vertices(self, n: int, rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
        """Points at the shape's vertices, with outward normals inside their cones.

        A fingertip sphere on a vertex (a box corner) pushes along any
        direction inside the cone spanned by the normals of the faces that
        meet there: the direction from the vertex to the fingertip centre.
        :class:`~dexplan.model.objects.primitives.Box` samples its 8 corners,
        :class:`~dexplan.model.objects.mesh.Mesh` its sharp convex vertices
        (none on a smooth mesh); the others return empty arrays, and
        ``n == 0`` or no vertices leaves ``rng`` untouched.

        Args:
            n: number of samples (>= 0).
            rng: random generator.

        Returns:
            ``(points, normals_out)``: (m, 3) each, object frame (m = n on
            shapes with vertices, else 0).
        """
        check_sample_args(n, rng)
        return np.zeros((0, 3)), np.zeros((0, 3))

    @property
    @abstractmethod
    def bounding_radius(self) -> float:
        """Largest distance from the object-frame origin to the surface (m)."""

    @property
    def characteristic_length(self) -> float:
        """Length (m) that scales torques into force units in force closure.

        It is :attr:`bounding_radius`, the radius of the smallest ball centred
        at the object-frame origin that contains the object: every contact
        satisfies ``|p x f| <= characteristic_length * |f|``, so torques divided
        by it are commensurate with forces. Sphere: the radius; box: the half
        diagonal; capsule: ``length / 2 + radius``; cylinder:
        ``hypot(radius, length / 2)``; mesh: the largest vertex distance from the
        origin.
        """
        return self.bounding_radius

    @property
    @abstractmethod
    def surface_area(self) -> float:
        """Surface area (m^2)."""

    @property
    @abstractmethod
    def volume(self) -> float:
        """Enclosed volume (m^3)."""

    @abstractmethod
    def to_coal(self) -> Any:
        """Return the coal collision geometry of this shape in the object frame (cached)."""

    @abstractmethod
    def to_dict(self, base_dir: Path | None = None) -> dict[str, Any]:
        """Serialise to the scenario/plan-file object schema.

        Args:
            base_dir: directory that relative mesh paths are written relative to
                (meshes only; None writes an absolute path).

        Returns:
            e.g. ``{"shape": "sphere", "radius": 0.04}``; read back with
            :func:`dexplan.model.objects.shape_from_dict`.

        """
