"""URDF ``<mimic>`` joints: a joint that follows another's value.

An MJCF hand's couplings become mimic joints (:mod:`.couplings`); Pinocchio
models them exactly (one value in ``q`` moves both joints) but does not
expose the follower's axis, which the MuJoCo replay needs for its joint
equality: :func:`mimic_joints` reads it from the URDF text.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass

from dexplan.core.errors import ModelError, shorten

__all__ = ["MimicJoint", "mimic_joints"]


@dataclass(frozen=True)
class MimicJoint:
    """``q = multiplier * q[primary] + offset``.

    Attributes:
        primary: the joint it follows.
        multiplier: ``dq / dq[primary]``.
        offset: its value (rad, m) when the primary's is 0.
        kind: ``"revolute"`` or ``"prismatic"``.
        axis: its axis, in its own frame.
        lower: its lower limit.
        upper: its upper limit.
    """

    primary: str
    multiplier: float
    offset: float
    kind: str
    axis: tuple[float, float, float]
    lower: float
    upper: float


def _numbers(raw: str | None, default: str, n: int, what: str) -> list[float]:
    text = default if raw is None else raw
    try:
        vals = [float(t) for t in text.split()]
    except ValueError:
        vals = []
    if len(vals) != n or not all(math.isfinite(v) for v in vals):
        raise ModelError(f"{what} must be {n} finite numbers, got {shorten(raw)}")
    return vals


def mimic_joints(urdf_xml: str) -> dict[str, MimicJoint]:
    """The ``<mimic>`` joints of a URDF by name (none when the XML does not parse)."""
    try:
        root = ET.fromstring(urdf_xml)
    except ET.ParseError:
        return {}
    out = {}
    for joint in root.findall("joint"):
        mimic = joint.find("mimic")
        if mimic is None:
            continue
        name = joint.get("name", "")
        axis, limit = joint.find("axis"), joint.find("limit")
        xyz = _numbers(None if axis is None else axis.get("xyz"), "1 0 0", 3, f"{name!r} axis")
        lo, hi = (
            _numbers(limit.get(k), "0", 1, f"{name!r} limit {k}")[0] if limit is not None else 0.0
            for k in ("lower", "upper")
        )
        out[name] = MimicJoint(
            mimic.get("joint", ""),
            _numbers(mimic.get("multiplier"), "1", 1, f"{name!r} mimic multiplier")[0],
            _numbers(mimic.get("offset"), "0", 1, f"{name!r} mimic offset")[0],
            joint.get("type", "revolute"),
            (xyz[0], xyz[1], xyz[2]),
            lo,
            hi,
        )
    return out
