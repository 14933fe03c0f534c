"""Reduction of a GSn path to transfer and regrasp segments (paper, section IV).

The reduction property says a path in valid GSn can be replaced by a finite
alternation of transfer and regrasp paths. On symmetric objects the GSn path
itself mostly slides the contacts, so the physical plan is made here, and made
to look like a finger gait (see MEASURED.md):

1. follow the object trajectory with one transfer on the current grasp for as
   long as it stays valid;
2. regrasp the finger that blocks it (IK, joint limit, collision) onto the
   landing from which it can follow the rest of the motion longest; when that
   finger has no landing, move another finger first (fewest remaining steps
   first), which may clear its way;
3. repeat until the object reaches the end of the trajectory.

Only the object trajectory of the GSn path is followed; its contacts are
offered as landing hints. A clear failure status is returned when no regrasp
works or no progress is made.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dexplan.planning.path import Segment
from dexplan.planning.transitions import GraspContacts, Transitions
from dexplan.typing import FloatArray


@dataclass(frozen=True)
class ReductionSettings:
    """Limits of the reduction.

    Attributes:
        max_regrasps: give up after this many regrasps.
        max_stall: give up after this many regrasps in a row without object progress.
    """

    max_regrasps: int = 200
    max_stall: int = 8


@dataclass(frozen=True)
class ReductionResult:
    """Outcome of :func:`reduce_object_path`.

    Attributes:
        success: the object reached the end of the trajectory.
        segments: transfer and regrasp segments, in order.
        reached: index of the last pose reached in the dense trajectory.
        reason: failure reason, None on success.
        stats: counters (transfers, regrasps, attempts).
    """

    success: bool
    segments: tuple[Segment, ...]
    reached: int
    reason: str | None
    stats: dict[str, int] = field(default_factory=dict)


def reduce_object_path(
    trans: Transitions,
    poses: FloatArray,
    q_start: FloatArray,
    grasp: GraspContacts,
    settings: ReductionSettings | None = None,
    hints: FloatArray | None = None,
) -> ReductionResult:
    """Turn a dense object trajectory into transfer and regrasp segments.

    Args:
        trans: local planners.
        poses: (P, 7) dense object trajectory (consecutive poses within the
            transfer resolution), starting at the current pose.
        q_start: (nq,) hand configuration holding ``grasp`` at ``poses[0]``.
        grasp: initial contacts (all n fingers).
        settings: limits.
        hints: optional (P, n, 6) per-pose contact point and outward normal
            (object frame) of each finger along the GSn path, offered as
            landing candidates.

    Returns:
        A :class:`ReductionResult`.
    """
    settings = settings or ReductionSettings()
    n = trans.hand.n_fingers
    segments: list[Segment] = []
    idx, q = 0, q_start.copy()
    regrasps = stall = 0
    r = trans.hand.fingertip_radius
    while True:
        tr = trans.transfer(poses, idx, q, grasp)
        if len(tr.waypoints) > 1:
            segments.append(Segment("transfer", None, tr.waypoints))
            stall = 0
        idx, q = tr.reached, tr.waypoints[-1].q
        if tr.reason is None:
            return ReductionResult(True, tuple(segments), idx, None, _stats(trans, regrasps))
        if tr.blocking is None:
            return ReductionResult(
                False,
                tuple(segments),
                idx,
                f"transfer blocked: {tr.reason}",
                _stats(trans, regrasps),
            )
        future = poses[idx:]
        # the blocking finger first, then the others, least remaining follow first
        others = [i for i in range(n) if i != tr.blocking]
        follow = {
            i: int(
                trans.follow_scores(i, (grasp.points[i] + r * grasp.normals_out[i])[None], future)[
                    0
                ]
            )
            for i in others
        }
        order = [tr.blocking, *sorted(others, key=lambda i: follow[i])]
        done = False
        for f in order:
            hint = None
            if hints is not None:
                h = hints[min(idx, len(hints) - 1), f]
                hint = (h[:3], h[3:])
            for point, normal, score in trans.landing_candidates(
                f, poses[idx], q, grasp, future, hint
            ):
                if f != tr.blocking and score <= follow[f]:
                    break  # moving this finger would not help it follow further
                seg = trans.regrasp(poses[idx], q, grasp, f, point, normal)
                if seg is not None:
                    segments.append(seg)
                    q = seg.end.q
                    grasp = grasp.replace(f, point, normal)
                    done = True
                    break
            if done:
                break
        if not done:
            return ReductionResult(
                False,
                tuple(segments),
                idx,
                f"no feasible regrasp at trajectory step {idx} (blocked by finger "
                f"{tr.blocking}: {tr.reason})",
                _stats(trans, regrasps),
            )
        regrasps += 1
        stall += 1
        if regrasps > settings.max_regrasps or stall > settings.max_stall:
            return ReductionResult(
                False,
                tuple(segments),
                idx,
                f"no progress after {regrasps} regrasps at trajectory step {idx}",
                _stats(trans, regrasps),
            )


def _stats(trans: Transitions, regrasps: int) -> dict[str, int]:
    out = dict(trans.stats)
    out["reduction_regrasps"] = regrasps
    return out


def grasp_from_state(trans: Transitions, pose: FloatArray, q: FloatArray) -> GraspContacts:
    """Contacts (object frame) of the fingertips of ``q`` at an object pose."""
    from dexplan.pose import inverse_transform_points

    tips = inverse_transform_points(pose, trans.hand.fingertip_positions(q))
    pts, n_out = trans.obj.closest_point(tips)
    return GraspContacts(np.asarray(pts), np.asarray(n_out))
