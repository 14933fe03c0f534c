"""The builtin ``dex3``: the Unitree G1's right Dex3 hand, cut out of the robot's URDF.

example-robot-data ships the G1 humanoid with its two Dex3 hands
(``g1_29dof_with_hand_rev_1_0.urdf``). :func:`dex3_urdf` builds the right hand
from that file:

- the subtree below ``right_hand_palm_link`` is kept
  (:func:`~dexplan.model.hand.extract.extract_hand`): a thumb of 3 joints
  (``right_hand_thumb_0..2_joint``: one about the palm's y axis, two parallel
  ones about z) and an index and a middle finger of **2 joints** each, both
  about the palm's z axis, so each of these fingertips moves in a plane
  (z = +-28.5 mm in the palm frame);
- the palm is mounted palm-up (:data:`DEX3_MOUNT_RPY`): the fingers point
  along the world's +x, curl towards +z, and their flexion axes lie along the
  world's -y;
- each distal link gets a fingertip frame ``right_hand_<finger>_tip`` at the
  centre of its rounded end, :data:`DEX3_TIP_OFFSET` along the link, with a
  sphere of :data:`DEX3_TIP_RADIUS` (the distal meshes are 17.8 mm thick
  across the pad and taper to the tip);
- the distal meshes cover the tip spheres, so they would touch the object
  wherever a fingertip does: their collision elements are two capsules
  1.5 mm slimmer than the tip sphere, one along the shaft ending 10 mm behind
  the tip centre, one across the finger's width; the palm, the thumb's base
  and the proximal links keep their ``package://example-robot-data/...`` meshes.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

from dexplan.core.errors import ModelError
from dexplan.model.hand.extract import extract_hand

__all__ = [
    "DEX3_MOUNT_RPY",
    "DEX3_ROOT_LINK",
    "DEX3_TIPS",
    "DEX3_TIP_OFFSET",
    "DEX3_TIP_RADIUS",
    "G1_URDF",
    "dex3_urdf",
]

#: The G1 with hands, below example-robot-data's ``robots/`` folder.
G1_URDF = "g1_description/urdf/g1_29dof_with_hand_rev_1_0.urdf"
#: The link the right hand hangs from.
DEX3_ROOT_LINK = "right_hand_palm_link"
#: Fingertip frames: thumb (3 joints), index and middle (2 joints each).
DEX3_TIPS: tuple[str, ...] = (
    "right_hand_thumb_tip",
    "right_hand_index_tip",
    "right_hand_middle_tip",
)
#: Fingertip radius (m): about half the distal link's thickness across the pad.
DEX3_TIP_RADIUS = 0.009
#: Distance (m) of the tip centre from the distal joint, along the distal link
#: (the mesh ends 52 mm from the joint).
DEX3_TIP_OFFSET = 0.040
#: Palm-up mounting (URDF fixed-axis roll, pitch, yaw): the palm's +y (the
#: side the fingers curl to) becomes the world's +z.
DEX3_MOUNT_RPY = (math.pi / 2, 0.0, 0.0)
_CAPSULE_RADIUS = 0.0075
# distal shaft: from 4 mm to 30 mm along the link (the cap ends 2.5 mm behind
# the tip centre, inside the sphere's back half)
_SHAFT = (0.004, 0.030)
# across the width (the mesh is 26 mm wide): at 18 mm along the link
_CROSS_AT, _CROSS_HALF = 0.018, 0.0045
#: per distal link: its tip frame and the link's axis (the thumb's distal link
#: points along its y, the fingers' along x)
_DISTAL = {
    "right_hand_thumb_2_link": ("right_hand_thumb_tip", 1),
    "right_hand_index_1_link": ("right_hand_index_tip", 0),
    "right_hand_middle_1_link": ("right_hand_middle_tip", 0),
}
# rpy turning a capsule's z axis onto the link's x or y axis
_ALONG = {0: "0 1.5707963267948966 0", 1: "-1.5707963267948966 0 0"}


def _xyz(axis: int, along: float, z: float = 0.0) -> str:
    """A point ``along`` the link's ``axis`` (0: x, 1: y), ``z`` along its z."""
    p = [0.0, 0.0, z]
    p[axis] = along
    return " ".join(repr(v) for v in p)


def _capsule(xyz: str, rpy: str, length: float) -> ET.Element:
    """A dexplan ``<capsule>`` collision element (axis: local z after ``rpy``)."""
    col = ET.Element("collision")
    ET.SubElement(col, "origin", xyz=xyz, rpy=rpy)
    geometry = ET.SubElement(col, "geometry")
    ET.SubElement(geometry, "capsule", radius=repr(_CAPSULE_RADIUS), length=repr(length))
    return col


def _distal_collisions(axis: int) -> list[ET.Element]:
    """The distal link's two capsules (see the module docstring)."""
    lo, hi = _SHAFT
    return [
        _capsule(_xyz(axis, (lo + hi) / 2), _ALONG[axis], hi - lo),
        _capsule(_xyz(axis, _CROSS_AT), "0 0 0", 2 * _CROSS_HALF),
    ]


def _tip(distal: str, tip: str, axis: int) -> tuple[ET.Element, ET.Element]:
    """The tip link (with its sphere) and the fixed joint placing it on ``distal``."""
    link = ET.Element("link", name=tip)
    col = ET.SubElement(link, "collision")
    ET.SubElement(ET.SubElement(col, "geometry"), "sphere", radius=repr(DEX3_TIP_RADIUS))
    joint = ET.Element("joint", name=f"{tip}_joint", type="fixed")
    ET.SubElement(joint, "origin", xyz=_xyz(axis, DEX3_TIP_OFFSET), rpy="0 0 0")
    ET.SubElement(joint, "parent", link=distal)
    ET.SubElement(joint, "child", link=tip)
    return link, joint


def dex3_urdf(g1_xml: str) -> str:
    """The right Dex3 hand's URDF built from the G1's (see the module docstring).

    Unmounted: the palm link is the root (``Hand`` callers mount it with
    :data:`DEX3_MOUNT_RPY`).

    Raises:
        ModelError: the text is not the G1 URDF this is written for.
    """
    robot = ET.fromstring(extract_hand(g1_xml, DEX3_ROOT_LINK, what="hand 'dex3'"))
    links = {e.get("name", ""): e for e in robot.findall("link")}
    missing = sorted(set(_DISTAL) - set(links))
    if missing:
        raise ModelError(f"hand 'dex3': the G1 URDF lacks the distal links {missing}")
    for distal, (tip, axis) in _DISTAL.items():
        link = links[distal]
        for col in link.findall("collision"):
            link.remove(col)
        link.extend(_distal_collisions(axis))
        robot.extend(_tip(distal, tip, axis))
    ET.indent(robot, space="  ")
    return ET.tostring(robot, encoding="unicode")
