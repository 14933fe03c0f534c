"""A hand cut out of a robot's URDF: the links and joints below one root link.

Robot descriptions ship their hands inside the whole robot (example-robot-data's
Unitree G1 with its Dex3 hands, Alex with PSYONIC hands). dexplan plans for a
fixed palm, so :func:`extract_hand` keeps the subtree below a chosen link (the
palm, or a wrist link) and drops the rest of the robot: arms, legs and the other
hand, their joints and anything that names them (transmissions, Gazebo tags).
The chosen link becomes the URDF's root, fixed at the world origin (the
scenario's palm frame). The result is URDF text, so a plan file carries the hand
alone and is checked without the robot's file.
"""

from __future__ import annotations

import difflib
import xml.etree.ElementTree as ET
from pathlib import Path

from dexplan.core.errors import ModelError, shorten
from dexplan.core.files import read_input_file
from dexplan.model.hand.urdf import urdf_text

__all__ = ["extract_hand", "read_urdf"]

#: Top-level URDF elements kept beside the subtree's links and joints (named
#: materials: links refer to them by name).
_KEPT_TAGS = frozenset({"material"})


def _child_joints(root: ET.Element) -> dict[str, list[ET.Element]]:
    """Joints by parent link name, in file order."""
    out: dict[str, list[ET.Element]] = {}
    for joint in root.findall("joint"):
        parent = joint.find("parent")
        if parent is not None:
            out.setdefault(parent.get("link", ""), []).append(joint)
    return out


def extract_hand(urdf_xml: str, root_link: str, *, what: str = "hand") -> str:
    """The URDF text of the subtree below ``root_link``, which becomes the root.

    Args:
        urdf_xml: the whole robot's URDF text.
        root_link: the link the hand hangs from (its palm or wrist link).
        what: the hand named in error messages.

    Returns:
        URDF text with the links reachable from ``root_link`` through child
        joints, those joints, and the robot's named materials; the robot's
        name is kept.

    Raises:
        ModelError: malformed XML, ``root_link`` not a link of the URDF (with
            the closest name), or no movable joint below it.
    """
    try:
        robot = ET.fromstring(urdf_xml)
    except ET.ParseError as exc:
        raise ModelError(f"{what}: malformed URDF XML: {exc}") from None
    links = {link.get("name", ""): link for link in robot.findall("link")}
    if root_link not in links:
        close = difflib.get_close_matches(root_link, list(links), n=1, cutoff=0.5)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise ModelError(
            f"{what}: hand.root_link {shorten(root_link)} is not a link of the URDF{hint}"
        )
    below = _child_joints(robot)
    kept_links, kept_joints = [root_link], []
    stack = [root_link]
    while stack:  # depth first; a URDF is a tree, so every link is reached once
        for joint in below.get(stack.pop(), []):
            child = joint.find("child")
            name = "" if child is None else child.get("link", "")
            if name in links and name not in kept_links:
                kept_joints.append(joint)
                kept_links.append(name)
                stack.append(name)
    if all(j.get("type") == "fixed" for j in kept_joints):
        raise ModelError(
            f"{what}: hand.root_link {root_link!r} has no movable joint below it "
            "(give the link the fingers hang from, such as the palm)"
        )
    out = ET.Element("robot", name=robot.get("name", "robot"))
    out.extend(e for e in robot if e.tag in _KEPT_TAGS)
    keep = set(kept_links)
    out.extend(link for name, link in links.items() if name in keep)
    out.extend(kept_joints)
    ET.indent(out, space="  ")
    return ET.tostring(out, encoding="unicode")


def read_urdf(path: Path, root_link: str | None = None) -> str:
    """The URDF text of file ``path``; with ``root_link``, the hand below that link.

    Raises:
        ModelError: the file is missing, unreadable or not UTF-8 text, or
            :func:`extract_hand` refuses ``root_link``.
    """
    text = urdf_text(read_input_file(path, "URDF", ModelError), f"URDF file {str(path)!r}")
    return text if root_link is None else extract_hand(text, root_link, what=f"hand {path.stem!r}")
