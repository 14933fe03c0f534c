"""Shortcutting of object trajectories and merging of needless regrasps.

- :func:`shortcut_object_path` replaces the object trajectory of a GSn path by
  the fewest straight (line + slerp) pieces that keep the object clear of the
  obstacles and inside its workspace: RRT-style GSn paths wander, and every
  detour costs regrasps.
- :func:`merge_regrasps` replaces two regrasps of the same finger in a row by
  one, when the local planner finds the direct move.
- :func:`drop_regrasps` drops regrasps the plan does not need: trailing ones
  (the object is already at the goal), and a regrasp whose following transfer
  the old grasp can make too when the same finger regrasps right after it
  (that later regrasp then starts from the old contact), or when that
  transfer ends the plan. Transfers left in a row on one grasp are joined.

Every segment the planner keeps is re-checked afterwards by the plan verifier.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from dexplan.core.pose import inverse_transform_points
from dexplan.core.segments import Segment, SegmentKind, Waypoint
from dexplan.core.typing import FloatArray
from dexplan.planning.local.transitions import GraspContacts, Transitions, densify_poses


def straight_move_ok(
    a: FloatArray,
    b: FloatArray,
    pose_ok: Callable[[FloatArray], bool],
    step_m: float,
    step_rad: float,
) -> bool:
    """True when ``pose_ok`` holds along the straight move from pose ``a`` to ``b`` (XYZW).

    The move is sampled at ``step_m`` / ``step_rad``; ``a`` itself is not checked
    (callers start from a pose already known to be fine).
    """
    dense = densify_poses(np.array([a, b]), step_m, step_rad)
    return all(pose_ok(p) for p in dense[1:])


def shortcut_object_path(
    poses: FloatArray,
    pose_ok: Callable[[FloatArray], bool],
    step_m: float = 0.005,
    step_rad: float = 0.05,
) -> FloatArray:
    """Greedy shortcut: from each kept pose jump to the farthest one reachable straight.

    Args:
        poses: (P, 7) object poses (XYZW) along a path.
        pose_ok: True when the object may be at a pose (no obstacle, in workspace).
        step_m: check resolution in position (m).
        step_rad: check resolution in orientation (rad).

    Returns:
        (P', 7) kept poses, first and last included, P' <= P.
    """
    if len(poses) <= 2:
        return np.array(poses)
    kept = [0]
    i = 0
    while i < len(poses) - 1:
        j = len(poses) - 1
        while j > i + 1 and not straight_move_ok(poses[i], poses[j], pose_ok, step_m, step_rad):
            j = (i + j) // 2 if j - i > 8 else j - 1
        kept.append(j)
        i = j
    return np.array([poses[k] for k in kept])


def merge_regrasps(trans: Transitions, segments: list[Segment]) -> list[Segment]:
    """Merge consecutive regrasps of the same finger into one regrasp, when possible.

    The merged regrasp goes straight from the first segment's start contact to
    the second's end contact; it replaces both only if the local planner finds
    it. Other segments are kept as they are.
    """
    out: list[Segment] = []
    k = 0
    while k < len(segments):
        s = segments[k]
        nxt = segments[k + 1] if k + 1 < len(segments) else None
        if (
            nxt is not None
            and s.kind == "regrasp"
            and nxt.kind == "regrasp"
            and s.finger == nxt.finger
            and s.finger is not None
        ):
            merged = _direct_regrasp(trans, s, nxt)
            if merged is not None:
                out.append(merged)
                k += 2
                continue
        out.append(s)
        k += 1
    return out


def _direct_regrasp(trans: Transitions, a: Segment, b: Segment) -> Segment | None:
    """One regrasp of ``a.finger`` from where ``a`` starts to where ``b`` ends, or None."""
    f = a.finger
    assert f is not None
    w0, w1 = a.start, b.end
    # the stated contacts, not the fingertips' closest points: the holding
    # fingers' contacts are copied into every interior waypoint
    grasp = _stated_grasp(trans, w0)
    end = _stated_grasp(trans, w1)
    seg = trans.regrasp(w0.object_pose_xyzquat, w0.q, grasp, f, end.points[f], end.normals_out[f])
    if (
        seg is None
        or not np.allclose(seg.end.q, w1.q, atol=1e-6)
        or not _holders_still(trans, f, w0, w1)
    ):
        return None
    # reuse the exact boundary waypoints so the neighbours still join up
    return Segment(SegmentKind.REGRASP, f, (w0, *seg.waypoints[1:-1], w1))


def drop_regrasps(trans: Transitions, segments: list[Segment]) -> list[Segment]:
    """Drop regrasps that the transfers after them do not need (see the module doc).

    Every replacement is planned by the local planners from the exact
    boundary waypoints, and kept only when it ends where the segments it
    replaces ended, so the rest of the plan is unchanged.
    """
    segs = list(segments)
    while len(segs) > 1 and segs[-1].kind == "regrasp":
        segs.pop()  # regrasps do not move the object: the goal is reached before them
    k = 0
    while k + 1 < len(segs):
        r, t = segs[k], segs[k + 1]
        after = segs[k + 2] if k + 2 < len(segs) else None
        if r.kind != "regrasp" or t.kind != "transfer" or r.finger is None:
            k += 1
            continue
        if after is None:
            moved = _transfer_on(trans, r.start, t)
            if moved is not None:
                segs[k : k + 2] = [moved]
                continue
        elif after.kind == "regrasp" and after.finger == r.finger:
            moved = _transfer_on(trans, r.start, t)
            again = None if moved is None else _regrasp_to(trans, moved.end, after)
            if moved is not None and again is not None:
                segs[k : k + 3] = [moved, again]
                continue
        k += 1
    return _join_transfers(segs)


def _stated_grasp(trans: Transitions, w: Waypoint) -> GraspContacts:
    """The contacts a waypoint states (exactly), with the normals the fingertips push along.

    The surface point closest to a fingertip centre is not always its stated
    contact: in a concave region the fingertip sphere touches the surface near
    two places, and the closest point may be the other one (3.4 mm away on the
    bean mesh's waist). Re-planned segments copy these contacts into their
    waypoints, so they are the stated ones. Per finger, the normal is the
    surface normal at the stated contact or the one at the fingertip's closest
    point, whichever puts the fingertip centre (contact + radius * normal)
    nearer to where it is: the first on a face, the second at a box edge or
    corner, as the plan verifier reads contacts. A free finger (contact None)
    gets the point its fingertip is closest to.
    """
    tips = inverse_transform_points(w.object_pose_xyzquat, trans.hand.fingertip_positions(w.q))
    pts, n_out = trans.obj.closest_point(tips)
    points = np.array(pts, dtype=float).reshape(-1, 3)
    normals = np.array(n_out, dtype=float).reshape(-1, 3)
    held = [i for i, c in enumerate(w.contacts) if c is not None]
    if held:
        stated = np.array([w.contacts[i] for i in held], dtype=float).reshape(-1, 3)
        _, n_at_stated = trans.obj.closest_point(stated)
        n_stated = np.asarray(n_at_stated, dtype=float).reshape(-1, 3)
        r = trans.hand.fingertip_radius
        gap_stated = np.linalg.norm(stated + r * n_stated - tips[held], axis=1)
        gap_touched = np.linalg.norm(stated + r * normals[held] - tips[held], axis=1)
        normals[held] = np.where((gap_stated < gap_touched)[:, None], n_stated, normals[held])
        points[held] = stated
    return GraspContacts(points, normals)


def _transfer_on(trans: Transitions, start: Waypoint, t: Segment) -> Segment | None:
    """Transfer ``t``'s object motion on the grasp of waypoint ``start``, or None."""
    grasp = _stated_grasp(trans, start)
    poses = np.array([w.object_pose_xyzquat for w in t.waypoints])
    tr = trans.transfer(poses, 0, start.q, grasp)
    if tr.reason is not None:
        return None
    return Segment(SegmentKind.TRANSFER, None, (start, *tr.waypoints[1:]))


def _regrasp_to(trans: Transitions, start: Waypoint, target: Segment) -> Segment | None:
    """Regrasp of ``target.finger`` from ``start`` to where ``target`` ends, or None."""
    f = target.finger
    assert f is not None
    pose = start.object_pose_xyzquat
    grasp = _stated_grasp(trans, start)
    end = _stated_grasp(trans, target.end)
    if trans.grasp_quality(grasp) <= trans.validity.fc_margin:
        return None  # certified bounds only: keep the original plan when unsure
    if not _holders_still(trans, f, start, target.end):
        return None
    seg = trans.regrasp(pose, start.q, grasp, f, end.points[f], end.normals_out[f])
    if seg is None or not np.allclose(seg.end.q, target.end.q, atol=1e-6):
        return None
    return Segment(SegmentKind.REGRASP, f, (start, *seg.waypoints[1:-1], target.end))


#: How far (rad, m) a holding finger's joint may differ between a regrasp's
#: first and last waypoints: the plan verifier's "does not move".
_STILL = 1e-9


def _holders_still(trans: Transitions, f: int, a: Waypoint, b: Waypoint) -> bool:
    """True when every finger but ``f`` has the same joints at ``a`` and at ``b``.

    A replacement regrasp ends on the waypoint of the segments it replaces;
    that waypoint's holding fingers came from another IK solve, equal to
    ``a``'s only where the IK is closed form (a numerical solve lands within
    its tolerance, up to 1e-7 rad away), and a regrasp must not move them.
    """
    others = [i for k, idx in enumerate(trans.hand.finger_q_index) if k != f for i in idx]
    return bool(np.all(np.abs(a.q[others] - b.q[others]) <= _STILL))


def _join_transfers(segments: list[Segment]) -> list[Segment]:
    """Join transfers in a row that hold the same contacts into one."""
    out: list[Segment] = []
    for s in segments:
        prev = out[-1] if out else None
        if prev is not None and prev.kind == s.kind == "transfer" and _same_contacts(prev, s):
            out[-1] = Segment(SegmentKind.TRANSFER, None, prev.waypoints + s.waypoints[1:])
        else:
            out.append(s)
    return out


def _same_contacts(a: Segment, b: Segment) -> bool:
    pairs = zip(a.end.contacts, b.start.contacts, strict=True)
    return all(x is not None and y is not None and np.array_equal(x, y) for x, y in pairs)
