"""``dexplan info``: the builtin hand, the default object and dependency versions."""

from __future__ import annotations

import sys

from dexplan.cli.console import ExitCode, dist_version
from dexplan.cli.options import InfoOptions
from dexplan.model.hand.hand import Hand
from dexplan.model.objects import Sphere

__all__ = ["run"]

DEPENDENCIES = ("ompl", "pin", "coal", "osqp", "numpy", "scipy", "trimesh", "rerun-sdk")
"""The distributions whose versions ``info`` lists."""


def run(opts: InfoOptions) -> int:
    """Print the builtin hand, the default object and dependency versions."""
    hand = Hand.builtin(opts.hand)
    out = sys.stdout
    out.write(f"dexplan {dist_version('dexplan')}\n")
    out.write(
        f"hand: {hand.name}: {hand.n_fingers} fingers, {hand.nq} joints, "
        f"fingertip radius {hand.fingertip_radius} m\n"
    )
    for i, idx in enumerate(hand.finger_q_index):
        joints = ", ".join(
            f"{hand.joint_names[j]} [{hand.lower[j]:+.2f}, {hand.upper[j]:+.2f}]" for j in idx
        )
        out.write(f"  finger {i} ({hand.fingertip_frames[i]}): {joints}\n")
    obj = Sphere(0.04)
    out.write(f"object: {obj.to_dict()}\n")
    for dist in DEPENDENCIES:
        out.write(f"{dist}: {dist_version(dist)}\n")
    return ExitCode.OK
