"""Generate the two mesh objects of the scenario suite (dexplan/data/scenarios/suite/).

- ``egg.obj``: a convex egg about 8 x 6.4 x 6.4 cm, an icosphere (subdivision
  4, 5120 triangles) stretched along x with one end blunter than the other.
- ``bean.obj``: a non-convex bean about 8.4 cm long, an icosphere (subdivision
  4, 5120 triangles) whose radius has a waist around x = 0 (concave there)
  and a slight bend.

Both are closed, consistently oriented, in metres, centred at their centre of
mass. Run from the repository root::

    python scripts/make_suite_meshes.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

OUT = Path("dexplan/data/meshes")


def _radial(subdivisions: int, radius_of: object) -> trimesh.Trimesh:
    """A star-shaped mesh: an icosphere's directions ``d`` scaled by ``radius_of(d)``."""
    sphere = trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)
    d = sphere.vertices / np.linalg.norm(sphere.vertices, axis=1, keepdims=True)
    mesh = trimesh.Trimesh(d * radius_of(d)[:, None], sphere.faces, process=True)  # type: ignore[operator]
    mesh.apply_translation(-mesh.center_mass)
    trimesh.repair.fix_normals(mesh)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0
    return mesh


def egg() -> trimesh.Trimesh:
    """The convex egg."""
    mesh = _radial(4, lambda d: np.full(len(d), 1.0))
    mesh.vertices *= np.array([0.040, 0.032, 0.032])
    x = mesh.vertices[:, 0]
    mesh.vertices[:, 1:] *= (1.0 + 0.12 * x / 0.04)[:, None]  # one end blunter
    mesh.apply_translation(-mesh.center_mass)
    assert mesh.is_convex
    return mesh


def bean() -> trimesh.Trimesh:
    """The non-convex bean (a waist at x = 0)."""

    def radius(d: np.ndarray) -> np.ndarray:
        x, _, z = d.T
        return 0.03 * (1.0 + 0.4 * (2.0 * x * x - 1.0)) * (1.0 + 0.06 * z) + 0.004 * z * x * x

    mesh = _radial(4, radius)
    assert not mesh.is_convex
    return mesh


def main() -> None:
    """Write both OBJ files and print their sizes."""
    OUT.mkdir(parents=True, exist_ok=True)
    for name, mesh in (("egg", egg()), ("bean", bean())):
        path = OUT / f"{name}.obj"
        path.write_text(
            trimesh.exchange.obj.export_obj(mesh, include_normals=False, digits=9),
            encoding="utf-8",
        )
        ext = mesh.bounds[1] - mesh.bounds[0]
        print(f"{path}: {len(mesh.faces)} triangles, extents {np.round(ext * 1000, 1)} mm")


if __name__ == "__main__":
    main()
