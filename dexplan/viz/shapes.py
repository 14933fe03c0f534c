"""Rerun archetypes of shapes: dexplan shapes and a hand's coal geometries."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import coal
import numpy as np
import numpy.typing as npt
import pinocchio as pin
import trimesh

from dexplan.core.errors import InvalidInputError
from dexplan.core.typing import FloatArray
from dexplan.model.objects import Box, Capsule, Cylinder, Mesh, Shape, Sphere
from dexplan.viz.session import rerun_module, rgba

if TYPE_CHECKING:  # rerun's types for annotations; at run time rerun loads on first use
    import rerun
    import rerun.components


def mesh_archetype(
    vertices: FloatArray, faces: npt.ArrayLike, color: Sequence[int]
) -> rerun.Mesh3D:
    """Return a ``rr.Mesh3D`` of a triangle mesh, with vertex normals.

    Args:
        vertices: ``(V, 3)`` vertex positions in the shape's frame.
        faces: ``(F, 3)`` vertex indices of each triangle.
        color: RGBA.
    """
    rr = rerun_module()

    tm = trimesh.Trimesh(np.asarray(vertices, float), np.asarray(faces, int), process=False)
    return rr.Mesh3D(
        vertex_positions=tm.vertices,
        triangle_indices=tm.faces,
        vertex_normals=tm.vertex_normals,
        albedo_factor=rgba(color),
    )


def shape_archetype(
    shape: Shape, color: Sequence[int], *, wireframe: bool = False
) -> rerun.AsComponents:
    """Return a Rerun archetype drawing a dexplan shape in its own frame.

    Raises:
        InvalidInputError: the shape is of no known kind.
    """
    rr = rerun_module()
    fill = rr.components.FillMode.MajorWireframe if wireframe else rr.components.FillMode.Solid
    c = [rgba(color)]
    if isinstance(shape, Sphere):
        return rr.Ellipsoids3D(half_sizes=[[shape.radius] * 3], colors=c, fill_mode=fill)
    if isinstance(shape, Box):
        return rr.Boxes3D(sizes=[np.asarray(shape.size)], colors=c, fill_mode=fill)
    if isinstance(shape, Capsule):
        return _capsule(shape.length, shape.radius, c, fill)
    if isinstance(shape, Cylinder):
        return rr.Cylinders3D(
            lengths=[shape.length], radii=[shape.radius], colors=c, fill_mode=fill
        )
    if isinstance(shape, Mesh):
        if wireframe:
            return _light_mesh_outline(shape, color)
        return mesh_archetype(shape.vertices, shape.faces, color)
    raise InvalidInputError(f"cannot draw shape {shape!r}")


# A mesh drawn "lightly" (a goal pose): every edge up to this many faces,
# else this many surface points, so that the object seen through it stays visible.
_OUTLINE_MAX_FACES = 400
_OUTLINE_POINTS = 500


def _light_mesh_outline(shape: Mesh, color: Sequence[int]) -> rerun.AsComponents:
    """A light drawing of a mesh: its edges when few, else a sparse point cloud."""
    rr = rerun_module()
    faces = np.asarray(shape.faces)
    if len(faces) <= _OUTLINE_MAX_FACES:
        edges = shape.vertices[faces[:, [0, 1, 2, 0]]]
        return rr.LineStrips3D(edges, colors=[rgba(color)], radii=[0.0003])
    verts = np.asarray(shape.vertices, dtype=float)
    step = max(1, len(verts) // _OUTLINE_POINTS)
    faint = [*rgba(color)[:3], 150]
    return rr.Points3D(verts[::step], colors=[faint], radii=[0.0008])


def _capsule(
    length: float, radius: float, colors: list[list[int]], fill: rerun.components.FillMode
) -> rerun.Capsules3D:
    """A capsule centred on its frame (rerun's start at the origin and extend along +z)."""
    rr = rerun_module()
    return rr.Capsules3D(
        lengths=[length],
        radii=[radius],
        translations=[[0.0, 0.0, -length / 2]],
        colors=colors,
        fill_mode=fill,
    )


def coal_archetype(geom: pin.GeometryObject, color: Sequence[int]) -> rerun.AsComponents | None:
    """Return a Rerun archetype for a Pinocchio geometry object's coal shape (own frame).

    Returns:
        The archetype, or None for a geometry that cannot be drawn.
    """
    rr = rerun_module()
    g = geom.geometry
    c = [rgba(color)]
    solid = rr.components.FillMode.Solid
    if isinstance(g, coal.Box):
        return rr.Boxes3D(half_sizes=[np.asarray(g.halfSide)], colors=c, fill_mode=solid)
    if isinstance(g, coal.Sphere):
        return rr.Ellipsoids3D(half_sizes=[[g.radius] * 3], colors=c, fill_mode=solid)
    if isinstance(g, coal.Ellipsoid):
        return rr.Ellipsoids3D(half_sizes=[np.asarray(g.radii)], colors=c, fill_mode=solid)
    if isinstance(g, coal.Cylinder):
        return rr.Cylinders3D(
            lengths=[2 * g.halfLength], radii=[g.radius], colors=c, fill_mode=solid
        )
    if isinstance(g, coal.Capsule):
        return _capsule(2 * g.halfLength, g.radius, c, solid)
    return _coal_mesh_archetype(geom, color)


def _coal_mesh_archetype(geom: pin.GeometryObject, color: Sequence[int]) -> rerun.Mesh3D | None:
    """A mesh geometry: its coal triangles, else the mesh file it was loaded from."""
    g = geom.geometry
    if hasattr(g, "num_tris") and hasattr(g, "tri_indices"):
        n_t = int(g.num_tris)
        verts = np.asarray(g.vertices(), dtype=float)
        if n_t and len(verts):
            faces = np.array([[t[0], t[1], t[2]] for t in (g.tri_indices(i) for i in range(n_t))])
            return mesh_archetype(verts, faces, color)
    mesh_path = getattr(geom, "meshPath", "")
    if mesh_path and Path(mesh_path).is_file():
        try:
            tm = trimesh.load(mesh_path, force="mesh")
        except (ValueError, OSError):
            return None
        if not isinstance(tm, trimesh.Trimesh):  # a file holding no triangles
            return None
        return mesh_archetype(tm.vertices * np.asarray(geom.meshScale), tm.faces, color)
    return None
