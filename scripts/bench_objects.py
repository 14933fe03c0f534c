"""Micro-benchmark of dexplan.model.objects queries (single point, object frame).

Prints the median microseconds per call of ``signed_distance_and_gradient`` for
one (3,) point on each primitive and on icosphere meshes (1280 and 81920
triangles, plus 327680 with ``--large``), and of ``closest_point`` and
``contact_params`` on the meshes. Query points are drawn in a shell around the
surface (where fingertips are), plus a line for deep-inside points.

Usage: python scripts/bench_objects.py [--calls N] [--large]
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from dexplan.model.objects import Box, Capsule, Cylinder, Mesh, Shape, Sphere


def call_times(fn: Callable[[np.ndarray], object], points: np.ndarray) -> np.ndarray:
    """(N,) the time of one call per point, in seconds."""
    times = np.empty(len(points))
    for i, p in enumerate(points):
        t0 = time.perf_counter()
        fn(p)
        times[i] = time.perf_counter() - t0
    return times


def median_us(fn: Callable[[np.ndarray], object], points: np.ndarray) -> float:
    """Median over points of the time of one call, in microseconds."""
    return float(np.median(call_times(fn, points)) * 1e6)


def shell_points(shape: Shape, n: int, rng: np.random.Generator, spread: float) -> np.ndarray:
    """Points within ``spread * bounding_radius`` of random surface points."""
    pts, normals = shape.sample_surface(n, rng)
    offset = rng.uniform(-spread, spread, size=(n, 1)) * shape.bounding_radius
    return np.ascontiguousarray(pts + offset * normals)


def _shapes(large: bool) -> list[tuple[str, Shape]]:
    """The primitives, then icosphere meshes (their build time printed)."""
    shapes: list[tuple[str, Shape]] = [
        ("sphere", Sphere(0.04)),
        ("box", Box([0.04, 0.06, 0.08])),
        ("capsule", Capsule(0.02, 0.05)),
        ("cylinder", Cylinder(0.02, 0.05)),
    ]
    subdivisions = [3, 6] + ([7] if large else [])
    for sub in subdivisions:
        ico = trimesh.creation.icosphere(subdivisions=sub, radius=0.05)
        t0 = time.perf_counter()
        mesh = Mesh(ico.vertices, ico.faces)
        mesh.to_coal()
        build = time.perf_counter() - t0
        print(f"mesh_{len(ico.faces)}: build (validation, pseudo-normals, BVH) {build:.3f} s")
        shapes.append((f"mesh_{len(ico.faces)}", mesh))
    return shapes


def _near_surface_table(shapes: list[tuple[str, Shape]], n: int, rng: np.random.Generator) -> None:
    """Median us per query for points within 10 % of each surface."""
    print(f"\nmedian us per call, single (3,) point, {n} points within 10% of the surface")
    print("(sdf_and_grad x4: one call on a (4, 3) array, as for a 4-finger constraint)")
    head = f"{'shape':<14}{'sdf_and_grad':>14}{'sdf_and_grad x4':>17}"
    print(head + f"{'closest_point':>15}{'contact_params':>16}")
    for name, shape in shapes:
        pts = shell_points(shape, n, rng, 0.1)
        sdf = median_us(shape.signed_distance_and_gradient, pts)
        four = median_us(shape.signed_distance_and_gradient, pts[: n - n % 4].reshape(-1, 4, 3))
        line = f"{name:<14}{sdf:>14.2f}{four:>17.2f}"
        if isinstance(shape, Mesh):
            cp = median_us(shape.closest_point, pts)
            tuv = median_us(shape.contact_params, pts)
            line += f"{cp:>15.2f}{tuv:>16.2f}"
        print(line)


def _mesh_table(shapes: list[tuple[str, Shape]], n: int, rng: np.random.Generator) -> None:
    """Median and 95th percentile us on meshes for points inside, far outside, at the centre."""
    print("\nmeshes, other query points (sdf_and_grad, median / 95th percentile us)")
    for name, shape in shapes:
        if not isinstance(shape, Mesh):
            continue
        for label, pts in (
            ("uniform in ball r=0.05", _ball(rng, n, 0.05)),
            ("outside, 0.10-0.15 m", _shell(rng, n, 0.1, 0.15)),
        ):
            times = call_times(shape.signed_distance_and_gradient, pts)
            med, p95 = np.median(times) * 1e6, np.percentile(times, 95) * 1e6
            print(f"{name:<14}{label:<26}{med:>10.1f}{p95:>10.1f}")
        t0 = time.perf_counter()
        shape.signed_distance_and_gradient(np.zeros(3))
        print(f"{name:<14}{'centre (worst case)':<26}{(time.perf_counter() - t0) * 1e6:>10.1f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=2000, help="query points per line")
    parser.add_argument("--large", action="store_true", help="also a 327680-triangle mesh")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    shapes = _shapes(args.large)
    _near_surface_table(shapes, args.calls, rng)
    _mesh_table(shapes, args.calls, rng)
    batch = shell_points(shapes[-1][1], 1000, rng, 0.1)
    t0 = time.perf_counter()
    shapes[-1][1].signed_distance_and_gradient(batch)
    per = (time.perf_counter() - t0) / len(batch) * 1e6
    print(f"\n{shapes[-1][0]}: batch of 1000 points, {per:.1f} us per point")


def _ball(rng: np.random.Generator, n: int, r: float) -> np.ndarray:
    d = rng.standard_normal((n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return np.ascontiguousarray(d * r * rng.random((n, 1)) ** (1 / 3))


def _shell(rng: np.random.Generator, n: int, r0: float, r1: float) -> np.ndarray:
    d = rng.standard_normal((n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return np.ascontiguousarray(d * rng.uniform(r0, r1, (n, 1)))


if __name__ == "__main__":
    main()
