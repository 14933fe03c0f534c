"""Analytic primitive shapes: sphere, box, capsule and cylinder.

All are centred at the object-frame origin. Capsule and cylinder axes are the
object z axis and ``length`` is the length of the cylindrical part (a capsule is
``length + 2 * radius`` long overall). A box ``size`` holds full edge lengths.

Signed distances are exact (Euclidean) everywhere, not bounds.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import coal
import numpy as np

from dexplan.core.errors import InvalidInputError
from dexplan.core.typing import FloatArray, as_positive, as_vector
from dexplan.model.objects.shape import Shape, ShapeKind, check_sample_args, normalize_rows

#: Gradient chosen on the medial axis of capsules and cylinders (the z axis).
_AXIS_FALLBACK = (1.0, 0.0, 0.0)


def _sign(x: FloatArray) -> FloatArray:
    """+1 where ``x >= 0``, -1 elsewhere (no zero, unlike ``np.sign``)."""
    return np.where(x >= 0.0, 1.0, -1.0)


#: Smallest angle (rad) between a sampled edge normal and either face normal
#: (:meth:`Box.sample_edges`).
EDGE_NORMAL_MIN = math.radians(15.0)


class Sphere(Shape):
    """Sphere of radius ``radius`` centred at the origin.

    Args:
        radius: radius (m), finite and > 0.

    Raises:
        InvalidInputError: bad radius.

    """

    kind = ShapeKind.SPHERE

    def __init__(self, radius: float) -> None:
        self._radius = as_positive(radius, "radius")
        self._coal: Any = None

    @property
    def radius(self) -> float:
        """Radius (m)."""
        return self._radius

    def __repr__(self) -> str:
        return f"Sphere(radius={self._radius!r})"

    def __eq__(self, other: object) -> bool:
        return type(other) is Sphere and other._radius == self._radius

    # compared by value: unhashable, as Python makes a class that defines __eq__; the
    # base class declares __hash__ as a method, so mypy wants an ignore here
    __hash__ = None  # type: ignore[assignment]

    def _sdf_grad_xyz(self, x: float, y: float, z: float) -> tuple[float, float, float, float]:
        n = math.sqrt(x * x + y * y + z * z)
        if n == 0.0:  # centre: every surface point is closest
            return -self._radius, 0.0, 0.0, 1.0
        return n - self._radius, x / n, y / n, z / n

    def _sdf_batch(self, p: FloatArray) -> FloatArray:
        return np.sqrt(np.einsum("ij,ij->i", p, p)) - self._radius

    def _sdf_grad_batch(self, p: FloatArray) -> tuple[FloatArray, FloatArray]:
        n = np.sqrt(np.einsum("ij,ij->i", p, p))
        return n - self._radius, normalize_rows(p, (0.0, 0.0, 1.0))

    def _closest_batch(self, p: FloatArray) -> tuple[FloatArray, FloatArray]:
        g = normalize_rows(p, (0.0, 0.0, 1.0))
        return self._radius * g, g

    def _sample(self, n: int, rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
        g = normalize_rows(rng.standard_normal((n, 3)), (0.0, 0.0, 1.0))
        return self._radius * g, g

    @property
    def bounding_radius(self) -> float:
        """Radius (m)."""
        return self._radius

    @property
    def surface_area(self) -> float:
        """``4 pi r^2`` (m^2)."""
        return 4.0 * math.pi * self._radius**2

    @property
    def volume(self) -> float:
        """``4/3 pi r^3`` (m^3)."""
        return 4.0 / 3.0 * math.pi * self._radius**3

    def to_coal(self) -> coal.Sphere:
        """``coal.Sphere(radius)`` (cached)."""
        if self._coal is None:
            self._coal = coal.Sphere(self._radius)
        return self._coal

    def to_dict(self, base_dir: Path | None = None) -> dict[str, Any]:
        """``{"shape": "sphere", "radius": r}``."""
        return {"shape": "sphere", "radius": self._radius}


class Box(Shape):
    """Axis-aligned box centred at the origin.

    Args:
        size: (3,) full edge lengths ``(sx, sy, sz)`` (m), each finite and > 0.

    Raises:
        InvalidInputError: bad size.

    """

    kind = ShapeKind.BOX

    def __init__(self, size: object) -> None:
        s = as_vector(size, "size", 3)
        if not np.all(s > 0.0):
            raise InvalidInputError(f"size must be finite and > 0, got {s.tolist()!r}")
        self._size = s
        self._size.flags.writeable = False
        self._half = s / 2.0
        self._hx, self._hy, self._hz = self._half.tolist()
        self._coal: Any = None

    @property
    def size(self) -> FloatArray:
        """(3,) full edge lengths (m), read-only."""
        return self._size

    def __repr__(self) -> str:
        return f"Box(size={self._size.tolist()!r})"

    def __eq__(self, other: object) -> bool:
        return type(other) is Box and bool(np.array_equal(other._size, self._size))

    # compared by value: unhashable, as Python makes a class that defines __eq__; the
    # base class declares __hash__ as a method, so mypy wants an ignore here
    __hash__ = None  # type: ignore[assignment]

    def _sdf_grad_xyz(self, x: float, y: float, z: float) -> tuple[float, float, float, float]:
        sx = 1.0 if x >= 0.0 else -1.0
        sy = 1.0 if y >= 0.0 else -1.0
        sz = 1.0 if z >= 0.0 else -1.0
        qx = x * sx - self._hx
        qy = y * sy - self._hy
        qz = z * sz - self._hz
        if qx > 0.0 or qy > 0.0 or qz > 0.0:
            ox = qx if qx > 0.0 else 0.0
            oy = qy if qy > 0.0 else 0.0
            oz = qz if qz > 0.0 else 0.0
            d = math.sqrt(ox * ox + oy * oy + oz * oz)
            return d, sx * ox / d, sy * oy / d, sz * oz / d
        if qx >= qy and qx >= qz:
            return qx, sx, 0.0, 0.0
        if qy >= qz:
            return qy, 0.0, sy, 0.0
        return qz, 0.0, 0.0, sz

    def _sdf_batch(self, p: FloatArray) -> FloatArray:
        q = np.abs(p) - self._half
        out = np.maximum(q, 0.0)
        return np.sqrt(np.einsum("ij,ij->i", out, out)) + np.minimum(q.max(axis=1), 0.0)

    def _sdf_grad_batch(self, p: FloatArray) -> tuple[FloatArray, FloatArray]:
        s = _sign(p)
        q = np.abs(p) - self._half
        out = np.maximum(q, 0.0)
        no = np.sqrt(np.einsum("ij,ij->i", out, out))
        outside = no > 0.0
        rows = np.arange(len(p))
        k = np.argmax(q, axis=1)
        g_in = np.zeros_like(p)
        g_in[rows, k] = s[rows, k]
        g_out = s * out / np.where(outside, no, 1.0)[:, None]
        g = np.where(outside[:, None], g_out, g_in)
        d = np.where(outside, no, q[rows, k])
        return d, g

    def _closest_batch(self, p: FloatArray) -> tuple[FloatArray, FloatArray]:
        d, g = self._sdf_grad_batch(p)
        c = np.clip(p, -self._half, self._half)
        inside = np.flatnonzero(d <= 0.0)
        k = np.argmax(np.abs(g[inside]), axis=1)
        c[inside, k] = g[inside, k] * self._half[k]
        return c, g

    def _sample(self, n: int, rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
        sx, sy, sz = self._size.tolist()
        area = np.array([sy * sz, sx * sz, sx * sy])  # faces normal to x, y, z
        cdf = np.cumsum(np.repeat(area, 2))
        face = np.searchsorted(cdf, rng.random(n) * cdf[-1], side="right")
        face = np.minimum(face, 5)
        axis = face // 2
        sign = np.where(face % 2 == 0, 1.0, -1.0)
        pts = (rng.random((n, 3)) - 0.5) * self._size
        rows = np.arange(n)
        pts[rows, axis] = sign * self._half[axis]
        normals = np.zeros((n, 3))
        normals[rows, axis] = sign
        return pts, normals

    def sample_edges(self, n: int, rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
        """Points on the 12 edges (uniform in length), normals between the two faces'.

        The normal makes an angle uniform in [EDGE_NORMAL_MIN, 90 deg -
        EDGE_NORMAL_MIN] with either face normal: far enough from both that
        the plan verifier reads the same normal from the fingertip (a contact
        whose tip centre lies within 1 mm of a face's is read as on that face).
        """
        n = check_sample_args(n, rng)
        along = rng.choice(3, size=n, p=self._size / self._size.sum())  # edge direction
        rows = np.arange(n)
        a = (along + 1) % 3
        b = (along + 2) % 3
        sa = np.where(rng.random(n) < 0.5, 1.0, -1.0)
        sb = np.where(rng.random(n) < 0.5, 1.0, -1.0)
        pts = np.zeros((n, 3))
        pts[rows, along] = (rng.random(n) - 0.5) * self._size[along]
        pts[rows, a] = sa * self._half[a]
        pts[rows, b] = sb * self._half[b]
        theta = rng.uniform(EDGE_NORMAL_MIN, 0.5 * math.pi - EDGE_NORMAL_MIN, n)
        normals = np.zeros((n, 3))
        normals[rows, a] = sa * np.cos(theta)
        normals[rows, b] = sb * np.sin(theta)
        return pts, normals

    def sample_vertices(self, n: int, rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
        """Points at the 8 corners (uniform), normals inside the corner's cone.

        The outward normal at corner ``(sx hx, sy hy, sz hz)`` is any unit
        vector with components of signs ``(sx, sy, sz)``: a fingertip there
        pushes along the direction from the corner to its centre. Each
        normal is drawn uniformly on that octant of the sphere and kept at
        least :data:`EDGE_NORMAL_MIN` from each of the three face planes
        (its component along each face normal is at least sin of it): a
        fingertip whose centre came closer to an edge's or face's region
        would be read on that edge or face by the plan verifier.
        """
        n = check_sample_args(n, rng)
        signs = np.where(rng.random((n, 3)) < 0.5, 1.0, -1.0)
        low = math.sin(EDGE_NORMAL_MIN)
        normals = np.zeros((n, 3))
        todo = np.arange(n)
        # rejection sampling on the octant: about 60 % of the draws are kept
        while len(todo):
            v = np.abs(rng.normal(size=(len(todo), 3)))
            v /= np.linalg.norm(v, axis=1, keepdims=True)
            ok = np.all(v >= low, axis=1)
            normals[todo[ok]] = v[ok]
            todo = todo[~ok]
        return signs * self._half, signs * normals

    @property
    def bounding_radius(self) -> float:
        """Half diagonal ``|size| / 2`` (m)."""
        return float(np.linalg.norm(self._half))

    @property
    def surface_area(self) -> float:
        """``2 (sx sy + sy sz + sz sx)`` (m^2)."""
        sx, sy, sz = self._size.tolist()
        return 2.0 * (sx * sy + sy * sz + sz * sx)

    @property
    def volume(self) -> float:
        """``sx sy sz`` (m^3)."""
        return float(np.prod(self._size))

    def to_coal(self) -> coal.Box:
        """``coal.Box(sx, sy, sz)`` (full edge lengths; cached)."""
        if self._coal is None:
            self._coal = coal.Box(*self._size.tolist())
        return self._coal

    def to_dict(self, base_dir: Path | None = None) -> dict[str, Any]:
        """``{"shape": "box", "size": [sx, sy, sz]}``."""
        return {"shape": "box", "size": self._size.tolist()}


class _AxialShape(Shape):
    """Common part of :class:`Capsule` and :class:`Cylinder` (axis z, centred)."""

    def __init__(self, radius: float, length: float) -> None:
        self._radius = as_positive(radius, "radius")
        self._length = as_positive(length, "length")
        self._a = self._length / 2.0
        self._coal: Any = None

    @property
    def radius(self) -> float:
        """Radius (m)."""
        return self._radius

    @property
    def length(self) -> float:
        """Length of the cylindrical part along z (m)."""
        return self._length

    def __repr__(self) -> str:
        return f"{type(self).__name__}(radius={self._radius!r}, length={self._length!r})"

    def __eq__(self, other: object) -> bool:
        return (
            type(other) is type(self)
            and other._radius == self._radius
            and other._length == self._length
        )

    # compared by value: unhashable, as Python makes a class that defines __eq__; the
    # base class declares __hash__ as a method, so mypy wants an ignore here
    __hash__ = None  # type: ignore[assignment]

    def to_dict(self, base_dir: Path | None = None) -> dict[str, Any]:
        """``{"shape": kind, "radius": r, "length": l}``."""
        return {"shape": self.kind, "radius": self._radius, "length": self._length}


class Capsule(_AxialShape):
    """Capsule: the points within ``radius`` of the z-axis segment ``|z| <= length / 2``.

    Args:
        radius: radius (m), finite and > 0.
        length: length of the cylindrical part (m), finite and > 0; the total
            length is ``length + 2 * radius``.

    Raises:
        InvalidInputError: bad radius or length.

    """

    kind = ShapeKind.CAPSULE

    def _sdf_grad_xyz(self, x: float, y: float, z: float) -> tuple[float, float, float, float]:
        a = self._a
        vz = z - a if z > a else (z + a if z < -a else 0.0)
        n = math.sqrt(x * x + y * y + vz * vz)
        if n == 0.0:
            return -self._radius, *_AXIS_FALLBACK
        return n - self._radius, x / n, y / n, vz / n

    def _axis_offset(self, p: FloatArray) -> FloatArray:
        v = p.copy()
        v[:, 2] -= np.clip(p[:, 2], -self._a, self._a)
        return v

    def _sdf_batch(self, p: FloatArray) -> FloatArray:
        v = self._axis_offset(p)
        return np.sqrt(np.einsum("ij,ij->i", v, v)) - self._radius

    def _sdf_grad_batch(self, p: FloatArray) -> tuple[FloatArray, FloatArray]:
        v = self._axis_offset(p)
        n = np.sqrt(np.einsum("ij,ij->i", v, v))
        return n - self._radius, normalize_rows(v, _AXIS_FALLBACK)

    def _closest_batch(self, p: FloatArray) -> tuple[FloatArray, FloatArray]:
        v = self._axis_offset(p)
        g = normalize_rows(v, _AXIS_FALLBACK)
        return p - v + self._radius * g, g

    def _sample(self, n: int, rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
        r, a = self._radius, self._a
        side_area = 2.0 * math.pi * r * self._length
        on_side = rng.random(n) * (side_area + 4.0 * math.pi * r * r) < side_area
        normals = np.empty((n, 3))
        pts = np.empty((n, 3))
        ns = int(on_side.sum())
        theta = rng.random(ns) * (2.0 * math.pi)
        normals[on_side] = np.column_stack([np.cos(theta), np.sin(theta), np.zeros(ns)])
        pts[on_side] = r * normals[on_side]
        pts[on_side, 2] = (rng.random(ns) * 2.0 - 1.0) * a
        # caps: a uniform point of the whole sphere, each half moved to its end
        g = normalize_rows(rng.standard_normal((n - ns, 3)), (0.0, 0.0, 1.0))
        normals[~on_side] = g
        pts[~on_side] = r * g
        pts[~on_side, 2] += _sign(g[:, 2]) * a
        return pts, normals

    @property
    def bounding_radius(self) -> float:
        """``length / 2 + radius`` (m)."""
        return self._a + self._radius

    @property
    def surface_area(self) -> float:
        """``2 pi r length + 4 pi r^2`` (m^2)."""
        r = self._radius
        return 2.0 * math.pi * r * self._length + 4.0 * math.pi * r * r

    @property
    def volume(self) -> float:
        """``pi r^2 length + 4/3 pi r^3`` (m^3)."""
        r = self._radius
        return math.pi * r * r * self._length + 4.0 / 3.0 * math.pi * r**3

    def to_coal(self) -> coal.Capsule:
        """``coal.Capsule(radius, length)`` (cylindrical-part length; cached)."""
        if self._coal is None:
            self._coal = coal.Capsule(self._radius, self._length)
        return self._coal


class Cylinder(_AxialShape):
    """Solid cylinder of radius ``radius`` spanning ``|z| <= length / 2``.

    Args:
        radius: radius (m), finite and > 0.
        length: full length along z (m), finite and > 0.

    Raises:
        InvalidInputError: bad radius or length.

    """

    kind = ShapeKind.CYLINDER

    def _sdf_grad_xyz(self, x: float, y: float, z: float) -> tuple[float, float, float, float]:
        rho = math.sqrt(x * x + y * y)
        sz = 1.0 if z >= 0.0 else -1.0
        q0 = rho - self._radius
        q1 = z * sz - self._a
        if rho > 0.0:
            ux, uy = x / rho, y / rho
        else:
            ux, uy = _AXIS_FALLBACK[0], _AXIS_FALLBACK[1]
        if q0 > 0.0 or q1 > 0.0:
            w0 = q0 if q0 > 0.0 else 0.0
            w1 = q1 if q1 > 0.0 else 0.0
            d = math.sqrt(w0 * w0 + w1 * w1)
            c0, c1 = w0 / d, w1 / d
            return d, c0 * ux, c0 * uy, c1 * sz
        if q0 > q1:
            return q0, ux, uy, 0.0
        return q1, 0.0, 0.0, sz

    def _sdf_grad_batch(self, p: FloatArray) -> tuple[FloatArray, FloatArray]:
        rho = np.hypot(p[:, 0], p[:, 1])
        sz = _sign(p[:, 2])
        q0 = rho - self._radius
        q1 = np.abs(p[:, 2]) - self._a
        radial = np.zeros_like(p)
        radial[:, :2] = p[:, :2]
        radial = normalize_rows(radial, _AXIS_FALLBACK)
        w0 = np.maximum(q0, 0.0)
        w1 = np.maximum(q1, 0.0)
        no = np.hypot(w0, w1)
        outside = no > 0.0
        safe = np.where(outside, no, 1.0)
        c0 = np.where(outside, w0 / safe, (q0 > q1).astype(float))
        c1 = np.where(outside, w1 / safe, (q0 <= q1).astype(float))
        g = c0[:, None] * radial
        g[:, 2] += c1 * sz
        d = np.where(outside, no, np.maximum(q0, q1))
        return d, g

    def _sample(self, n: int, rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
        r, a = self._radius, self._a
        side_area = 2.0 * math.pi * r * self._length
        on_side = rng.random(n) * (side_area + 2.0 * math.pi * r * r) < side_area
        theta = rng.random(n) * (2.0 * math.pi)
        rho = np.where(on_side, r, r * np.sqrt(rng.random(n)))
        z = rng.random(n) * 2.0 - 1.0
        zc = np.where(on_side, z * a, _sign(z) * a)
        pts = np.column_stack([rho * np.cos(theta), rho * np.sin(theta), zc])
        normals = np.zeros((n, 3))
        normals[on_side, 0] = np.cos(theta[on_side])
        normals[on_side, 1] = np.sin(theta[on_side])
        normals[~on_side, 2] = _sign(z[~on_side])
        return pts, normals

    @property
    def bounding_radius(self) -> float:
        """``hypot(radius, length / 2)`` (m)."""
        return math.hypot(self._radius, self._a)

    @property
    def surface_area(self) -> float:
        """``2 pi r length + 2 pi r^2`` (m^2)."""
        r = self._radius
        return 2.0 * math.pi * r * self._length + 2.0 * math.pi * r * r

    @property
    def volume(self) -> float:
        """``pi r^2 length`` (m^3)."""
        return math.pi * self._radius**2 * self._length

    def to_coal(self) -> coal.Cylinder:
        """``coal.Cylinder(radius, length)`` (cached)."""
        if self._coal is None:
            self._coal = coal.Cylinder(self._radius, self._length)
        return self._coal
