"""The fingertip side of a plan's contacts, and how far each contact travels on both surfaces.

A contact is one world point seen from two bodies: ``contacts`` gives it in
the object's frame, ``tip_contacts`` (format ``/2``) in the tip link's frame.
Here the tip side is recomputed from a waypoint's joints and object pose
alone (Pinocchio's forward kinematics), so the verifier never trusts the
file's numbers: rolling without slipping means the contact's paths on the
two surfaces have the same length (Montana's contact equations).
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import pairwise

import numpy as np
import pinocchio as pin

from dexplan.core.pose import length, quat_to_matrix
from dexplan.core.segments import Segment, Waypoint
from dexplan.core.typing import FloatArray
from dexplan.model.hand.hand import Hand

__all__ = ["contact_path_lengths", "tip_sides"]


def tip_sides(hand: Hand, w: Waypoint) -> list[FloatArray]:
    """Each contact of ``w`` in its tip link's frame, ``(3,)`` (zeros for a free finger).

    ``R_tip^T (x_obj + R_obj p_obj - c_tip)``, the tip frame's placement from
    the waypoint's joints.
    """
    pose = w.object_pose_xyzquat
    R = quat_to_matrix(pose[3:] / length(pose[3:]))
    pin.forwardKinematics(hand.model, hand.data, w.q)
    out = []
    for c, fid in zip(w.contacts, hand.tip_frame_ids, strict=True):
        if c is None:
            out.append(np.zeros(3))
            continue
        M = pin.updateFramePlacement(hand.model, hand.data, fid)
        out.append(M.rotation.T @ (pose[:3] + R @ np.asarray(c) - M.translation))
    return out


def contact_path_lengths(
    hand: Hand, seg: Segment, tips: Sequence[Sequence[FloatArray]] | None = None
) -> list[tuple[int, float, float]]:
    """Per contact finger of a transfer: ``(finger, on the fingertip (m), on the object (m))``.

    Each path is the polyline through the contact's places at the segment's
    waypoints (the verifier's step rule keeps them close, so chords and arcs
    agree to second order). ``tips``: the waypoints' :func:`tip_sides`, when
    the caller has them.
    """
    wps = seg.waypoints
    if tips is None:
        tips = [tip_sides(hand, w) for w in wps]
    out = []
    for i, c0 in enumerate(wps[0].contacts):
        if c0 is None:
            continue
        on_obj = sum(
            length(np.asarray(b.contacts[i], dtype=float) - np.asarray(a.contacts[i], dtype=float))
            for a, b in pairwise(wps)
        )
        on_tip = sum(length(tb[i] - ta[i]) for ta, tb in pairwise(tips))
        out.append((i, on_tip, on_obj))
    return out
