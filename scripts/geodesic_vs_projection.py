"""How OMPL's projected interpolation moves the contacts, against surface geodesics.

For every GSn edge of the roadmaps module 1 builds on a mesh scenario, the
edge is densified with OMPL's projected interpolation (what module 1 and the
path re-check use, ``PlanningProblem.interpolate_path``) and each contact
finger's contact trajectory is read off the dense states (closest surface
point of its fingertip centre, object frame). It is compared with the surface
geodesic between the edge's end contacts (``dexplan.model.objects.geodesic``):
length ratio and largest distance of the trajectory from the geodesic
polyline.

Usage: python scripts/geodesic_vs_projection.py SCENARIO.toml [SEEDS (1-3)]
"""

from __future__ import annotations

import sys

import numpy as np

from dexplan.model.objects.geodesic import surface_geodesics
from dexplan.model.scenario import load_scenario
from dexplan.planning.context import build_context
from dexplan.planning.planner import plan
from dexplan.planning.roadmap.queries import query_problem


def _dist_to_polyline(p: np.ndarray, poly: np.ndarray) -> float:
    if len(poly) == 1:
        return float(np.linalg.norm(p - poly[0]))
    a, b = poly[:-1], poly[1:]
    ab = b - a
    t = np.clip(
        np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-30), 0, 1
    )
    return float(np.min(np.linalg.norm(a + t[:, None] * ab - p, axis=1)))


def main() -> None:
    scenario = load_scenario(sys.argv[1])
    lo, hi = (int(v) for v in (sys.argv[2] if len(sys.argv) > 2 else "1-3").split("-"))
    ratios, devs, lengths = [], [], []
    for seed in range(lo, hi + 1):
        res = plan(scenario, seed=seed)
        ctx = build_context(scenario, seed)
        problem = query_problem(ctx)
        geo = surface_geodesics(ctx.obj)
        rm = res.roadmap
        if rm is None:
            continue
        for a, b in rm.edges.tolist():
            dense = problem.interpolate_path(np.stack([rm.vertices[a], rm.vertices[b]]))
            contacts = np.array([ctx.gsn.contacts(x)[0] for x in dense])  # (K, n, 3)
            for f in range(contacts.shape[1]):
                c = contacts[:, f]
                g = geo.path(c[0], c[-1])
                if g.length < 1e-3:  # contact barely moves
                    continue
                walked = float(np.linalg.norm(np.diff(c, axis=0), axis=1).sum())
                ratios.append(walked / g.length)
                lengths.append(g.length)
                devs.append(max(_dist_to_polyline(p, g.points) for p in c))
    r, d, ln = np.array(ratios), np.array(devs) * 1e3, np.array(lengths) * 1e3
    print(f"{scenario.name}: {len(r)} contact trajectories on roadmap edges, seeds {lo}-{hi}")
    print(f"  geodesic length (mm): median {np.median(ln):.1f}, max {ln.max():.1f}")
    for name, v in (("projected / geodesic length", r), ("largest gap to the geodesic (mm)", d)):
        print(
            f"  {name}: median {np.median(v):.3f}, p90 {np.percentile(v, 90):.3f}, "
            f"max {v.max():.3f}"
        )


if __name__ == "__main__":
    main()
