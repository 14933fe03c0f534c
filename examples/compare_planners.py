"""Compare OMPL planners on one scenario: success, median time, regrasps.

Any OMPL geometric planner can explore the grasp subspace GSn; this runs the
paper's experiment with PRM, RRTConnect and KPIECE1 over a few seeds through
``dexplan.plan(..., planner=name, seed=s)`` and prints a small table. The times
are wall-clock seconds on this machine. ``dexplan bench`` does the same at
scale (Planner Arena database, plots).

Run from the repository root::

    python examples/compare_planners.py
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

import dexplan

SCENARIO = Path(__file__).resolve().parent.parent / "scenarios" / "paper_sphere.toml"
PLANNERS = ("PRM", "RRTConnect", "KPIECE1")
SEEDS = (1, 2, 3)
TIME_LIMIT = 20.0  # seconds per query


def main() -> int:
    """Plan with each planner and seed, print one table row per planner."""
    scenario = dexplan.load_scenario(SCENARIO)  # parsed once, planned many times
    print(f"{'planner':12s} {'solved':>7s} {'median s':>9s} {'regrasps':>9s}")
    for name in PLANNERS:
        times, regrasps = [], []
        for seed in SEEDS:
            t0 = time.perf_counter()
            plan = dexplan.plan(scenario, planner=name, seed=seed, time_limit=TIME_LIMIT)
            if plan.solved:
                times.append(time.perf_counter() - t0)
                regrasps.append(sum(seg.kind == "regrasp" for seg in plan.segments))
        median_t = f"{statistics.median(times):9.2f}" if times else f"{'-':>9s}"
        median_r = f"{statistics.median(regrasps):9.1f}" if regrasps else f"{'-':>9s}"
        print(f"{name:12s} {len(times):>3d} / {len(SEEDS)} {median_t} {median_r}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
