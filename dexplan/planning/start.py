"""The start GSn state of a query: the scenario's start grasp, or a sampled one.

A sampled start grasp is chosen among a few valid grasps at the start pose
by how far its fingers can follow the object's straight move to the goal
(:data:`START_CANDIDATES`); a given ``start.q`` is checked and moved onto GSn
within OMPL's tolerance.
"""

from __future__ import annotations

import numpy as np

from dexplan.core.errors import InvalidInputError
from dexplan.core.typing import FloatArray
from dexplan.planning.context import PlanningContext
from dexplan.planning.gsn.space import POSE_DIM
from dexplan.planning.local.reduction import grasp_follow
from dexplan.planning.local.transitions import densify_poses

__all__ = ["START_CANDIDATES", "start_state"]


#: Valid start grasps the planner samples to choose the one it starts from
#: (1: the first, as the paper). The first is kept unless another one follows
#: the object's straight move to the goal all the way (a plan without
#: regrasps, where the first needs them). Choosing the best-following grasp
#: whatever its follow removes most regrasps on boxes, but on a sphere that
#: no grasp turns all the way its long partial transfers let the fingertips
#: roll further from the planned contacts, and the physics replay then
#: loses plans that replay from the first grasp.
START_CANDIDATES = 8


def start_state(
    ctx: PlanningContext,
    attempts: int = 400,
    candidates: int = START_CANDIDATES,
    rng: np.random.Generator | None = None,
) -> FloatArray | None:
    """The start GSn state: the scenario's ``start.q`` (checked) or a sampled grasp.

    A sampled start grasp is the first valid grasp found at the start pose,
    unless it cannot follow the object's straight move to the goal pose
    all the way and one of ``candidates - 1`` more, drawn from ``rng``, can
    (:func:`~dexplan.planning.local.reduction.grasp_follow`, IK-only: every finger
    reaches its contact at every pose within the joint margin): then the
    first of those. Every finger a transfer cannot follow costs a regrasp;
    on a box some start grasps turn it with none and others need a dozen.
    The extra grasps come from their own stream, so a query whose
    first grasp is kept samples and plans exactly as with ``candidates=1``.
    Hands with redundant fingers (the Allegro's 4 joints) take the first
    grasp: the IK-only follow says little about how a redundant finger's
    posture and links will fare (queries failed from the best-scored grasp
    that plan from the first).

    Args:
        ctx: the planning context.
        attempts: sampler attempts allowed before the first valid grasp.
        candidates: valid grasps to choose from (1: the first one found).
        rng: the stream of the extra candidates (None: seeded with 0).

    Raises:
        InvalidInputError: ``start.q`` has the wrong size or is not a valid grasp.
    """
    spec = ctx.scenario.start
    pose = spec.object_pose_xyzquat
    if spec.q is not None:
        if spec.q.shape != (ctx.hand.nq,):
            raise InvalidInputError(
                f"start.q must have {ctx.hand.nq} entries, got {spec.q.shape[0]}"
            )
        x = ctx.gsn.join(pose, spec.q)
        res = ctx.gsn.residual(x)
        if res > 1e-3:
            raise InvalidInputError(
                f"start.q does not put every fingertip on the object (error {res:.4g} m)"
            )
        x = _onto_gsn(ctx, x)
        verdict = ctx.validity.check(x)
        if not verdict.valid:
            raise InvalidInputError(f"start.q is not a valid grasp: {verdict.reason}")
        return x
    first: FloatArray | None = None
    for _ in range(max(1, attempts // ctx.sampler.settings.max_attempts)):
        if ctx.deadline.expired() or first is not None:
            break
        first = ctx.sampler.sample_at_pose(pose)
    trans = ctx.transitions
    if (
        first is None
        or candidates <= 1
        or any(trans.redundant(f) for f in range(ctx.hand.n_fingers))
    ):
        return first
    goal = ctx.scenario.goal.object_pose_xyzquat
    future = densify_poses(
        np.array([pose, goal]), trans.settings.max_step_m, trans.settings.max_step_rad
    )

    def all_the_way(x: FloatArray) -> bool:
        return grasp_follow(trans, pose, x[POSE_DIM:], future)[0] >= len(future)

    if all_the_way(first):
        return first
    rng = np.random.default_rng(0) if rng is None else rng
    for x in ctx.sampler.samples_at_pose(pose, candidates - 1, rng):
        if all_the_way(x):
            return x
    return first


def _onto_gsn(ctx: PlanningContext, x: FloatArray, tol: float = 1e-9) -> FloatArray:
    """``x`` with its hand joints moved onto GSn (Gauss-Newton, the object pose kept).

    A ``start.q`` within 1 mm of a grasp is accepted, but OMPL's constrained
    space takes only states within its tolerance (1e-5): a start 4e-5 off
    stopped the query with "start is off the manifold". Hand-written or
    rounded joint values are that far off.
    """
    x = np.array(x, dtype=float)
    for _ in range(20):
        f = ctx.gsn.function(x)
        if float(np.max(np.abs(f), initial=0.0)) <= tol:
            break
        J = ctx.gsn.jacobian(x)[:, POSE_DIM:]
        x[POSE_DIM:] -= np.linalg.lstsq(J, f, rcond=None)[0]
    return x
