"""Section VI GSn motions against OMPL's projected motions, between the same states.

The paper (section VI) joins two GSn states on a polyhedral object by moving
each contact along its surface geodesic while the object pose interpolates;
the fingers follow by IK. OMPL's ProjectedStateSpace instead interpolates the
ambient vector (pose and joints) and projects. This script samples valid GSn
states with the RLG sampler, pairs each with its nearest neighbours in object
pose (as PRM connects milestones), and checks both motions on every pair:

- projected: ``PlanningProblem.check_motion`` (OMPL's discrete geodesic);
- section VI: pose slerp, contacts at the same arc-length fraction of their
  geodesics (``dexplan.objects.geodesic``), closed-form finger IK to the
  fingertip centres (branch nearest the previous step), every state through
  the validity checker; steps of at most 2 mm of contact travel, 2 mm of
  object translation and 0.02 rad of rotation, halved (up to 5 times) while a
  joint moves more than 0.05 rad in one (else it fails: a branch jump).

It reports how many pairs each motion joins, and why section VI motions fail.
Nothing here is used by the planner: it measures whether a Python
``ob.MotionValidator`` along these motions (which the ompl 2.0.1 wheel does
call, docs/meshes.md) would join more of the roadmap.

Usage: python scripts/section6_motions.py SCENARIO.toml [STATES (60)] [NEIGHBOURS (4)] [SEED (1)]
"""

from __future__ import annotations

import collections
import math
import sys

import numpy as np

from dexplan.objects.geodesic import surface_geodesics
from dexplan.planning.context import build_context
from dexplan.planning.gsn import POSE_DIM
from dexplan.planning.queries import query_problem
from dexplan.planning.reduction import grasp_from_state
from dexplan.planning.roadmap import pose_distances
from dexplan.pose import interpolate_pose, quat_angle, quat_to_matrix
from dexplan.scenario import load_scenario

STEP_M = 0.002
STEP_RAD = 0.02
JUMP_RAD = 0.05
MAX_SPLITS = 5


def section6_motion(ctx, geo, a: np.ndarray, b: np.ndarray) -> str | None:
    """None when the section VI motion a -> b is valid, else why not."""
    tr, hand = ctx.transitions, ctx.hand
    pa, pb = a[:POSE_DIM].copy(), b[:POSE_DIM].copy()
    pa[3:] /= np.linalg.norm(pa[3:])
    pb[3:] /= np.linalg.norm(pb[3:])
    ga = grasp_from_state(tr, pa, a[POSE_DIM:])
    gb = grasp_from_state(tr, pb, b[POSE_DIM:])
    paths = [geo.path(ga.points[f], gb.points[f]) for f in range(hand.n_fingers)]
    travel = max(p.length for p in paths)
    n = max(
        1,
        math.ceil(travel / STEP_M),
        math.ceil(float(np.linalg.norm(pb[:3] - pa[:3])) / STEP_M),
        math.ceil(quat_angle(pa[3:], pb[3:]) / STEP_RAD),
    )
    r = hand.fingertip_radius

    def state(t: float, q_prev: np.ndarray) -> tuple[np.ndarray, np.ndarray] | str:
        pose = interpolate_pose(pa, pb, t)
        R = quat_to_matrix(pose[3:])
        q_new = q_prev.copy()
        for f, path in enumerate(paths):
            p, _, nrm = path.at(t)
            tip = R @ (p + r * nrm) + pose[:3]
            q_f = hand.finger_ik_fast(f, tip, q_prev, -(R @ nrm))
            if q_f is None:
                return "ik"
            q_new[hand.finger_q_index[f]] = q_f
        return pose, q_new

    def advance(t0: float, t1: float, q0: np.ndarray, depth: int) -> np.ndarray | str:
        """Joints at t1 reached from q0 at t0 in valid steps of at most JUMP_RAD."""
        got = state(t1, q0)
        if isinstance(got, str):
            return got
        pose, q1 = got
        if np.max(np.abs(q1 - q0)) > JUMP_RAD:
            if depth >= MAX_SPLITS:
                return "joint jump"
            mid = advance(t0, 0.5 * (t0 + t1), q0, depth + 1)
            return mid if isinstance(mid, str) else advance(0.5 * (t0 + t1), t1, mid, depth + 1)
        verdict = ctx.validity.check(np.concatenate([pose, q1]))
        if not verdict.valid:
            return str(verdict.reason).split(":")[0]
        return q1

    q = a[POSE_DIM:].copy()
    for k in range(1, n + 1):
        got = advance((k - 1) / n, k / n, q, 0)
        if isinstance(got, str):
            return got
        q = got
    return None


def main() -> None:
    scenario = load_scenario(sys.argv[1])
    n_states = int(sys.argv[2]) if len(sys.argv) > 2 else 60
    k_near = int(sys.argv[3]) if len(sys.argv) > 3 else 4
    seed = int(sys.argv[4]) if len(sys.argv) > 4 else 1
    ctx = build_context(scenario, seed)
    geo = surface_geodesics(ctx.obj)
    problem = query_problem(ctx)
    states = []
    while len(states) < n_states:
        x = ctx.sampler.sample()
        if x is not None:
            states.append(x)
    xs = np.array(states)
    both = proj_only = s6_only = neither = 0
    why: collections.Counter[str] = collections.Counter()
    for i, a in enumerate(xs):
        d = pose_distances(xs, a[None])
        d[i] = np.inf
        for j in np.argsort(d, kind="stable")[:k_near].tolist():
            proj = problem.check_motion(a, xs[j])
            reason = section6_motion(ctx, geo, a, xs[j])
            s6 = reason is None
            if reason is not None:
                why[reason] += 1
            both += proj and s6
            proj_only += proj and not s6
            s6_only += s6 and not proj
            neither += not proj and not s6
    pairs = both + proj_only + s6_only + neither
    print(f"{scenario.name}: {pairs} pairs ({n_states} states x {k_near} nearest), seed {seed}")
    print(f"  projected valid {both + proj_only}, section VI valid {both + s6_only}")
    print(
        f"  both {both}, projected only {proj_only}, section VI only {s6_only}, neither {neither}"
    )
    print(f"  section VI failures: {dict(why.most_common())}")


if __name__ == "__main__":
    main()
