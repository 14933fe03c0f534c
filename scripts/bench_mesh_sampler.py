"""Valid GSn samples per second on meshes of 5k to 330k triangles (how the rate scales).

Builds the paper_sphere task with the ball replaced by a geodesic sphere mesh
of the same radius (5,120, 81,920, 100,820 or 327,680 triangles: the
icosahedron's faces split into 16, 64, 71 or 128 rows, written to a temporary
folder), and runs the planner's own RLG sampler (``GraspSampler.sample()``,
random poses) for ``--seconds`` of sampling time on each, alternating the
meshes ``--rounds`` times in one process; prints a Markdown table (median
valid/s of each mesh and its ratio to the 5k mesh) and each run's figures.

    python scripts/bench_mesh_sampler.py --seconds 10 --rounds 3
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
from pathlib import Path

import numpy as np
import trimesh

from dexplan.model.scenario import load_scenario
from dexplan.planning.context import build_context

ROOT = Path(__file__).resolve().parent.parent
PAPER = ROOT / "dexplan" / "data" / "scenarios" / "paper_sphere.toml"
#: Rows each icosahedron face is split into: 20 f^2 triangles.
COUNTS = {"5k": 16, "82k": 64, "101k": 71, "328k": 128}


def geodesic_sphere(frequency: int, radius: float) -> trimesh.Trimesh:
    """A closed sphere mesh of ``20 frequency^2`` triangles (a geodesic polyhedron).

    trimesh's icospheres come in powers of 4 (81,920 then 327,680 triangles);
    this one takes any frequency, 71 for about 100k triangles.
    """
    ico = trimesh.creation.icosahedron()
    verts, faces = [], []
    f = frequency
    for a, b, c in ico.vertices[ico.faces]:
        index = {}
        for i in range(f + 1):
            for j in range(f + 1 - i):
                index[i, j] = len(verts)
                verts.append(a + (b - a) * i / f + (c - a) * j / f)
        for i in range(f):
            for j in range(f - i):
                faces.append([index[i, j], index[i + 1, j], index[i, j + 1]])
                if j < f - i - 1:
                    faces.append([index[i + 1, j], index[i + 1, j + 1], index[i, j + 1]])
    v = np.asarray(verts)
    v = radius * v / np.linalg.norm(v, axis=1, keepdims=True)
    mesh = trimesh.Trimesh(v, np.asarray(faces), process=True)  # merges the shared vertices
    mesh.fix_normals()
    return mesh


def mesh_scenario(folder: Path, count: int) -> Path:
    """paper_sphere.toml with its 4 cm ball as a geodesic sphere of frequency ``count``."""
    mesh = geodesic_sphere(count, 0.04)
    if not mesh.is_watertight or len(mesh.faces) != 20 * count * count:
        raise SystemExit(f"geodesic sphere of frequency {count} is not a closed mesh")
    obj = folder / f"ball_{count}.obj"
    mesh.export(obj)
    ball = 'shape = "sphere"\nradius = 0.04'
    base = PAPER.read_text()
    if ball not in base:  # else the benchmark would quietly sample the sphere
        raise SystemExit(f"{PAPER}: no {ball!r} to replace with the mesh")
    text = base.replace(ball, f'shape = "mesh"\npath = "{obj.as_posix()}"')
    out = folder / f"paper_mesh_{count}.toml"
    out.write_text(text)
    return out


def rate(path: Path, seconds: float, seed: int) -> tuple[float, int]:
    """Valid samples per second of sampling time, and the mesh's triangle count."""
    ctx = build_context(load_scenario(path), seed)
    sampler = ctx.sampler
    while sampler.stats.time_s < seconds:
        sampler.sample()
    return sampler.stats.samples_per_second, len(ctx.obj.faces)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        paths = {k: mesh_scenario(Path(tmp), c) for k, c in COUNTS.items()}
        runs: dict[str, list[float]] = {k: [] for k in COUNTS}
        faces: dict[str, int] = {}
        for r in range(args.rounds):
            for k in COUNTS:
                v, faces[k] = rate(paths[k], args.seconds, args.seed + r)
                runs[k].append(v)
                print(f"round {r + 1} {k} ({faces[k]} triangles): {v:.1f} valid/s", flush=True)
    med = {k: statistics.median(v) for k, v in runs.items()}
    print("\n| mesh | triangles | valid samples/s (median) | 5k / this |\n|---|---|---|---|")
    for k in COUNTS:
        print(f"| {k} | {faces[k]} | {med[k]:.1f} | {med['5k'] / med[k]:.2f} |")


if __name__ == "__main__":
    main()
