"""Contact trajectories between two grasps along surface geodesics (paper, section VI).

On a triangulated object the paper parameterises a path in GSn between two
grasps by the contacts' trajectories on the surface, found by a geodesic
computation: each contact moves along the surface geodesic from its first to
its second position (a polyline: the surface is polyhedral), while the object
pose interpolates. :class:`ContactPaths` gives those intermediate contacts for
the planner's own interpolation of contacts (the edge-by-edge reduction's
bisection, :mod:`dexplan.planning.local.reduction`).

Only meshes get geodesics. For the primitives (closed-form surfaces) and for
a mesh potpourri3d cannot handle (:class:`~dexplan.core.errors.GeodesicError`:
a non-manifold vertex), :meth:`ContactPaths.between` returns None and the
caller keeps its previous interpolation (projecting interpolated fingertip
positions onto the surface); :attr:`ContactPaths.fallback` then says why.
"""

from __future__ import annotations

import numpy as np

from dexplan.core.errors import GeodesicError
from dexplan.model.objects import Mesh, Shape
from dexplan.model.objects.geodesic import MeshGeodesics, SurfacePath, surface_geodesics
from dexplan.planning.local.transitions import GraspContacts

__all__ = ["ContactPaths"]


class ContactPaths:
    """Geodesic contact interpolation for one object.

    Args:
        obj: the object shape (object frame).

    Attributes:
        fallback: why geodesics are not used (not a mesh, or the mesh's
            :class:`GeodesicError` message), or None when they are.
        calls: geodesic contact interpolations made (per grasp, not per finger).
    """

    def __init__(self, obj: Shape) -> None:
        self._geo: MeshGeodesics | None = None
        self.fallback: str | None = None
        self.calls = 0
        if not isinstance(obj, Mesh):
            self.fallback = f"{obj.kind} is not a mesh"
            return
        try:
            self._geo = surface_geodesics(obj)
        except GeodesicError as exc:
            self.fallback = str(exc)

    @property
    def active(self) -> bool:
        """Whether contacts move along surface geodesics."""
        return self._geo is not None

    def paths(self, ca: GraspContacts, cb: GraspContacts) -> list[SurfacePath] | None:
        """Each finger's surface geodesic from ``ca`` to ``cb`` (object frame).

        None when geodesics are not available (see :attr:`fallback`) or a
        finger's two contacts have no geodesic between them.
        """
        if self._geo is None:
            return None
        try:
            return [self._geo.path(a, b) for a, b in zip(ca.points, cb.points, strict=True)]
        except GeodesicError:
            return None

    def between(self, ca: GraspContacts, cb: GraspContacts, t: float) -> GraspContacts | None:
        """Contacts a fraction ``t`` of the way along each finger's surface geodesic.

        Args:
            ca: contacts at ``t = 0`` (object frame).
            cb: contacts at ``t = 1`` (object frame), same fingers.
            t: arc-length fraction in [0, 1] (clipped).

        Returns:
            The intermediate contacts, each on the surface with the outward
            normal of its triangle (object frame; a finger whose two contacts
            coincide keeps its own), or None when geodesics are not available
            (see :attr:`fallback`) or a finger's two contacts have no geodesic
            between them.
        """
        curves = self.paths(ca, cb)
        if curves is None:
            return None
        pts = np.empty((len(curves), 3))
        nrm = np.empty((len(curves), 3))
        for f, path in enumerate(curves):
            if path.length <= 0.0:  # a finger that stays put keeps its contact
                pts[f], nrm[f] = ca.points[f], ca.normals_out[f]
            else:
                pts[f], _, nrm[f] = path.at(t)
        self.calls += 1
        return GraspContacts(pts, nrm)
