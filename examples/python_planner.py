"""Your own OMPL planner, in Python and in no registry, on dexplan's GSn problem.

Run: ``python examples/python_planner.py`` (docs/ompl.md explains each step).
"""

import sys
from pathlib import Path

from ompl import base as ob
from ompl import geometric as og

import dexplan.ompl as dompl

SCENARIO = Path(__file__).resolve().parent.parent / "scenarios" / "paper_sphere.toml"


class GraspTree(ob.Planner):
    """A tree of valid grasps from the start, each joined to its nearest by a valid motion."""

    def solve(self, ptc: ob.PlannerTerminationCondition) -> ob.PlannerStatus:
        si, pdef = self.getSpaceInformation(), self.getProblemDefinition()
        goal = si.allocState()
        pdef.getGoal().sampleGoal(goal)  # the goal region's sampler: a grasp there
        tree = [pdef.getStartState(0)]
        branches = [tree[:]]  # branches[i]: the states from the start to tree[i]
        sampler = si.allocValidStateSampler()  # dexplan's RLG-style sampler of GSn
        while not ptc():
            state = si.allocState()
            if not sampler.sample(state):
                continue
            near = min(range(len(tree)), key=lambda j: si.distance(state, tree[j]))
            if not si.checkMotion(tree[near], state):
                continue
            tree.append(state)
            branches.append([*branches[near], state])
            if si.checkMotion(state, goal):
                path = og.PathGeometric(si)
                for s in [*branches[-1], goal]:
                    path.append(s)
                pdef.addSolutionPath(path)
                return ob.PlannerStatus(ob.PlannerStatus.EXACT_SOLUTION)
        return ob.PlannerStatus(ob.PlannerStatus.TIMEOUT)


def main() -> int:
    """Solve GSn with GraspTree, make its path a verified plan; return an exit code."""
    setup = dompl.SimpleSetup(SCENARIO, seed=1)
    setup.set_planner(GraspTree(setup.space_information, "GraspTree"))
    print(f"{setup.planner.getName()}: {setup.solve(60.0).status}")
    path = setup.solution_path()  # (K, 7 + nq): metres, quaternion XYZW, radians
    print(f"GSn path: {len(path)} states of dimension {setup.dimension}")
    plan = setup.to_plan(path)  # module 2, the reduction, the plan-file verifier
    stats = plan.result.stats
    print(f"plan: {plan.status}, {stats.regrasps} regrasps, {stats.transfers} transfers")
    return 0 if plan.solved else 1


if __name__ == "__main__":
    sys.exit(main())
