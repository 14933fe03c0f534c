"""Plan the paper's experiment, inspect the plan, save it and verify the file.

Shows the front door: ``dexplan.plan`` returns a ``Plan`` whose ``segments``
alternate transfers (the object moves, the grasp is fixed) and regrasps (the
object is still, one finger lets go and lands elsewhere); ``Plan.save`` writes
the ``dexplan-plan/1`` file and ``dexplan.verify`` re-checks it from the file
alone.

Run from the repository root::

    python examples/plan_and_inspect.py
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import dexplan

SCENARIO = Path(__file__).resolve().parent.parent / "scenarios" / "paper_sphere.toml"


def main() -> int:
    """Plan, print the segments and counts, save and verify; return an exit code."""
    plan = dexplan.plan(SCENARIO, seed=1)
    print(f"status: {plan.status}")
    if not plan.solved:
        print(plan.result.message)
        return 1
    for i, seg in enumerate(plan.segments):
        finger = "-" if seg.finger is None else seg.finger
        print(f"segment {i:2d}: {seg.kind:8s} finger {finger}  {len(seg.waypoints)} waypoints")
    stats = plan.result.stats  # a PlanStats
    print(f"regrasps: {stats.regrasps}  transfers: {stats.transfers}")
    print(f"planner: {stats.planner}  time: {stats.time_s:.2f} s")

    with tempfile.TemporaryDirectory() as tmp:
        path = plan.save(Path(tmp) / "plan.json")
        report = dexplan.verify(path)
        print(f"verify: {'OK' if report.ok else 'FAILED'} ({report.waypoints} waypoints)")
        for violation in report.violations[:5]:
            print(f"  {violation}")
    return 0 if report.ok else 1


if __name__ == "__main__":
    sys.exit(main())
