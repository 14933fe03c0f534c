"""Finger gaits against the paper's edge-by-edge reduction, on the same GSn paths.

Run from the repository root:

    python scripts/compare_reductions.py [SCENARIO] [--planner NAME] [--seeds N]

For each seed, plans once per reduction method (``gaits``, ``edges``, ``auto``)
and prints a row per run, then per method: success count, median time,
regrasps and transfers over solved runs. Module 1 is seed-deterministic, so
the three methods reduce the same GSn path for a seed.
"""

from __future__ import annotations

import argparse
import statistics

from dexplan.model.scenario import builtin_scenario_path, default_scenario, load_scenario
from dexplan.planning.planner import REDUCTIONS, plan


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario", nargs="?", help="scenario file or builtin name")
    ap.add_argument("--planner", help="OMPL planner (default: the scenario's)")
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--time-limit", type=float, default=30.0)
    args = ap.parse_args()
    if args.scenario is None:
        scenario = default_scenario()
    elif args.scenario.endswith(".toml"):
        scenario = load_scenario(args.scenario)
    else:
        scenario = load_scenario(builtin_scenario_path(args.scenario))
    methods = ("gaits", "edges", "auto")
    assert set(methods) == set(REDUCTIONS)
    rows: dict[str, list[dict]] = {m: [] for m in methods}
    print("seed method status time_s regrasps transfers")
    for seed in range(1, args.seeds + 1):
        for m in methods:
            r = plan(
                scenario,
                planner=args.planner,
                seed=seed,
                time_limit=args.time_limit,
                reduction=m,
            )
            st = r.stats
            rows[m].append({"solved": r.solved, **st})
            print(
                f"{seed} {m} {r.status} {st['time_s']:.2f} "
                f"{st.get('regrasps', '-')} {st.get('transfers', '-')}",
                flush=True,
            )
    print("\nmethod solved time_median_s regrasps_median transfers_median")
    for m in methods:
        ok = [r for r in rows[m] if r["solved"]]
        med = statistics.median
        t = med(r["time_s"] for r in rows[m])
        reg = med(r["regrasps"] for r in ok) if ok else float("nan")
        tra = med(r["transfers"] for r in ok) if ok else float("nan")
        print(f"{m} {len(ok)}/{len(rows[m])} {t:.2f} {reg} {tra}")


if __name__ == "__main__":
    main()
