"""Shortcutting of object trajectories and merging of needless regrasps.

- :func:`shortcut_object_path` replaces the object trajectory of a GSn path by
  the fewest straight (line + slerp) pieces that keep the object clear of the
  obstacles and inside its workspace: RRT-style GSn paths wander, and every
  detour costs regrasps (MEASURED.md).
- :func:`merge_regrasps` replaces two regrasps of the same finger in a row by
  one, when the local planner finds the direct move.

Every segment the planner keeps is re-checked afterwards by the plan verifier.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from dexplan.planning.path import Segment
from dexplan.planning.transitions import GraspContacts, Transitions, densify_poses
from dexplan.typing import FloatArray


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
    from dexplan.planning.reduction import grasp_from_state

    f = a.finger
    assert f is not None
    w0, w1 = a.start, b.end
    grasp = grasp_from_state(trans, w0.object_pose_xyzquat, w0.q)
    end = grasp_from_state(trans, w1.object_pose_xyzquat, w1.q)
    if not isinstance(grasp, GraspContacts):
        return None
    seg = trans.regrasp(w0.object_pose_xyzquat, w0.q, grasp, f, end.points[f], end.normals_out[f])
    if seg is None or not np.allclose(seg.end.q, w1.q, atol=1e-6):
        return None
    # reuse the exact boundary waypoints so the neighbours still join up
    return Segment("regrasp", f, (w0, *seg.waypoints[1:-1], w1))
