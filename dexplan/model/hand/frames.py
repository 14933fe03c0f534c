"""Fingers in a Pinocchio model: joint limits, fingertip frames and the joints moving each.

:class:`~dexplan.model.hand.hand.Hand` reads its fingers with these checks;
each raises a :class:`~dexplan.core.errors.ModelError` naming the hand.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from dexplan.core.errors import ModelError, shorten
from dexplan.core.typing import FloatArray

__all__ = [
    "finger_joint_indices",
    "fingertip_frame_id",
    "fingertip_list",
    "joint_limits",
    "joint_names",
]


def joint_names(model: pin.Model) -> tuple[str, ...]:
    """Names of the joints with a value of their own, in ``q`` order.

    A ``<mimic>`` joint follows another joint's value and has none (nq = 0).
    """
    return tuple(model.names[j] for j in range(1, model.njoints) if model.joints[j].nq > 0)


def joint_limits(
    model: pin.Model, joint_names: Sequence[str], name: str
) -> tuple[FloatArray, FloatArray]:
    """(nq,) lower and upper joint limits, checked finite and ordered.

    Raises:
        ModelError: a joint without finite limits or with lower > upper.
    """
    lower = np.array(model.lowerPositionLimit, dtype=float)
    upper = np.array(model.upperPositionLimit, dtype=float)
    for j, joint in enumerate(joint_names):
        lo, hi = lower[j], upper[j]
        if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi:
            raise ModelError(
                f"hand {name!r}: joint {joint!r} needs finite limits with lower <= upper, "
                f"got lower={lo!r}, upper={hi!r}"
            )
    return lower, upper


def fingertip_list(fingertip_frames: object, name: str) -> tuple[str, ...]:
    """The fingertip frame names as given: a list of at least 2, none repeated.

    Raises:
        ModelError: not a list, fewer than 2 frames, or a repeated frame.
    """
    if isinstance(fingertip_frames, str | bytes) or not isinstance(fingertip_frames, Sequence):
        raise ModelError(
            f"hand {name!r}: fingertip_frames must be a list of frame names, "
            f"got {shorten(fingertip_frames)}"
        )
    tips = list(fingertip_frames)
    if len(tips) < 2:
        raise ModelError(f"hand {name!r} needs at least 2 fingertip frames, got {shorten(tips)}")
    if len(set(map(repr, tips))) != len(tips):
        raise ModelError(f"hand {name!r}: fingertip_frames repeat a frame: {shorten(tips)}")
    return tuple(tips)


def fingertip_frame_id(model: pin.Model, tip: object, name: str) -> int:
    """Pinocchio frame id of the fingertip frame ``tip``.

    Raises:
        ModelError: ``tip`` is not the name of a frame of the model.
    """
    frames = [f.name for f in model.frames]
    if not isinstance(tip, str) or tip not in frames:
        # the candidates in full: links and operational frames (a tip frame is
        # one of those; joint frames and the universe only lengthen the line)
        candidates = [
            f.name
            for f in model.frames
            if f.type in (pin.FrameType.BODY, pin.FrameType.OP_FRAME) and f.name != "universe"
        ]
        close = difflib.get_close_matches(str(tip), candidates, n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise ModelError(
            f"unknown fingertip frame {shorten(tip)} in hand {name!r}{hint} "
            f"(links and frames: {', '.join(candidates)})"
        )
    return int(model.getFrameId(tip))


def finger_joint_indices(model: pin.Model, fid: int, tip: str) -> list[int]:
    """Sorted ``q`` indices of the joints between the root and frame ``fid``.

    Raises:
        ModelError: no joint moves the frame.
    """
    chain = []
    jid = model.frames[fid].parentJoint
    while jid > 0:
        if model.joints[jid].nq > 0:  # a mimic joint moves with its primary's value
            chain.append(model.joints[jid].idx_q)
        jid = model.parents[jid]
    chain.sort()
    if not chain:
        raise ModelError(f"fingertip frame {tip!r} is not moved by any joint")
    return chain
