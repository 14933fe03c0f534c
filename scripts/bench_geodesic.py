"""Accuracy and cost of dexplan.model.objects.geodesic on icospheres (radius 4 cm).

Random area-uniform point pairs (seed per mesh); the geodesic's length against
the sphere's great-circle distance, relative to the mean edge length.

Usage: python scripts/bench_geodesic.py [PAIRS (50)]
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np
import trimesh

from dexplan.model.objects import Mesh
from dexplan.model.objects.geodesic import MeshGeodesics

RADIUS = 0.04


def main() -> None:
    pairs = int(sys.argv[1]) if len(sys.argv) > 1 else 50
    print(
        "| subdivisions | triangles | mean edge (mm) | solver build (ms) | path (ms, median) "
        "| error min / median / max (mm) | max error / edge |"
    )
    print("|---|---|---|---|---|---|---|")
    for sub in (2, 3, 4, 5):
        tm = trimesh.creation.icosphere(subdivisions=sub, radius=RADIUS)
        mesh = Mesh(np.asarray(tm.vertices), np.asarray(tm.faces))
        t0 = time.perf_counter()
        geo = MeshGeodesics(mesh)
        build = time.perf_counter() - t0
        t = mesh.vertices[mesh.faces]
        edge = float(np.linalg.norm(t[:, 0] - t[:, 1], axis=1).mean())
        rng = np.random.default_rng(sub)
        errs, times = [], []
        for _ in range(pairs):
            tri, u, v = mesh.sample_surface_params(2, rng)
            a, b = mesh.contact_points(tri, u, v)
            t0 = time.perf_counter()
            length = geo.path(a, b).length
            times.append(time.perf_counter() - t0)
            cos = float(np.clip(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)), -1.0, 1.0))
            errs.append(length - RADIUS * math.acos(cos))
        e = np.array(errs) * 1e3
        print(
            f"| {sub} | {len(mesh.faces)} | {edge * 1e3:.2f} | {build * 1e3:.1f} | "
            f"{np.median(times) * 1e3:.2f} | {e.min():.3f} / {np.median(e):.3f} / {e.max():.3f} "
            f"| {e.max() / (edge * 1e3):.2f} |"
        )


if __name__ == "__main__":
    main()
