"""Manipulation paths: waypoints and transfer/regrasp segments.

A manipulation path is an alternation of **transfer** segments (contacts fixed
in the object frame, the object moves) and **regrasp** segments (the object is
still, one finger leaves its contact and lands on another). Consecutive
segments share their boundary waypoint. These are the in-memory types; the plan
file (``dexplan.planfile.document``) serialises them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from dexplan.core.pose import length, quat_angle
from dexplan.core.typing import FloatArray


class SegmentKind(StrEnum):
    """What a segment does: a transfer moves the object, a regrasp moves one finger."""

    TRANSFER = "transfer"
    REGRASP = "regrasp"


@dataclass(frozen=True)
class Waypoint:
    """One configuration of hand and object.

    Attributes:
        object_pose_xyzquat: (7,) object pose in the world frame, XYZW.
        q: (nq,) hand joints in ``Hand.joint_names`` order.
        contacts: per finger, the contact point ``(3,)`` in the object frame,
            or None for a free finger.
    """

    object_pose_xyzquat: FloatArray
    q: FloatArray
    contacts: tuple[FloatArray | None, ...]

    def contact_mask(self) -> tuple[bool, ...]:
        """Per finger, True when it is in contact."""
        return tuple(c is not None for c in self.contacts)


@dataclass(frozen=True)
class Segment:
    """A transfer (``finger`` None) or a regrasp of ``finger``."""

    kind: SegmentKind
    finger: int | None
    waypoints: tuple[Waypoint, ...]

    @property
    def start(self) -> Waypoint:
        """First waypoint."""
        return self.waypoints[0]

    @property
    def end(self) -> Waypoint:
        """Last waypoint."""
        return self.waypoints[-1]


def count_kinds(segments: Sequence[Segment]) -> dict[str, int]:
    """Number of transfer and regrasp segments."""
    return {
        "transfers": sum(s.kind == "transfer" for s in segments),
        "regrasps": sum(s.kind == "regrasp" for s in segments),
    }


def joint_travel(segments: Sequence[Segment]) -> float:
    """Total hand joint travel over the plan: ``sum |q_{k+1} - q_k|_1`` (rad; m for prismatic)."""
    total = 0.0
    for s in segments:
        qs = np.array([w.q for w in s.waypoints], dtype=float)
        total += float(np.abs(np.diff(qs, axis=0)).sum())
    return total


def object_path_length(segments: Sequence[Segment]) -> tuple[float, float]:
    """Total object translation (m) and rotation (rad) over the transfers."""
    trans, rot = 0.0, 0.0
    for s in segments:
        for a, b in zip(s.waypoints, s.waypoints[1:], strict=False):
            pa, pb = a.object_pose_xyzquat, b.object_pose_xyzquat
            trans += length(pb[:3] - pa[:3])
            rot += quat_angle(pa[3:], pb[3:])
    return trans, rot
