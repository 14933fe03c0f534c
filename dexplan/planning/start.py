"""The start GSn state of a query: the scenario's start grasp, or a sampled one.

A sampled start grasp is chosen among a few valid grasps at the start pose
by how far its fingers can follow the object's straight move to the goal,
then by strength (:data:`START_CANDIDATES`); a given ``start.q`` is checked and moved onto GSn
within OMPL's tolerance.
"""

from __future__ import annotations

import numpy as np

from dexplan.core.errors import InvalidInputError
from dexplan.core.typing import FloatArray
from dexplan.planning.context import PlanningContext
from dexplan.planning.gsn.space import POSE_DIM
from dexplan.planning.local.grasps import (
    current_follow,
    finger_follows,
    follow_bound,
    grasp_from_state,
)
from dexplan.planning.local.transitions import GraspContacts, Transitions, densify_poses

__all__ = [
    "START_CANDIDATES",
    "START_FOLLOW_SHARE",
    "START_HOLD_CHECKS",
    "START_MORE_CANDIDATES",
    "start_state",
]


#: Valid start grasps the planner samples to choose the one it starts from
#: (1: the first, as the paper).
START_CANDIDATES = 8
#: More start grasps drawn when every candidate follows the object's move to
#: the goal by IK alone but none does with its links and holds checked.
START_MORE_CANDIDATES = 16
#: Start grasps whose fingers together follow the object's straight move (the
#: stroke secured, summed over the fingers) at least this share of the best
#: one's are ranked by strength.
START_FOLLOW_SHARE = 0.85
#: Of those, the strongest few whose releases are checked: the grasp kept is
#: the strongest from which every finger can be let go (the others hold the
#: object within the effort limits), else the one from which most can.
START_HOLD_CHECKS = 4


