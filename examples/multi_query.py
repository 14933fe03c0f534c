"""Multi-query planning: build a roadmap once, answer several queries on it.

The learning phase (``RoadmapPlanner.build``) grows a goal-independent GSn
roadmap over the scenario's workspace and links its components with
transfer-regrasp sequences. It is saved to a ``.npz`` file and loaded back
(refused if it was built for other models: hand, object, obstacles,
friction); every query then starts from the scenario's start and is
answered on the roadmap, each with its own statistics.

Run from the repository root::

    python examples/multi_query.py
"""

from __future__ import annotations

import math
import sys
import tempfile
from pathlib import Path

import dexplan

SCENARIO = Path(__file__).resolve().parent.parent / "scenarios" / "paper_sphere.toml"


def yaw(degrees: float) -> list[float]:
    """The start position turned ``degrees`` about the vertical (x, y, z, qx, qy, qz, qw)."""
    half = math.radians(degrees) / 2.0
    return [0.0, 0.0, 0.1, 0.0, 0.0, math.sin(half), math.cos(half)]


def main() -> int:
    """Build, save, load, query; return an exit code."""
    scenario = dexplan.load_scenario(SCENARIO)
    built = dexplan.RoadmapPlanner.build(scenario, nodes=16, seed=1)  # deterministic size
    st = built.build_stats
    print(f"built: {st.nodes} nodes, {st.edges} edges, {st.links} links in {st.time_s:.1f} s")
    with tempfile.TemporaryDirectory() as tmp:
        path = built.save(Path(tmp) / "roadmap.npz")
        planner = dexplan.RoadmapPlanner.load(scenario, path)
    rm = planner.roadmap
    print(f"loaded {rm.n_vertices} vertices, {len(rm.edges)} edges")
    solved = 0
    for k, plan in enumerate(planner.query_many([yaw(90.0), yaw(-60.0), yaw(180.0)]), start=1):
        s = plan.result.stats
        solved += plan.solved
        print(
            f"query {k}: {plan.status} in {s.time_s:.2f} s, {s.regrasps} regrasps ({s.gsn_status})"
        )
    return 0 if solved == 3 else 1


if __name__ == "__main__":
    sys.exit(main())
