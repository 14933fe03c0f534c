"""Generate dexplan/data/meshes/pebble.obj, the mesh object of allegro_mesh.toml.

A smooth, slightly irregular pebble about the size of the Allegro sphere
(radius 6 cm): an icosphere (subdivision 4, 5120 triangles) whose radius
varies with direction by a few low-order harmonics, flattened a little along
z. It stays convex enough that fingertips find force-closure grasps all round
it, and irregular enough that the planner cannot treat it as a sphere.

Run from the repository root::

    python scripts/make_allegro_mesh.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

OUT = Path("dexplan/data/meshes/pebble.obj")


def pebble() -> trimesh.Trimesh:
    """The pebble mesh (metres, centred at the origin, outward normals)."""
    mesh = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    d = mesh.vertices / np.linalg.norm(mesh.vertices, axis=1, keepdims=True)
    x, y, z = d.T
    r = (
        0.058
        * (1.0 + 0.05 * (x * x - y * y) + 0.03 * x * y * z * 4.0 + 0.03 * x)
        * (1.0 - 0.08 * z * z)
    )
    mesh = trimesh.Trimesh(d * r[:, None], mesh.faces, process=True)
    mesh.apply_translation(-mesh.center_mass)
    trimesh.repair.fix_normals(mesh)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0
    return mesh


def main() -> None:
    """Write the OBJ file and print its size."""
    mesh = pebble()
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(trimesh.exchange.obj.export_obj(mesh, include_normals=False), encoding="utf-8")
    ext = mesh.bounds[1] - mesh.bounds[0]
    print(f"{OUT}: {len(mesh.faces)} triangles, extents {np.round(ext * 1000, 1)} mm")


if __name__ == "__main__":
    main()
