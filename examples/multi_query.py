"""Multi-query planning: build a GSn roadmap once, answer a second query on it.

The first query explores the grasp subspace GSn and keeps its roadmap
(``plan.result.roadmap``). The roadmap is saved to a ``.npz`` file, loaded
back (refused if it was built for other models: hand, object, obstacles,
friction) and passed as ``roadmap=`` to a second query with another goal,
which links its start and goal into it instead of exploring from scratch.

Run from the repository root::

    python examples/multi_query.py
"""

from __future__ import annotations

import dataclasses
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

import dexplan
from dexplan.planning.context import build_context
from dexplan.planning.roadmap import Roadmap, scenario_key

SCENARIO = Path(__file__).resolve().parent.parent / "scenarios" / "paper_sphere.toml"


def main() -> int:
    """Plan twice on one roadmap; return an exit code."""
    scenario = dexplan.load_scenario(SCENARIO)  # goal: 180 degrees about z
    first = dexplan.plan(scenario, seed=1)
    roadmap = first.result.roadmap
    print(f"first query: {first.status}, roadmap of {roadmap.n_vertices} vertices")

    ctx = build_context(scenario, hand=first.hand)  # the models the roadmap must match
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "roadmap.npz"
        roadmap.save(path)
        loaded = Roadmap.load(path, scenario_key(ctx), ambient_dim=ctx.gsn.ambient_dim)
    print(f"loaded {loaded.n_vertices} vertices, {len(loaded.edges)} edges")

    half = math.radians(90.0) / 2.0  # second goal: 90 degrees about z
    pose = np.array([0.0, 0.0, 0.1, 0.0, 0.0, math.sin(half), math.cos(half)])
    goal = dataclasses.replace(scenario.goal, object_pose_xyzquat=pose)
    second = dexplan.plan(dataclasses.replace(scenario, goal=goal), roadmap=loaded, hand=first.hand)
    regrasps = sum(seg.kind == "regrasp" for seg in second.segments)
    print(f"second query: {second.status}, {len(second.segments)} segments, {regrasps} regrasps")
    return 0 if first.solved and second.solved else 1


if __name__ == "__main__":
    sys.exit(main())