def start_state(
    ctx: PlanningContext,
    attempts: int = 400,
    candidates: int = START_CANDIDATES,
    rng: np.random.Generator | None = None,
) -> FloatArray | None:
    """The start GSn state: the scenario's ``start.q`` (checked) or a sampled grasp.

    A sampled start grasp is chosen among ``candidates`` valid grasps at
    the start pose (the first found, then ``candidates - 1`` more drawn from
    ``rng``): one that follows the object's straight move to the goal pose
    all the way if any does (a plan without regrasps: the first whose
    transfer, links and holds checked, reaches the goal; when every
    candidate follows by IK alone but none transfers,
    :data:`START_MORE_CANDIDATES` more are tried), else, among those
    whose fingers together follow at least :data:`START_FOLLOW_SHARE` of
    the best one's stroke (:func:`_stroke_sum`: each finger's own follow,
    links checked, summed), the strongest: the largest least force-closure quality of its
    (n-1)-finger subgrasps, among the :data:`START_HOLD_CHECKS` strongest the
    first from which every finger can be let go (the holds of its first
    regrasps, :meth:`Transitions.can_release`). Fingers that
    cannot follow cost regrasps; a weak grasp is where a real hand drops
    the object. The extra grasps come from their own stream, so the first
    grasp's sampling is the same whatever ``candidates`` is.

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
    if first is None or candidates <= 1:
        return first
    trans = ctx.transitions
    goal = ctx.scenario.goal.object_pose_xyzquat
    future = densify_poses(
        np.array([pose, goal]), trans.settings.max_step_m, trans.settings.max_step_rad
    )
    rng = np.random.default_rng(0) if rng is None else rng
    pool = [first, *ctx.sampler.samples_at_pose(pose, candidates - 1, rng)]
    grasps = [grasp_from_state(trans, pose, x[POSE_DIM:]) for x in pool]
    ik = [finger_follows(trans, g, future) for g in grasps]  # each finger's, IK alone
    whole = [x for x, f in zip(pool, ik, strict=True) if min(f) >= len(future)]
    if whole:
        return _carrying(ctx, pose, future, whole, len(whole) == len(pool), rng)
    near = _near(trans, future, pool, grasps, ik)
    strength = [trans.grasp_quality(grasps[k], exact=True) for k in near]
    best, most = pool[near[0]], -1
    for k in np.argsort(strength, kind="stable")[::-1][:START_HOLD_CHECKS]:
        x, g = pool[near[k]], grasps[near[k]]
        free = sum(trans.can_release(f, pose, x[POSE_DIM:], g) for f in range(ctx.hand.n_fingers))
        if free > most:
            best, most = x, free
        if free == ctx.hand.n_fingers:
            break
    return best


def _near(
    trans: Transitions,
    future: FloatArray,
    pool: list[FloatArray],
    grasps: list[GraspContacts],
    ik: list[list[int]],
) -> list[int]:
    """The indexes of ``pool``'s states whose stroke is near the best one's, ascending.

    Near: a :func:`_stroke_sum` at least :data:`START_FOLLOW_SHARE` of the
    largest. ``grasps`` and ``ik`` are the states' contacts and their
    fingers' IK-only follows
    (:func:`~dexplan.planning.local.grasps.finger_follows`). Tracking the
    fingers is most of a start grasp's cost, and the IK-only follows bound
    it nearly as tightly (:func:`~dexplan.planning.local.grasps.follow_bound`):
    the states are tracked largest bound first, and those whose bound is
    already below the share of a tracked one's stroke are not tracked.
    """
    end = len(future) - 1
    n = trans.hand.n_fingers
    bounds = [sum(min(follow_bound(trans, f, b[f]), end) for f in range(n)) for b in ik]
    strokes: dict[int, int] = {}
    for i in sorted(range(len(pool)), key=lambda i: bounds[i], reverse=True):
        if strokes and bounds[i] < START_FOLLOW_SHARE * max(strokes.values()):
            break  # neither near the best nor the best, nor is any after it
        strokes[i] = _stroke_sum(trans, pool[i], grasps[i], ik[i], future)
    far = max(strokes.values())
    return [i for i in range(len(pool)) if strokes.get(i, -1) >= START_FOLLOW_SHARE * far]


def _stroke_sum(
    trans: Transitions, x: FloatArray, grasp: GraspContacts, ik: list[int], future: FloatArray
) -> int:
    """The poses of ``future`` the fingers of state ``x`` follow, summed over the fingers.

    Each finger's own follow with its links collision-checked
    (:func:`~dexplan.planning.local.grasps.current_follow`, from its IK-only
    follow ``ik``): a finger whose
    stroke ends early costs a regrasp there, whichever finger it is, so
    the sum (the stroke the start grasp secures) ranks start grasps as the
    gait search ranks its states.
    """
    q = x[POSE_DIM:]
    end = len(future) - 1
    return sum(
        min(current_follow(trans, f, q, grasp, future, ik[f]), end)
        for f in range(trans.hand.n_fingers)
    )


def _carrying(
    ctx: PlanningContext,
    pose: FloatArray,
    future: FloatArray,
    whole: list[FloatArray],
    all_whole: bool,
    rng: np.random.Generator,
) -> FloatArray:
    """Of the grasps ``whole`` that follow ``future`` by IK alone, the first that transfers.

    When every candidate followed by IK (``all_whole``) and none transfers,
    :data:`START_MORE_CANDIDATES` more are drawn from ``rng`` and tried; when
    none does either, the first of ``whole`` (the planner may still regrasp).
    """
    done = _transferable(ctx, pose, future, whole)
    if done is None and all_whole:
        more = ctx.sampler.samples_at_pose(pose, START_MORE_CANDIDATES, rng)
        done = _transferable(ctx, pose, future, more)
    return whole[0] if done is None else done


def _transferable(
    ctx: PlanningContext, pose: FloatArray, future: FloatArray, states: list[FloatArray]
) -> FloatArray | None:
    """The first of ``states`` (at ``pose``) whose transfer along ``future`` reaches its end.

    The IK-only follow (:func:`~dexplan.planning.local.grasps.finger_follows`)
    ignores link collisions and holds; the transfer checks them, as the
    reduction will. On the TriFinger's cube every start grasp follows a
    quarter turn by IK alone, and 11 of 32 sampled ones transfer all the
    way (the others' links collide).
    """
    trans = ctx.transitions
    for x in states:
        if ctx.deadline.expired():
            return None
        grasp = grasp_from_state(trans, pose, x[POSE_DIM:])
        done = trans.transfer(future, 0, x[POSE_DIM:], grasp)
        if done.reason is None and done.reached >= len(future) - 1:
            return x
    return None


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
