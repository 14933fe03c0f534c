"""Search for fingertip-only Allegro grasps of a cube (docs/hands.md: what it can hold).

Builds a probe scenario (builtin Allegro, a cube of the given side, poses
within ``--half-extent`` of (-0.01, 0, 0.09)) and calls the planner's own
GSn sampler (random positions, uniform orientations, per-finger pools) for
``--seconds``; prints the valid grasps found and the validity checker's
rejection counts with the colliding pairs seen most.

    python scripts/search_cube_grasps.py 0.05 --seconds 60 --mu 1.0
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from dexplan.model.scenario import load_scenario
from dexplan.planning.context import build_context
from dexplan.planning.gsn.space import POSE_DIM

PROBE = """
name = "allegro_cube_probe"
[hand]
builtin = "allegro"
[object]
shape = "box"
size = [{s}, {s}, {s}]
[contact]
mu = {mu}
friction_edges = 8
[start]
object_pose_xyzquat = [-0.01, 0.0, 0.09, 0.0, 0.0, 0.0, 1.0]
[goal]
object_pose_xyzquat = [-0.01, 0.0, 0.09, 0.0, 0.0, 0.0, 1.0]
[workspace]
half_extent = [{h}, {h}, {h}]
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("side", type=float, help="cube side (m)")
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--mu", type=float, default=0.8)
    ap.add_argument("--half-extent", type=float, default=0.05)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    text = PROBE.format(s=args.side, mu=args.mu, h=args.half_extent)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "probe.toml"
        path.write_text(text)
        ctx = build_context(load_scenario(path), args.seed)
    sampler, found = ctx.sampler, []
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < args.seconds:
        x = sampler.sample()
        if x is not None:
            found.append(x)
    vs = ctx.validity.stats
    print(f"cube {args.side} m, mu {args.mu}: {len(found)} valid grasps")
    print(f"checked {vs.checked}, rejected {dict(vs.rejected)}")
    print(f"colliding pairs: {vs.top_collision_pairs(5)}")
    for x in found[:5]:
        print("pose", np.round(x[:POSE_DIM], 4).tolist(), "q", np.round(x[POSE_DIM:], 4).tolist())


if __name__ == "__main__":
    main()
