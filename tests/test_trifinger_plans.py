"""The builtin TriFinger on its cube: start grasps that carry the cube, plans that verify."""

import numpy as np
import pytest

from dexplan.model.scenario import load_scenario
from dexplan.planning.context import build_context
from dexplan.planning.gsn.space import POSE_DIM
from dexplan.planning.local.grasps import grasp_from_state
from dexplan.planning.local.transitions import densify_poses
from dexplan.planning.start import start_state

YAW90 = "scenarios/trifinger_cube_yaw90.toml"


def test_cube_start_grasp_transfers_all_the_way_to_the_goal() -> None:
    """Two fingers cannot hold the cube within the motors' torque, so no
    finger is ever let go: the start grasp must carry the cube to the goal.
    Seed 1's first grasp that follows by IK alone collides on the way."""
    ctx = build_context(load_scenario(YAW90), seed=1)
    x = start_state(ctx)
    assert x is not None and ctx.validity.is_valid(x)
    pose, goal = ctx.scenario.start.object_pose_xyzquat, ctx.scenario.goal.object_pose_xyzquat
    s = ctx.transitions.settings
    future = densify_poses(np.array([pose, goal]), s.max_step_m, s.max_step_rad)
    grasp = grasp_from_state(ctx.transitions, pose, x[POSE_DIM:])
    done = ctx.transitions.transfer(future, 0, x[POSE_DIM:], grasp)
    assert done.reason is None and done.reached == len(future) - 1
    # and no finger can be let go from it (the holds need several times the torque)
    assert not any(ctx.transitions.can_release(f, pose, x[POSE_DIM:], grasp) for f in range(3))


@pytest.mark.slow
def test_cube_yaw90_plans_and_verifies(tmp_path) -> None:
    import dexplan

    plan = dexplan.plan(load_scenario(YAW90), seed=1, quality="none", time_limit=120.0)
    assert plan.result.solved, plan.result.message  # solved: the planner's verifier passed it
    assert dexplan.verify(plan.save(tmp_path / "plan.json")).ok
