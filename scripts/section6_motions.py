"""Section VI GSn motions against OMPL's projected motions, between the same states.

The paper (section VI) joins two GSn states on a polyhedral object by moving
each contact along its surface geodesic while the object pose interpolates;
the fingers follow by IK. OMPL's ProjectedStateSpace instead interpolates the
ambient vector (pose and joints) and projects. This script samples valid GSn
states with the RLG sampler, pairs each with its nearest neighbours in object
pose (as PRM connects milestones), and checks both motions on every pair:

- projected: ``PlanningProblem.check_motion`` (OMPL's discrete geodesic);
- section VI: pose slerp, contacts at the same arc-length fraction of their
  geodesics (``dexplan.model.objects.geodesic``), closed-form finger IK to the
  fingertip centres (branch nearest the previous step), every state through
  the validity checker; steps of at most 2 mm of contact travel, 2 mm of
  object translation and 0.02 rad of rotation, halved (up to 5 times) while a
  joint moves more than 0.05 rad in one (else it fails: a branch jump).

It reports how many pairs each motion joins, and why section VI motions fail.
The section VI motion is :func:`dexplan.planning.local.geodesic_motion.geodesic_motion`;
the planner does not use it yet: this measures whether a Python
``ob.MotionValidator`` along these motions (which the ompl 2.0.1 wheel does
call, docs/meshes.md) would join more of the roadmap.

Usage: python scripts/section6_motions.py SCENARIO.toml [STATES (60)] [NEIGHBOURS (4)] [SEED (1)]
"""

from __future__ import annotations

import collections
import sys

import numpy as np

from dexplan.model.scenario import load_scenario
from dexplan.planning.context import build_context
from dexplan.planning.local.contact_paths import ContactPaths
from dexplan.planning.local.geodesic_motion import MotionFailure, geodesic_motion
from dexplan.planning.roadmap.graph import pose_distances
from dexplan.planning.roadmap.queries import query_problem


def main() -> None:
    scenario = load_scenario(sys.argv[1])
    n_states = int(sys.argv[2]) if len(sys.argv) > 2 else 60
    k_near = int(sys.argv[3]) if len(sys.argv) > 3 else 4
    seed = int(sys.argv[4]) if len(sys.argv) > 4 else 1
    ctx = build_context(scenario, seed)
    paths = ContactPaths(ctx.obj)
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
            motion = geodesic_motion(ctx.transitions, ctx.validity, paths, a, xs[j])
            s6 = motion.valid
            if motion.failure is MotionFailure.INVALID:
                why[str(motion.detail).split(":")[0]] += 1
            elif motion.failure is not None:
                why[motion.failure.value] += 1
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
