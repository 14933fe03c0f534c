"""``to_plan`` on a GSn path of your own: module 2 joins it up, the reduction makes gaits.

The path here is two grasps: the start grasp and one the goal region's OMPL
sampler draws at the goal pose. No GSn motion joins them; module 2 links
them with transfers and regrasps, and the plan-file verifier checks the
plan. Run: ``python examples/own_gsn_path.py`` (see docs/ompl.md).
"""

import sys
import tempfile
from pathlib import Path

import numpy as np

import dexplan
import dexplan.ompl as dompl

SCENARIO = Path(__file__).resolve().parent.parent / "scenarios" / "paper_sphere.toml"


def main() -> int:
    """Build the two-grasp path, make it a plan, save and verify it; return an exit code."""
    setup = dompl.SimpleSetup(SCENARIO, seed=1)
    state = setup.new_state(setup.start_state)
    setup.problem_definition.getGoal().sampleGoal(state)  # OMPL's goal sampler
    path = np.stack([setup.start_state, setup.read_state(state)])  # metres, XYZW, radians
    print(f"path: {path.shape[0]} states, goal pose {np.round(path[-1, :7], 3).tolist()}")
    plan = setup.to_plan(path, planner="two_grasps")
    stats = plan.result.stats
    print(f"plan: {plan.status}, {stats.module2_links} module-2 links, {stats.regrasps} regrasps")
    with tempfile.TemporaryDirectory() as tmp:
        report = dexplan.verify(plan.save(Path(tmp) / "plan.json"))
    print(f"verify: {'OK' if report.ok else 'FAILED'}")
    return 0 if plan.solved and report.ok else 1


if __name__ == "__main__":
    sys.exit(main())
