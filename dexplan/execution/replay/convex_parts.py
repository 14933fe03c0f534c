"""Convex parts of a mesh for the physics replay: MuJoCo collides a mesh as its convex hull.

A MuJoCo mesh geom collides as the convex hull of its vertices, so a concave
object (the suite's bean, with its waist) would be replayed as a fuller body
than the plan's: the fingertips planned in the waist touch the hull instead,
millimetres off. :func:`convex_parts` splits a concave mesh into nearly convex
parts with CoACD (approximate convex decomposition, Wei et al., SIGGRAPH 2022;
the ``coacd`` package of the ``sim`` extra); the replay builds the object from
one geom per part (:mod:`dexplan.execution.replay.mjcf`). The parts' hulls
stay within :data:`CONCAVITY` (relative to the mesh's size, CoACD's own
measure) of the mesh; tests/test_replay_convex_parts.py states the distance
in millimetres for a concave test mesh. A convex mesh is its own single part.

The parts change the shape, not the body: :func:`mass_properties` gives the
mass distribution of the mesh itself (uniform density, trimesh's exact
polyhedral integrals), which the replay sets on the object's body.

CoACD runs with a fixed seed: the same mesh gives the same parts, twice in a
process and in a fresh one (the suite's bean: byte for byte).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import trimesh

from dexplan.core.errors import DependencyError
from dexplan.core.typing import FloatArray, IntArray

__all__ = [
    "CONCAVITY",
    "ConvexPart",
    "MassProperties",
    "convex_parts",
    "mass_properties",
]

#: CoACD's concavity threshold (a fraction of the mesh's size): parts whose hulls
#: stray farther from the mesh are split again. 0.05 is CoACD's default; on the
#: suite's bean it gives two parts within 0.4 mm of its surface.
CONCAVITY = 0.05
#: Fixed seed of CoACD's tree search: the same mesh gives the same parts.
SEED = 0
_PIP = "pip install 'dexplan[sim]' (or: pip install coacd)"


@dataclass(frozen=True)
class ConvexPart:
    """One convex part of a mesh.

    Attributes:
        vertices: (V, 3) the part's vertices, object frame (m).
        faces: (F, 3) vertex indices of its triangles.
    """

    vertices: FloatArray
    faces: IntArray


@dataclass(frozen=True)
class MassProperties:
    """A solid's mass distribution (uniform density).

    Attributes:
        mass: kg.
        center_of_mass: (3,) object frame (m).
        inertia: (3, 3) inertia tensor about the centre of mass, object-frame axes (kg m^2).
    """

    mass: float
    center_of_mass: FloatArray
    inertia: FloatArray


def _require_coacd() -> Any:
    """Import coacd or raise DependencyError naming the pip command."""
    try:
        import coacd
    except ImportError as exc:
        raise DependencyError(f"the replay of a concave mesh needs CoACD: {_PIP}") from exc
    return coacd


def convex_parts(
    vertices: FloatArray, faces: IntArray, *, threshold: float = CONCAVITY
) -> tuple[ConvexPart, ...]:
    """The mesh itself when it is convex, else its approximate convex decomposition.

    Args:
        vertices: (V, 3) a closed mesh's vertices, object frame (m).
        faces: (F, 3) its triangles.
        threshold: CoACD's concavity threshold (a fraction of the mesh's size).

    Returns:
        The parts, each a closed convex mesh (its own hull), object frame.

    Raises:
        DependencyError: the mesh is concave and coacd is not installed.
    """
    tm = trimesh.Trimesh(np.asarray(vertices, dtype=float), np.asarray(faces), process=False)
    if tm.is_convex:
        return (ConvexPart(np.asarray(tm.vertices, dtype=float), np.asarray(tm.faces)),)
    coacd = _require_coacd()
    coacd.set_log_level("error")
    parts = coacd.run_coacd(
        coacd.Mesh(np.asarray(tm.vertices, dtype=float), np.asarray(tm.faces, dtype=np.int64)),
        threshold=threshold,
        seed=SEED,
    )
    out = []
    for v, f in parts:
        hull = trimesh.Trimesh(np.asarray(v, dtype=float), np.asarray(f)).convex_hull
        out.append(ConvexPart(np.asarray(hull.vertices, dtype=float), np.asarray(hull.faces)))
    return tuple(out)


def mass_properties(vertices: FloatArray, faces: IntArray, mass: float) -> MassProperties:
    """Mass distribution of a closed mesh of uniform density and total ``mass`` (kg).

    Args:
        vertices: (V, 3) object frame (m).
        faces: (F, 3) its triangles (outward winding).
        mass: total mass (kg).
    """
    tm = trimesh.Trimesh(np.asarray(vertices, dtype=float), np.asarray(faces), process=False)
    tm.density = float(mass) / float(tm.volume)
    return MassProperties(
        mass=float(tm.mass),
        center_of_mass=np.asarray(tm.center_mass, dtype=float),
        inertia=np.asarray(tm.moment_inertia, dtype=float),
    )
