"""Benchmark the RLG-style GSn sampler: valid samples per second and rejection reasons.

For each scenario, builds the planning context, calls ``GraspSampler.sample()``
(random object poses in the workspace, as PRM does) until ``--seconds`` of
sampling time have passed, and prints one Markdown table row per scenario:
valid samples per second, valid samples per attempt, validity checks and how
they were rejected (``GraspValidity`` counts reasons), IK failures, and the
sampler's own counters.

Run with -j 1 discipline (one process, nothing else heavy on the machine)::

    python scripts/bench_sampler.py                      # paper and Allegro spheres
    python scripts/bench_sampler.py dexplan/data/scenarios/allegro_cube.toml --seconds 20
    python scripts/bench_sampler.py --seconds 8 --seeds 5  # median valid/s over seeds 1-5

With ``--seeds N`` a row gives the median valid samples per second over the
seeds (and their range) and the counts summed over them.

It only uses the public planning context, so it also runs against older
checkouts (``PYTHONPATH=/path/to/old/checkout python scripts/bench_sampler.py``),
which is how the "before" figures in the closing note were taken.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

from dexplan.model.scenario import load_scenario
from dexplan.planning.context import build_context

DEFAULT = ("dexplan/data/scenarios/paper_sphere.toml", "dexplan/data/scenarios/allegro_sphere.toml")


def bench(path: str, seconds: float, seed: int) -> dict[str, object]:
    """Sample for ``seconds`` of sampler time; return the figures."""
    scenario = load_scenario(Path(path))
    ctx = build_context(scenario, seed)
    sampler = ctx.sampler
    t0 = time.perf_counter()
    calls = 0
    while sampler.stats.time_s < seconds and time.perf_counter() - t0 < 3 * seconds:
        sampler.sample()
        calls += 1
    st = sampler.stats
    vs = ctx.validity.stats
    return {
        "scenario": scenario.name,
        "seed": seed,
        "calls": calls,
        "time_s": round(st.time_s, 3),
        "valid": st.valid,
        "attempts": st.attempts,
        "valid_per_s": round(st.samples_per_second, 1),
        "valid_per_attempt": round(st.valid_fraction, 4),
        "validity_checked": vs.checked,
        "validity_valid": vs.valid,
        "valid_per_check": round(vs.valid / vs.checked, 4) if vs.checked else 0.0,
        "rejected": dict(vs.rejected),
        "sampler": st.as_dict(),
    }


def main() -> None:
    """Command-line entry point."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scenarios", nargs="*", default=list(DEFAULT))
    ap.add_argument("--seconds", type=float, default=10.0, help="sampling time per scenario")
    ap.add_argument("--seed", type=int, default=1, help="first seed")
    ap.add_argument(
        "--seeds", type=int, default=1, help="seeds per scenario (--seed, --seed + 1, ...)"
    )
    ap.add_argument("--json", action="store_true", help="print JSON lines instead of a table")
    args = ap.parse_args()
    seeds = range(args.seed, args.seed + args.seeds)
    runs = [[bench(p, args.seconds, s) for s in seeds] for p in args.scenarios]
    if args.json:
        for per_seed in runs:
            for r in per_seed:
                print(json.dumps(r))
        return
    print(
        "| scenario | valid/s (median, range) | valid/attempt | attempts | checks | valid/check "
        "| rejected: joint_limits / collision / force_closure / bounds | IK failures |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for per_seed in runs:
        rates = [float(r["valid_per_s"]) for r in per_seed]  # type: ignore[arg-type]
        rate = f"{statistics.median(rates):.1f}"
        if len(rates) > 1:
            rate += f" ({min(rates):.0f}-{max(rates):.0f})"
        # the counts summed over the seeds
        tot: dict[str, float] = {}
        for r in per_seed:
            rej, sampler = r["rejected"], r["sampler"]
            assert isinstance(rej, dict) and isinstance(sampler, dict)
            for key, val in [*rej.items(), ("ik_failures", sampler.get("ik_failures", 0))]:
                tot[key] = tot.get(key, 0) + val
            for key in ("attempts", "validity_checked", "validity_valid", "valid"):
                tot[key] = tot.get(key, 0) + float(r[key])  # type: ignore[arg-type]
        checks = tot["validity_checked"]
        print(
            f"| {per_seed[0]['scenario']} | {rate} | {tot['valid'] / max(tot['attempts'], 1):.4f} "
            f"| {int(tot['attempts'])} | {int(checks)} "
            f"| {tot['validity_valid'] / max(checks, 1):.4f} "
            f"| {int(tot.get('joint_limits', 0))} / {int(tot.get('collision', 0))} / "
            f"{int(tot.get('force_closure', 0))} / {int(tot.get('bounds', 0))} "
            f"| {int(tot.get('ik_failures', 0))} |"
        )


if __name__ == "__main__":
    main()
