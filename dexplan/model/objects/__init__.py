"""Object shapes in their own frame: primitives, closed meshes, SDF, contacts.

Every shape is a :class:`Shape`: signed distance (negative inside) and its
gradient, closest points, area-uniform surface sampling, a coal geometry, and a
dictionary form for scenario and plan files (:func:`shape_from_dict`). Meshes
also give surface contacts as ``(triangle, u, v)`` parameters and geodesic
paths between surface points (:func:`surface_geodesics`, potpourri3d).

Conventions: all queries are in the object frame; primitives are centred at the
origin; capsule and cylinder axes are z, ``length`` being the cylindrical part;
box ``size`` holds full edge lengths; a mesh keeps its file's origin.
"""

from __future__ import annotations

from dexplan.model.objects.factory import SHAPE_KINDS, file_sha256, shape_from_dict
from dexplan.model.objects.geodesic import MeshGeodesics, SurfacePath, surface_geodesics
from dexplan.model.objects.mesh import BUILTIN_MESH_DIR, UNIT_SCALES, Mesh, unit_scale_hint
from dexplan.model.objects.primitives import Box, Capsule, Cylinder, Sphere
from dexplan.model.objects.shape import Shape, ShapeKind

__all__ = [
    "BUILTIN_MESH_DIR",
    "SHAPE_KINDS",
    "UNIT_SCALES",
    "Box",
    "Capsule",
    "Cylinder",
    "Mesh",
    "MeshGeodesics",
    "Shape",
    "ShapeKind",
    "Sphere",
    "SurfacePath",
    "file_sha256",
    "shape_from_dict",
    "surface_geodesics",
    "unit_scale_hint",
]
