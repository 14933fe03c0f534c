"""Memory of many queries on one loaded roadmap (it should not grow over 1000 queries).

Loads a roadmap, answers N cheap queries (a 3 degree turn of the paper sphere,
answered on the roadmap) one after the other in this process, and prints the
resident set size (and, with --trace, the Python heap from tracemalloc) along
the way, and whether the roadmap grew.

    dexplan roadmap build scenarios/paper_sphere.toml --nodes 16 -o rm.npz
    python scripts/multi_query_memory.py rm.npz [-n 1000] [--trace]
"""

from __future__ import annotations

import argparse
import gc
import math
import time
import tracemalloc
from pathlib import Path

import dexplan

PAPER = Path(dexplan.__file__).resolve().parent / "data" / "scenarios" / "paper_sphere.toml"
REPORT_AT = (10, 50, 100, 200, 500, 1000, 2000, 5000)


def rss_mib() -> float:
    """Resident set size of this process (MiB, from /proc/self/statm)."""
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * 4096 / 2**20


def main() -> int:
    """Run the queries; exit 1 if one is not solved."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("roadmap", help="a paper_sphere roadmap .npz")
    ap.add_argument("-n", type=int, default=1000, help="queries (1000)")
    ap.add_argument("--trace", action="store_true", help="also trace the Python heap (slower)")
    args = ap.parse_args()
    rp = dexplan.RoadmapPlanner.load(PAPER, args.roadmap)
    half = math.radians(3.0) / 2
    goal = [0.0, 0.0, 0.1, 0.0, 0.0, math.sin(half), math.cos(half)]
    if args.trace:
        tracemalloc.start()
    t0, before, solved = time.perf_counter(), rp.roadmap.n_vertices, 0
    for i in range(1, args.n + 1):
        p = rp.query(goal)
        solved += p.solved
        del p
        gc.collect()
        if i in REPORT_AT or i == args.n:
            heap = tracemalloc.get_traced_memory()[0] / 2**20 if args.trace else float("nan")
            print(
                f"after {i}: rss {rss_mib():.1f} MiB, python heap {heap:.2f} MiB, "
                f"vertices {rp.roadmap.n_vertices}, {time.perf_counter() - t0:.0f} s",
                flush=True,
            )
    print(
        f"solved {solved} of {args.n}; roadmap vertices before {before}, after "
        f"{rp.roadmap.n_vertices}"
    )
    return 0 if solved == args.n else 1


if __name__ == "__main__":
    raise SystemExit(main())
