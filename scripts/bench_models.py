"""Micro-benchmarks of the models dexplan's planner calls in its inner loops.

Run from the repository root:

    python scripts/bench_models.py

Prints the median microseconds per call (over repeated batches) of: fingertip
FK + Jacobians of all fingers, per-finger IK (closed form and damped least
squares), GSn constraint f and J, closest point on a sphere and on 1k / 82k
triangle meshes, a full collision check, and force-closure quality of a
4-finger grasp alone and with all its 3-finger subgrasps.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable

import numpy as np
import trimesh

from dexplan.model.collision import CollisionWorld
from dexplan.model.grasp import force_closure_quality, min_subgrasp_quality
from dexplan.model.hand.hand import Hand
from dexplan.model.objects import Mesh, Sphere
from dexplan.planning.gsn.space import GraspSubspace


def bench(fn: Callable[[], object], n: int = 2000, batches: int = 7) -> float:
    """Median over ``batches`` of the mean microseconds per call of ``fn``."""
    fn()
    per = []
    for _ in range(batches):
        t0 = time.perf_counter()
        for _ in range(n):
            fn()
        per.append((time.perf_counter() - t0) / n * 1e6)
    return statistics.median(per)


def grasp_state(hand: Hand) -> tuple[np.ndarray, np.ndarray]:
    """Object pose and hand joints of a 4-finger grasp of the builtin sphere."""
    pose = np.array([0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0])
    q = hand.neutral.copy()
    for i in range(hand.n_fingers):
        az = np.deg2rad(45 + 90 * i)
        lat = np.deg2rad(-15)
        d = 0.04 + hand.fingertip_radius
        target = pose[:3] + d * np.array(
            [np.cos(lat) * np.cos(az), np.cos(lat) * np.sin(az), np.sin(lat)]
        )
        q[hand.finger_q_index[i]] = hand.finger_ik(i, target, q).q_finger
    return pose, q


def main() -> None:
    hand = Hand.builtin("paper")
    sphere = Sphere(0.04)
    pose, q = grasp_state(hand)
    rows: list[tuple[str, float]] = []
    rows.append(("FK + Jacobians, 4 fingertips", bench(lambda: hand.fingertip_jacobians(q))))
    tip = hand.fingertip_positions(q)[0]
    rows.append(("IK one finger (closed form)", bench(lambda: hand.finger_ik(0, tip, q))))
    dls = Hand.builtin("paper")
    dls._analytic_ik = [None] * dls.n_fingers
    rows.append(("IK one finger (damped least squares)", bench(lambda: dls.finger_ik(0, tip), 300)))
    gsn = GraspSubspace(
        hand, sphere, workspace_center=pose[:3], workspace_half_extent=np.full(3, 0.02)
    )
    x = gsn.join(pose, q)
    step = [0]

    def moved() -> np.ndarray:
        step[0] += 1
        x[0] = 1e-9 * (step[0] % 2)  # defeat the evaluation cache
        return x

    rows.append(("GSn constraint f", bench(lambda: gsn.function(moved()))))
    rows.append(("GSn constraint J", bench(lambda: gsn.jacobian(moved()))))
    p = np.array([0.01, 0.02, 0.05])
    rows.append(("closest point, sphere", bench(lambda: sphere.closest_point(p))))
    for sub in (3, 6):
        ico = trimesh.creation.icosphere(subdivisions=sub, radius=0.04)
        mesh = Mesh(ico.vertices, ico.faces)
        label = f"closest point, mesh {len(ico.faces)} triangles"
        rows.append((label, bench(lambda m=mesh: m.closest_point(p), 500)))
    world = CollisionWorld(hand, sphere)
    mask = [True] * 4
    rows.append(("collision check (hand, object)", bench(lambda: world.check(q, pose, mask), 500)))
    pts, nrm = gsn.contacts(x)
    ts = sphere.characteristic_length
    fc_rows = (
        ("FC quality, 4 contacts (exact)", force_closure_quality, None),
        ("FC quality, 4 contacts + all 3-subgrasps (exact)", min_subgrasp_quality, None),
        ("FC 4 contacts + 3-subgrasps > margin 0.005 (validity)", min_subgrasp_quality, 0.005),
    )
    for label, fn, margin in fc_rows:

        def call(fn=fn, margin=margin) -> float:
            return fn(pts, nrm, 0.8, torque_scale=ts, margin=margin)

        rows.append((label, bench(call, 100 if margin is None else 500)))
    width = max(len(r[0]) for r in rows)
    print(f"{'operation':<{width}}  median us/call")
    for name, us in rows:
        print(f"{name:<{width}}  {us:10.1f}")


if __name__ == "__main__":
    main()
