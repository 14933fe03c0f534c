"""The builtin ``trifinger``: three example-robot-data ``finger_edu`` fingers, as on the platform.

The TriFinger platform (Wuthrich et al., CoRL 2020) hangs three identical
3-joint fingers from a frame, 120 degrees apart about the vertical, above the
object. :func:`trifinger_urdf` builds that hand from the single
``finger_edu.urdf`` example-robot-data ships:

- the world frame (the URDF's ``base_link``) is the floor's centre, z up; each
  finger's base frame sits :data:`TRIFINGER_BASE_HEIGHT` above it, its upper
  joint on a ring of radius :data:`TRIFINGER_RING_RADIUS` at ``90 + 120 k``
  degrees about z, the upper link's housing pointing outwards like a spoke
  (the finger's local +x towards the centre): the middle and lower joints
  bend the finger in the vertical plane through the centre, the upper joint
  swings that plane sideways. Links and joints carry the suffix ``_0``,
  ``_120``, ``_240`` as on the platform's own models;
- the fingertip frames ``finger_tip_link_<k>`` get the fingertip sphere of the
  real tip's radius (:data:`TRIFINGER_TIP_RADIUS`: the ``lower_link.stl``
  mesh ends in a hemisphere of that radius centred on the tip frame);
- the lower link's mesh, which is the fingertip's own rounded end, would touch
  the object wherever the tip does, so its collision element is a capsule along
  the shaft 1.7 mm slimmer than the mesh and ending 4 mm behind the tip centre
  (inside the tip sphere's front half); the upper and middle links and the
  base parts keep their ``package://example-robot-data/...`` meshes;
- the joint effort limits are the platform's motor torque cap
  (:data:`TRIFINGER_EFFORT_LIMIT`), not the URDF's placeholder 1000.
"""

from __future__ import annotations

import copy
import math
import xml.etree.ElementTree as ET

from dexplan.core.errors import ModelError

__all__ = [
    "FINGER_EDU_URDF",
    "TRIFINGER_BASE_HEIGHT",
    "TRIFINGER_EFFORT_LIMIT",
    "TRIFINGER_RING_RADIUS",
    "TRIFINGER_TIPS",
    "TRIFINGER_TIP_RADIUS",
    "trifinger_urdf",
]

#: The single finger's URDF below example-robot-data's ``robots/`` folder.
FINGER_EDU_URDF = "finger_edu_description/robots/finger_edu.urdf"
#: Fingertip frames, finger k at 120 k degrees about the vertical.
TRIFINGER_TIPS: tuple[str, ...] = (
    "finger_tip_link_0",
    "finger_tip_link_120",
    "finger_tip_link_240",
)
#: Fingertip radius (m): the hemisphere that ends ``lower_link.stl``.
TRIFINGER_TIP_RADIUS = 0.0095
#: Horizontal distance (m) of each upper joint's axis from the centre vertical.
TRIFINGER_RING_RADIUS = 0.0455
#: Height (m) of the finger bases above the floor (``finger_edu.urdf``'s base_to_finger).
TRIFINGER_BASE_HEIGHT = 0.283
#: Joint torque cap (N m): the platform's driver limits the motor current to
#: 2 A; torque constant 0.02 N m/A, gear ratio 9.
TRIFINGER_EFFORT_LIMIT = 2.0 * 0.02 * 9.0
# Lower link (link frame): the shaft is a 9.7 mm radius cylinder along -z at
# y = -8 mm from the joint to the tip centre at z = -160 mm.
_LOWER_CAPSULE_RADIUS = 0.008
_LOWER_CAPSULE_Z = (0.0, -0.156)
_TIP_Y = -0.008


def _renamed(elem: ET.Element, k: int, names: set[str]) -> ET.Element:
    """A copy of a link or joint with every link/joint name of ``names`` suffixed ``_<k>``.

    ``k`` is the finger's angle in degrees (0, 120, 240).
    """
    out = copy.deepcopy(elem)
    for e in out.iter():
        for attr in ("name", "link"):
            value = e.get(attr)
            if value in names and e.tag in ("link", "joint", "parent", "child"):
                e.set(attr, f"{value}_{k}")
    return out


def _lower_link_collision() -> ET.Element:
    """The lower link's capsule (dexplan's ``<capsule>`` form, along the link's z)."""
    z0, z1 = _LOWER_CAPSULE_Z
    col = ET.Element("collision")
    ET.SubElement(col, "origin", xyz=f"0 {_TIP_Y!r} {(z0 + z1) / 2!r}", rpy="0 0 0")
    geometry = ET.SubElement(col, "geometry")
    ET.SubElement(geometry, "capsule", radius=repr(_LOWER_CAPSULE_RADIUS), length=repr(z0 - z1))
    return col


def _tip_collision() -> ET.Element:
    """The fingertip sphere, centred on the tip frame."""
    col = ET.Element("collision")
    geometry = ET.SubElement(col, "geometry")
    ET.SubElement(geometry, "sphere", radius=repr(TRIFINGER_TIP_RADIUS))
    return col


def trifinger_urdf(finger_edu_xml: str) -> str:
    """The TriFinger URDF built from ``finger_edu.urdf``'s text (see the module docstring).

    Raises:
        ModelError: the text is not the finger_edu URDF this is written for.
    """
    try:
        finger = ET.fromstring(finger_edu_xml)
    except ET.ParseError as exc:
        raise ModelError(f"hand 'trifinger': malformed finger_edu URDF: {exc}") from None
    links = {e.get("name", ""): e for e in finger.findall("link")}
    joints = {e.get("name", ""): e for e in finger.findall("joint")}
    needed = {"base_link", "finger_base_link", "finger_lower_link", "finger_tip_link"}
    if not needed <= set(links) or "base_to_finger" not in joints:
        raise ModelError(
            f"hand 'trifinger': finger_edu URDF lacks {sorted(needed - set(links))} "
            "or joint 'base_to_finger'"
        )
    names = (set(links) | set(joints)) - {"base_link"}
    robot = ET.Element("robot", name="dexplan_trifinger")
    robot.append(copy.deepcopy(links["base_link"]))
    for k in (0, 120, 240):
        for name, link in links.items():
            if name == "base_link":
                continue
            new = _renamed(link, k, names)
            if name == "finger_lower_link":
                for col in new.findall("collision"):
                    new.remove(col)
                new.append(_lower_link_collision())
            elif name == "finger_tip_link":
                new.append(_tip_collision())
            robot.append(new)
        for name, joint in joints.items():
            new = _renamed(joint, k, names)
            if name == "base_to_finger":
                alpha = math.radians(90.0 + k)  # where on the ring
                x = TRIFINGER_RING_RADIUS * math.cos(alpha)
                y = TRIFINGER_RING_RADIUS * math.sin(alpha)
                origin = new.find("origin")
                if origin is None:
                    origin = ET.SubElement(new, "origin")
                origin.set("xyz", f"{x!r} {y!r} {TRIFINGER_BASE_HEIGHT!r}")
                # local +x towards the centre: the upper link points outwards
                origin.set("rpy", f"0 0 {alpha + math.pi!r}")
            limit = new.find("limit")
            if limit is not None:
                limit.set("effort", repr(TRIFINGER_EFFORT_LIMIT))
            robot.append(new)
    ET.indent(robot, space="  ")
    return ET.tostring(robot, encoding="unicode")
