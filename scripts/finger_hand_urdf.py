"""URDF text of a palm with identical 3-joint fingers (the builtin generated hands).

Shared by ``scripts/make_paper_hand.py`` and ``scripts/make_three_finger_hand.py``:
each finger sits on a circle around the palm's vertical axis and has an abduction
joint about its radial axis, two flexion joints that bend it towards that axis,
and a spherical fingertip (frame ``f<i>_tip`` at its centre). The scripts choose
the dimensions, limits and collision shapes of the phalanges and the palm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class FingerLayout:
    """Dimensions (m) and joint limits (rad) shared by every finger of a hand.

    Attributes:
        base_radius: radius of the circle of finger bases, palm frame.
        knuckle_height: flexion axis height above the palm.
        l_proximal: proximal phalanx length, flexion axis to flexion axis.
        l_distal: distal phalanx length, flexion axis to fingertip centre.
        tip_radius: fingertip sphere radius.
        abduction: (lower, upper) limits of the abduction joint.
        mcp: (lower, upper) limits of the first flexion joint.
        pip: (lower, upper) limits of the second flexion joint.
        base_format: format of the base's x and y in the URDF (``"!r"`` or ``".9f"``).
    """

    base_radius: float
    knuckle_height: float
    l_proximal: float
    l_distal: float
    tip_radius: float
    abduction: tuple[float, float]
    mcp: tuple[float, float]
    pip: tuple[float, float]
    base_format: str = "!r"


def inertial(mass: float) -> str:
    """An ``<inertial>`` element: ``mass`` (kg) with a small diagonal inertia."""
    i = mass * 1e-4
    return (
        f'<inertial><mass value="{mass}"/><origin xyz="0 0 0"/>'
        f'<inertia ixx="{i}" ixy="0" ixz="0" iyy="{i}" iyz="0" izz="{i}"/></inertial>'
    )


def _coordinate(value: float, fmt: str) -> str:
    return repr(value) if fmt == "!r" else format(value, fmt)


def _flexion(name: str, parent: str, child: str, z: float, limits: tuple[float, float]) -> str:
    """A flexion joint about the parent's -y axis, ``z`` (m) above its origin."""
    return f"""  <joint name="{name}" type="revolute">
    <parent link="{parent}"/><child link="{child}"/>
    <origin xyz="0 0 {z}"/>
    <axis xyz="0 -1 0"/><limit lower="{limits[0]}" upper="{limits[1]}" effort="1" velocity="2"/>
  </joint>"""


def finger_urdf(
    i: int, azimuth_deg: float, layout: FingerLayout, proximal: str, distal: str
) -> str:
    """Joints and links of finger ``i`` (``f<i>_abd``, ``f<i>_mcp``, ``f<i>_pip``).

    Args:
        i: finger index (names its joints and links).
        azimuth_deg: azimuth of the finger's base on the base circle (degrees).
        layout: the hand's finger dimensions and limits.
        proximal: the proximal link's ``<collision>`` element(s).
        distal: the distal link's ``<collision>`` element(s).
    """
    a = math.radians(azimuth_deg)
    x, y = layout.base_radius * math.cos(a), layout.base_radius * math.sin(a)
    xs, ys = _coordinate(x, layout.base_format), _coordinate(y, layout.base_format)
    kh, abd, mcp, pip = layout.knuckle_height, layout.abduction, layout.mcp, layout.pip
    return f"""
  <joint name="f{i}_abd" type="revolute">
    <parent link="palm"/><child link="f{i}_knuckle"/>
    <origin xyz="{xs} {ys} 0" rpy="0 0 {a!r}"/>
    <axis xyz="1 0 0"/>
    <limit lower="{abd[0]}" upper="{abd[1]}" effort="1" velocity="2"/>
  </joint>
  <link name="f{i}_knuckle">{inertial(0.01)}
    <collision><origin xyz="0 0 {kh / 2:.6f}"/>
      <geometry><box size="0.014 0.014 {kh:.6f}"/></geometry></collision>
  </link>
{_flexion(f"f{i}_mcp", f"f{i}_knuckle", f"f{i}_proximal", kh, mcp)}
  <link name="f{i}_proximal">{inertial(0.02)}
    {proximal}
  </link>
{_flexion(f"f{i}_pip", f"f{i}_proximal", f"f{i}_distal", layout.l_proximal, pip)}
  <link name="f{i}_distal">{inertial(0.015)}
    {distal}
  </link>
  <joint name="f{i}_tip_joint" type="fixed">
    <parent link="f{i}_distal"/><child link="f{i}_tip"/>
    <origin xyz="0 0 {layout.l_distal}"/>
  </joint>
  <link name="f{i}_tip">{inertial(0.005)}
    <collision><geometry><sphere radius="{layout.tip_radius}"/></geometry></collision>
  </link>"""


def hand_urdf(robot: str, comment: str, palm_collision: str, fingers: str) -> str:
    """The whole URDF: a ``palm`` link (0.3 kg) with ``palm_collision``, then ``fingers``."""
    return f"""<?xml version="1.0"?>
<!-- {comment} -->
<robot name="{robot}">
  <link name="palm">{inertial(0.3)}
    {palm_collision}
  </link>{fingers}
</robot>
"""
