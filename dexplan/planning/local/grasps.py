"""Grasps of hand states, how far a grasp follows the object, regrasps onto another grasp.

Shared by the finger-gait reduction (:mod:`.reduction`), the choice of the
start grasp (:mod:`dexplan.planning.start`) and module 2's links
(:mod:`dexplan.planning.roadmap.module2`).
"""

from __future__ import annotations

import numpy as np

from dexplan.core.pose import inverse_transform_points
from dexplan.core.segments import Segment
from dexplan.core.typing import FloatArray
from dexplan.planning.local.transitions import GraspContacts, Transitions

__all__ = [
    "current_follow",
    "finger_follows",
    "follow_bound",
    "grasp_follow",
    "grasp_from_state",
    "regrasps_onto",
]


def grasp_follow(
    trans: Transitions, pose: FloatArray, q: FloatArray, future: FloatArray
) -> tuple[int, ...]:
    """How far each finger of the grasp held at ``(pose, q)`` follows ``future``, ascending.

    The IK-only bound of :meth:`Transitions.follow_scores` per finger (joint
    limits, no link collisions: tracking the links too costs far more,
    ranks the grasps nearly alike, and the reduction tracks the grasp it
    keeps), sorted: compared as tuples, a grasp
    whose first blocked finger goes further, then whose second does, ranks
    higher (a transfer stops at the first blocked finger).
    """
    return tuple(sorted(finger_follows(trans, grasp_from_state(trans, pose, q), future)))


def finger_follows(trans: Transitions, grasp: GraspContacts, future: FloatArray) -> list[int]:
    """Per finger, in finger order, how far it follows ``future`` from ``grasp`` by IK alone.

    :meth:`Transitions.follow_scores` of each fingertip centre (joint
    limits, no link collisions): the bound :func:`current_follow` tightens.
    """
    tips = grasp.points + trans.hand.fingertip_radius * grasp.normals_out
    n = trans.hand.n_fingers
    return [int(trans.follow_scores(i, tips[i][None], future)[0]) for i in range(n)]


def current_follow(
    trans: Transitions,
    finger: int,
    q: FloatArray,
    grasp: GraspContacts,
    future: FloatArray,
    bound: int | None = None,
) -> int:
    """How many of the ``future`` poses ``finger`` can follow on its current contact.

    The IK-only bound (:meth:`Transitions.follow_scores`; ``bound`` when the
    caller has it, :func:`finger_follows`), tightened by tracking the
    finger with its links collision-checked (:meth:`Transitions.track_score`)
    for tracked fingers (:meth:`Transitions.tracked_count`).
    """
    r = trans.hand.fingertip_radius
    tip = grasp.points[finger] + r * grasp.normals_out[finger]
    if bound is None:
        bound = int(trans.follow_scores(finger, tip[None], future)[0])
    limit = follow_bound(trans, finger, bound)
    if limit == bound:  # not tracked, or nothing to track
        return bound
    return trans.track_score(finger, q, tip, grasp.normals_out[finger], future, limit)[0]


def follow_bound(trans: Transitions, finger: int, ik_follow: int) -> int:
    """An upper bound of :func:`current_follow` from the finger's IK-only follow.

    ``ik_follow``: its :func:`finger_follows` entry. Tracking counts at most
    the poses past it that its strides check
    (:attr:`TransitionSettings.follow_stride`).
    """
    if trans.tracked_count(finger) <= 0 or ik_follow <= 0:
        return ik_follow
    return ik_follow + max(1, trans.settings.follow_stride)


def regrasps_onto(
    trans: Transitions,
    pose: FloatArray,
    q: FloatArray,
    grasp: GraspContacts,
    target: GraspContacts,
    same_contact_m: float = 1e-3,
) -> tuple[list[Segment], FloatArray, GraspContacts] | None:
    """Regrasps (one finger at a time, the object fixed at ``pose``) from ``grasp`` onto ``target``.

    Every intermediate grasp keeps all its (n-1) subgrasps force closure; the
    finger order is chosen greedily, farthest contact first. Fingers already
    within ``same_contact_m`` of their target stay.

    Args:
        trans: local planners.
        pose: (7,) object pose, world frame.
        q: (nq,) hand joints holding ``grasp``.
        grasp: the current contacts, object frame.
        target: the contacts to end on, object frame.
        same_contact_m: contacts closer than this (m) count as the same.

    Returns:
        ``(regrasp segments, q, grasp)`` at the end (no segments when nothing
        had to move), or None when no order works.
    """
    gap = np.linalg.norm(grasp.points - target.points, axis=1)
    todo = [int(f) for f in np.argsort(-gap) if gap[f] > same_contact_m]
    segs: list[Segment] = []
    while todo:
        for f in todo:
            new = grasp.replace(f, target.points[f], target.normals_out[f])
            if trans.grasp_quality(new, exact=True) <= trans.validity.fc_margin:
                continue
            seg = trans.regrasp(pose, q, grasp, f, target.points[f], target.normals_out[f])
            if seg is not None:
                segs.append(seg)
                q, grasp = seg.end.q, new
                todo.remove(f)
                break
        else:
            return None
    return segs, q, grasp


def grasp_from_state(trans: Transitions, pose: FloatArray, q: FloatArray) -> GraspContacts:
    """Contacts (object frame) of the fingertips of ``q`` at an object pose."""
    tips = inverse_transform_points(pose, trans.hand.fingertip_positions(q))
    pts, n_out = trans.obj.closest_point(tips)
    return GraspContacts(np.asarray(pts), np.asarray(n_out))
