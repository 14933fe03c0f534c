"""Module-1 figures: constraint cost, valid samples per second, rejection reasons.

Run from the repository root:

    python scripts/bench_gsn.py [SCENARIO.toml] [--seconds S]

Prints microseconds per call of the GSn constraint f and J, the RLG sampler's
valid samples per second and valid fraction, and the validity checker's
rejections by reason, for the paper scenario by default.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from dexplan.model.scenario import default_scenario, load_scenario
from dexplan.planning.context import build_context


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario", nargs="?")
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    scenario = default_scenario() if args.scenario is None else load_scenario(args.scenario)
    ctx = build_context(scenario, args.seed)
    xs = [ctx.sampler.sample() for _ in range(50)]
    xs = [x for x in xs if x is not None]
    for name, fn in (("f", ctx.gsn.function), ("J", ctx.gsn.jacobian)):
        per = []
        for _ in range(5):
            t0 = time.perf_counter()
            for k in range(2000):
                x = xs[k % len(xs)].copy()
                x[0] += 1e-12 * k  # defeat the evaluation cache
                fn(x)
            per.append((time.perf_counter() - t0) / 2000 * 1e6)
        print(f"constraint {name}: {statistics.median(per):.1f} us/call")
    ctx = build_context(scenario, args.seed)  # fresh counters
    t0 = time.perf_counter()
    n = 0
    while time.perf_counter() - t0 < args.seconds:
        n += ctx.sampler.sample() is not None
    st = ctx.sampler.stats
    print(
        f"sampler: {n / args.seconds:.0f} valid samples/s, valid fraction "
        f"{st.valid_fraction:.3f} ({st.valid}/{st.attempts} attempts)"
    )
    v = ctx.validity.stats
    print(f"validity: {v.checked} checked, {v.valid} valid, rejected {v.rejected}")
    per_check = args.seconds / v.checked * 1e6 if v.checked else np.nan
    print(f"sampling time per validity check: {per_check:.0f} us (upper bound of one check)")


if __name__ == "__main__":
    main()
