"""Microbenchmark of dexplan.model.grasp: median microseconds per call.

Usage: python scripts/bench_grasp.py [--calls N] [--seed S]

Cases (edges = 8, mu = 0.8, sphere of radius 4 cm, torque scale 4 cm):
  tetra    - 4 well-spread (near-tetrahedral) contacts: full grasp and every
             3-contact subgrasp force closure, many directions nearly tied;
  sub-nfc  - 4 contacts, full grasp FC but one 3-contact subgrasp is not;
  non-fc   - 4 contacts on one hemisphere side, not force closure;
  random   - a different random grasp per call, drawn from 200 grasps whose
             3-contact subgrasps are all FC.
Both pair solvers are timed ("osqp", the default, and "nnls"), for the exact value
and for the validity fast path (margin = 0.005). The reference is scipy's qhull
Ferrari-Canny epsilon of the same edge wrenches. Wall and CPU (thread) time are
printed with the load average: other processes on this 2-core machine slow it.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from dexplan.model.grasp import ForceClosure, contact_wrenches

MU = 0.8
TS = 0.04
MARGIN = 0.005


def sphere_grasp(dirs: object, radius: float = 0.04) -> tuple[np.ndarray, np.ndarray]:
    d = np.asarray(dirs, dtype=float)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    return radius * d, -d


def hull_epsilon(points: np.ndarray, normals: np.ndarray) -> float:
    w = contact_wrenches(points, normals, MU, torque_scale=TS)
    try:
        hull = ConvexHull(w)
    except QhullError:
        return 0.0
    return float(max(np.min(-hull.equations[:, -1]), 0.0))


def timed(fn: Callable[[], object], calls: int) -> tuple[float, float]:
    """Median wall and CPU microseconds of ``fn()``."""
    wall, cpu = [], []
    for _ in range(calls):
        t0, c0 = time.perf_counter(), time.thread_time()
        fn()
        cpu.append(time.thread_time() - c0)
        wall.append(time.perf_counter() - t0)
    return statistics.median(wall) * 1e6, statistics.median(cpu) * 1e6


Grasp = tuple[np.ndarray, np.ndarray]


def _fc_pool(rng: np.random.Generator, size: int = 200) -> list[Grasp]:
    """Random 4-contact sphere grasps whose every 3-subgrasp is force closure."""
    probe = ForceClosure(solver="nnls")
    pool: list[Grasp] = []
    while len(pool) < size:
        p, n = sphere_grasp(rng.normal(size=(4, 3)))
        if probe.min_subgrasp_quality(p, n, MU, torque_scale=TS) > 0:
            pool.append((p, n))
    return pool


def _solver_rows(solver: str, cases: dict[str, Grasp], pool: list[Grasp], calls: int) -> None:
    """One table row per case (and the random pool) for one pair solver."""
    fc = ForceClosure(solver=solver)  # type: ignore[arg-type]
    rows: list[tuple[str, Grasp | None]] = [*cases.items(), ("random", None)]
    for name, grasp in rows:
        counter = iter(range(10**9))

        def pick(grasp=grasp, counter=counter) -> Grasp:
            return grasp if grasp is not None else pool[next(counter) % len(pool)]

        def quality(fc=fc, pick=pick) -> float:
            p, n = pick()
            return fc.quality(p, n, MU, torque_scale=TS)

        def minsub(fc=fc, pick=pick, margin=None) -> float:
            p, n = pick()
            return fc.min_subgrasp_quality(p, n, MU, torque_scale=TS, margin=margin)

        before = fc.stats["pairs_solved"], fc.stats["evaluations"]
        t_q = timed(quality, calls)
        t_m = timed(minsub, calls)
        t_v = timed(lambda minsub=minsub: minsub(margin=MARGIN), calls)
        pairs = (fc.stats["pairs_solved"] - before[0]) / (fc.stats["evaluations"] - before[1])
        q = quality() if grasp is not None else float("nan")
        m = minsub() if grasp is not None else float("nan")
        cells = [f"{w:6.0f} / {c:6.0f}" for w, c in (t_q, t_m, t_v)]
        print(f"{solver:6s} {name:8s} {q:8.4f} {m:8.4f}  " + "  ".join(cells) + f"  {pairs:6.2f}")
    print(f"{solver:6s} stats: {fc.stats}")


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--calls", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    tetra = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=float)
    cases = {
        "tetra": sphere_grasp(tetra + 0.1 * np.arange(12).reshape(4, 3) / 12),
        "sub-nfc": sphere_grasp([[1, 0, 0], [-1, 0, 0], [0, 1, 0.2], [0, 0.2, 1]]),
        "non-fc": sphere_grasp([[1, 0, 1], [0, 1, 1], [-1, 0, 1], [0, -1, 1.2]]),
    }
    pool = _fc_pool(np.random.default_rng(args.seed))
    load = os.getloadavg()[0]
    print(f"median microseconds per call over {args.calls} calls (wall / cpu), edges=8, mu={MU}")
    print(f"load average (1 min) before: {load:.2f} on {os.cpu_count()} cores\n")
    header = f"{'solver':6s} {'case':8s} {'Q':>8s} {'min sub':>8s}"
    print(f"{header}  {'quality':>15s}  {'min_subgrasp':>15s}  {'min_sub margin':>15s}  pairs/call")
    for solver in ("osqp", "nnls"):
        _solver_rows(solver, cases, pool, args.calls)
    p, n = cases["tetra"]
    fc = ForceClosure()
    t_s = timed(lambda: fc.is_force_closure(p, n, MU, torque_scale=TS, subgrasps=True), args.calls)
    print(
        f"\nis_force_closure(subgrasps=True), tetra (screens only): {t_s[0]:6.0f} / {t_s[1]:6.0f}"
    )
    t_h = timed(lambda: hull_epsilon(p, n), max(args.calls // 10, 20))
    print(
        f"reference: qhull epsilon of the full tetra grasp        : {t_h[0]:6.0f} / {t_h[1]:6.0f}"
    )
    print(f"load average (1 min) after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
