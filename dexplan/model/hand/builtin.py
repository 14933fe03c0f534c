"""The builtin hands: the URDF, fingertips and mounting each is built from.

``"paper"`` (4 x 3 DOF, after the paper) and ``"three_finger"`` (3 x 3 DOF,
capsule links) ship with dexplan; ``"trifinger"`` (3 x 3 DOF, the TriFinger
platform, :mod:`.trifinger`) is built from example-robot-data's finger_edu;
``"dex3"`` (a 3-joint thumb and two 2-joint fingers, :mod:`.dex3`) is cut out
of example-robot-data's Unitree G1; ``"allegro"`` and ``"allegro_left"``
(4 x 4 DOF) are read from the installed ``example-robot-data`` distribution,
given the real hand's joint torque caps (:data:`ALLEGRO_EFFORT_LIMITS`) and
collision shapes fitted to its visual meshes (:data:`ALLEGRO_COLLISION_SHAPES`),
and mounted palm-up (see :data:`ALLEGRO_MOUNT_RPY`).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import StrEnum
from importlib import metadata, resources
from pathlib import Path
from typing import Literal

from dexplan.core.errors import DependencyError, InvalidInputError, ModelError, shorten
from dexplan.model.hand.dex3 import DEX3_MOUNT_RPY, DEX3_TIP_RADIUS, DEX3_TIPS, G1_URDF, dex3_urdf
from dexplan.model.hand.trifinger import (
    FINGER_EDU_URDF,
    TRIFINGER_TIP_RADIUS,
    TRIFINGER_TIPS,
    trifinger_urdf,
)
from dexplan.model.hand.urdf import mount_urdf, urdf_text, with_effort_limits

#: Frames the builtin hands use for their fingertips.
PAPER_HAND_TIPS: tuple[str, ...] = ("f0_tip", "f1_tip", "f2_tip", "f3_tip")
PAPER_HAND_TIP_RADIUS = 0.012
THREE_FINGER_TIPS: tuple[str, ...] = ("f0_tip", "f1_tip", "f2_tip")
THREE_FINGER_TIP_RADIUS = 0.012
#: Allegro fingers: index, middle, ring, thumb. The joints follow Pinocchio's
#: order (index q[0:4], thumb q[4:8], middle q[8:12], ring q[12:16]).
ALLEGRO_TIPS: tuple[str, ...] = ("link_3.0_tip", "link_7.0_tip", "link_11.0_tip", "link_15.0_tip")
ALLEGRO_TIP_RADIUS = 0.012
#: Pairs not checked: the palm's shapes leave room for the thumb's base, and
#: link_13.0 stays 7.5 mm or more from them over the joint ranges.
ALLEGRO_COLLISION_EXCLUDE: tuple[tuple[str, str], ...] = (("palm_link", "link_13.0"),)
#: Roll, pitch, yaw (URDF fixed-axis XYZ) of palm_link in the world frame: the
#: palm normal (palm_link +x) is world +z, the fingers (palm_link +z) point
#: along world +x, palm_link +y is world -y. palm_link's origin is the world origin.
ALLEGRO_MOUNT_RPY: tuple[float, float, float] = (math.pi, -math.pi / 2, 0.0)

# The Allegro URDF's effort="15" is a placeholder. Wonik Robotics' driver
# (github.com/simlabrobotics/allegro_hand_ros_v4,
# src/allegro_hand_driver/src/AllegroHandDrv.cpp) sends each joint torque as a
# motor PWM duty, PWM = tau * 1200 on a v4 hand (12 V, global PWM cap 1200), and
# clips it per joint at PWM_LIMIT_ROLL/NEAR/MIDDLE/FAR (index, middle, ring:
# 250, 450, 300, 190, times 1.5) and PWM_LIMIT_THUMB_* (350, 270, 180, 180, times
# 1.5), in URDF joint order (abduction or thumb roll first). Those caps are the
# largest torques the hand applies.
_ALLEGRO_PWM_PER_NM = 1200.0
_ALLEGRO_FINGER_PWM_CAPS = (250.0 * 1.5, 450.0 * 1.5, 300.0 * 1.5, 190.0 * 1.5)
_ALLEGRO_THUMB_PWM_CAPS = (350.0 * 1.5, 270.0 * 1.5, 180.0 * 1.5, 180.0 * 1.5)
#: Joint torque caps of the Allegro hand (N m) by URDF joint name: 0.3125,
#: 0.5625, 0.375, 0.2375 for joint_0.0-3.0 (index), 4.0-7.0 (middle) and
#: 8.0-11.0 (ring); 0.4375, 0.3375, 0.225, 0.225 for joint_12.0-15.0 (thumb).
ALLEGRO_EFFORT_LIMITS: dict[str, float] = {
    f"joint_{first + k}.0": cap / _ALLEGRO_PWM_PER_NM
    for first, caps in (
        (0, _ALLEGRO_FINGER_PWM_CAPS),
        (4, _ALLEGRO_FINGER_PWM_CAPS),
        (8, _ALLEGRO_FINGER_PWM_CAPS),
        (12, _ALLEGRO_THUMB_PWM_CAPS),
    )
    for k, cap in enumerate(caps)
}


@dataclass(frozen=True)
class CollisionShape:
    """A box or capsule ``<collision>`` element of a link, in the link frame.

    Attributes:
        kind: ``"box"`` (axis-aligned) or ``"capsule"`` (along the link's z axis).
        size: the box's edge lengths (x, y, z), or the capsule's radius and
            length, the distance between its cap centres (m).
        xyz: centre (m).
    """

    kind: Literal["box", "capsule"]
    size: tuple[float, ...]
    xyz: tuple[float, float, float]

    def mirrored(self) -> CollisionShape:
        """The shape mirrored through the link's x-z plane (y to -y)."""
        x, y, z = self.xyz
        return CollisionShape(self.kind, self.size, (x, -y if y else 0.0, z))

    def element(self) -> ET.Element:
        """The URDF ``<collision>`` element (a capsule in dexplan's ``<capsule>`` form)."""
        col = ET.Element("collision")
        ET.SubElement(col, "origin", xyz=" ".join(map(repr, self.xyz)), rpy="0 0 0")
        geometry = ET.SubElement(col, "geometry")
        if self.kind == "box":
            ET.SubElement(geometry, "box", size=" ".join(map(repr, self.size)))
        else:
            ET.SubElement(geometry, "capsule", radius=repr(self.size[0]), length=repr(self.size[1]))
        return col


def _box(lo_mm: Sequence[float], hi_mm: Sequence[float]) -> CollisionShape:
    """The box between corners ``lo_mm`` and ``hi_mm`` (link frame, mm)."""
    size = tuple(round((h - lo) / 1000.0, 6) for lo, h in zip(lo_mm, hi_mm, strict=True))
    x, y, z = (round((h + lo) / 2000.0, 6) for lo, h in zip(lo_mm, hi_mm, strict=True))
    return CollisionShape("box", size, (x, y, z))


def _capsule_z(radius_mm: float, z0_mm: float, z1_mm: float) -> CollisionShape:
    """The capsule of radius ``radius_mm`` whose cap centres are (0, 0, z0) and (0, 0, z1) (mm)."""
    size = (round(radius_mm / 1000.0, 6), round((z1_mm - z0_mm) / 1000.0, 6))
    return CollisionShape("capsule", size, (0.0, 0.0, round((z0_mm + z1_mm) / 2000.0, 6)))


# Knuckle links (link_0/4/8/13.0): the mesh's palmar face bevels towards the
# next joint, so the box's palmar face sits 1.8 mm inside the mesh's (x = 8 mm).
_ALLEGRO_KNUCKLE = _box((-9.8, -13.45, 0.0), (8.0, 13.45, 16.4))
# Distal links: a capsule as thick as the phalanx (19.6 mm) from behind the
# joint to the fingertip centre. There it lies 2.2 mm inside the 12 mm
# fingertip sphere, more than the 1 mm contact penetration tolerated, so a
# fingertip touching the object anywhere on its front half leaves the distal
# link clear. The URDF's 27.5 mm wide box reached the fingertip centre and its
# edges stood 3.9 mm out of the fingertip. The side plates of the link's mesh
# (27 mm wide, up to 11 mm behind the fingertip centre) are left 3.7 mm
# uncovered on each side: no shape wider than the fingertip fits there.
_ALLEGRO_DISTAL = _capsule_z(9.8, 5.3, 26.7)
#: Collision shapes fitted to the Allegro right hand's visual meshes, replacing
#: the URDF's boxes of these links (the left hand's are mirrored, y to -y). The
#: other links keep the URDF's boxes, which follow their meshes to within
#: 2.1 mm. tests/test_allegro_model.py checks every shape against the meshes.
ALLEGRO_COLLISION_SHAPES: dict[str, tuple[CollisionShape, ...]] = {
    # The palm mesh is 107-113 mm wide only next to the knuckles: below them it
    # is open on the thumb side (the thumb's base turns there) down to a 58 mm
    # wide wrist. The URDF's single box stood up to 25 mm out of it. Three boxes
    # (each adds a collision pair per other link) leave the lower corner's
    # rounding, between the second and the wrist box, uncovered.
    "palm_link": (
        _box((-29.5, -54.5, -44.0), (11.3, 54.5, -2.0)),
        _box((-29.5, -49.0, -77.0), (11.3, 1.5, -44.0)),
        _box((-29.5, -29.0, -95.0), (11.3, 29.0, -84.0)),
    ),
    # The thumb's base is L-shaped: the URDF's box stood 9.9 mm out of its corner.
    "link_12.0": (
        _box((-35.8, -5.0, -6.0), (0.0, 15.0, 37.25)),
        _box((-35.8, -6.0, -6.0), (0.0, 26.0, 13.0)),
    ),
    "link_13.0": (_box((-9.8, -13.45, 0.0), (8.0, 13.45, 17.7)),),
    **{f"link_{k}.0": (_ALLEGRO_KNUCKLE,) for k in (0, 4, 8)},
    **{f"link_{k}.0": (_ALLEGRO_DISTAL,) for k in (3, 7, 11)},
    # The thumb's distal link is longer: fingertip centre 42.3 mm from its joint.
    "link_15.0": (_capsule_z(9.8, 1.0, 42.3),),
}


class BuiltinHandName(StrEnum):
    """Names of the builtin hands (``hand.builtin``; members equal their strings)."""

    PAPER = "paper"
    THREE_FINGER = "three_finger"
    ALLEGRO = "allegro"
    ALLEGRO_LEFT = "allegro_left"
    TRIFINGER = "trifinger"
    DEX3 = "dex3"


#: The builtin hands' names.
BUILTIN_HANDS: tuple[BuiltinHandName, ...] = tuple(BuiltinHandName)


@dataclass(frozen=True)
class BuiltinHand:
    """The arguments a builtin hand is built from (see :class:`~dexplan.model.hand.hand.Hand`).

    Attributes:
        urdf_xml: full URDF text, mounted in the palm frame.
        fingertip_frames: one frame name per finger.
        fingertip_radius: radius of the fingertip spheres (m).
        name: the builtin name.
        collision_exclude: link-name pairs never checked against each other.
        package_dirs: directories searched for mesh files.
    """

    urdf_xml: str
    fingertip_frames: tuple[str, ...]
    fingertip_radius: float
    name: str
    collision_exclude: tuple[tuple[str, str], ...] = ()
    package_dirs: tuple[str, ...] = ()


def builtin_hand(name: str) -> BuiltinHand:
    """The builtin hand ``name`` (one of :data:`BUILTIN_HANDS`).

    Raises:
        InvalidInputError: unknown name.
        DependencyError: an Allegro hand without ``example-robot-data``.
    """
    if name == "paper":
        text = _data_text("paper_hand.urdf")
        return BuiltinHand(text, PAPER_HAND_TIPS, PAPER_HAND_TIP_RADIUS, "paper")
    if name == "three_finger":
        text = _data_text("three_finger.urdf")
        return BuiltinHand(text, THREE_FINGER_TIPS, THREE_FINGER_TIP_RADIUS, "three_finger")
    if name in ("allegro", "allegro_left"):
        return _allegro_hand(left=name == "allegro_left")
    if name == "trifinger":
        return _trifinger_hand()
    if name == "dex3":
        return _dex3_hand()
    raise InvalidInputError(
        f"hand.builtin must be one of {[str(h) for h in BUILTIN_HANDS]}, got {shorten(name)}"
    )


def _data_text(filename: str) -> str:
    """Text of ``dexplan/data/hands/<filename>``."""
    return resources.files("dexplan").joinpath(f"data/hands/{filename}").read_text(encoding="utf-8")


# -------------------------------------------------------------- Allegro hands
_ERD = "example-robot-data"
_ERD_PIP = "pip install 'dexplan[allegro]' (or: pip install example-robot-data)"


def example_robot_data_share(robot_file: Path | None = None) -> Path:
    """The folder ``package://example-robot-data/robots/...`` mesh URIs resolve against.

    Args:
        robot_file: a file of the distribution,
            ``.../share/example-robot-data/robots/<robot>/<folder>/<file>``
            (default: the Allegro right hand's URDF).

    Raises:
        DependencyError: example-robot-data is not installed.
    """
    if robot_file is None:
        robot_file = example_robot_data_file(
            "allegro_hand_description/urdf/allegro_right_hand.urdf"
        )
    return robot_file.parents[4]


def example_robot_data_file(relative: str) -> Path:
    """Path of a file the installed ``example-robot-data`` distribution ships.

    example-robot-data 4.4 and later install no Python module, only files under
    ``<site-packages>/cmeel.prefix/share/example-robot-data/robots/``; they are
    found through the distribution's file list (``importlib.metadata``).

    Args:
        relative: path below ``robots/``, e.g.
            ``"allegro_hand_description/urdf/allegro_right_hand.urdf"``.

    Raises:
        DependencyError: the distribution is not installed or lacks the file.
    """
    try:
        dist = metadata.distribution(_ERD)
    except metadata.PackageNotFoundError:
        raise DependencyError(f"{_ERD} is not installed: {_ERD_PIP}") from None
    suffix = f"robots/{relative}"
    candidates = [
        Path(str(dist.locate_file(f))) for f in dist.files or () if str(f).endswith(suffix)
    ]
    candidates.append(Path(str(dist.locate_file(f"cmeel.prefix/share/{_ERD}/robots/{relative}"))))
    for path in candidates:
        if path.is_file():
            return path
    raise DependencyError(
        f"{_ERD} {dist.version} is installed but has no {relative!r}: "
        "pip install --upgrade 'dexplan[allegro]'"
    )


def _erd_urdf(relative: str, hand_name: str) -> tuple[str, Path]:
    """The text and path of the example-robot-data URDF a builtin hand is built from.

    Raises:
        DependencyError: naming the hand, when example-robot-data or the file is missing.
    """
    try:
        path = example_robot_data_file(relative)
    except DependencyError as exc:
        raise DependencyError(f"hand {hand_name!r}: {exc}") from None
    return urdf_text(path.read_bytes(), f"URDF file {str(path)!r}"), path


def _allegro_hand(*, left: bool) -> BuiltinHand:
    """The Allegro right (or left) hand from example-robot-data, mounted palm-up."""
    hand_name = "allegro_left" if left else "allegro"
    side = "left" if left else "right"
    text, path = _erd_urdf(f"allegro_hand_description/urdf/allegro_{side}_hand.urdf", hand_name)
    text = with_effort_limits(text, ALLEGRO_EFFORT_LIMITS, what=f"hand {hand_name!r}")
    shapes = {
        link: tuple(s.mirrored() for s in link_shapes) if left else link_shapes
        for link, link_shapes in ALLEGRO_COLLISION_SHAPES.items()
    }
    text = with_collision_shapes(text, shapes, what=f"hand {hand_name!r}")
    return BuiltinHand(
        mount_urdf(text, ALLEGRO_MOUNT_RPY),
        ALLEGRO_TIPS,
        ALLEGRO_TIP_RADIUS,
        hand_name,
        collision_exclude=ALLEGRO_COLLISION_EXCLUDE,
        package_dirs=(str(example_robot_data_share(path)),),
    )


def _trifinger_hand() -> BuiltinHand:
    """The TriFinger from example-robot-data's finger_edu (:mod:`.trifinger`)."""
    text, path = _erd_urdf(FINGER_EDU_URDF, "trifinger")
    return BuiltinHand(
        trifinger_urdf(text),
        TRIFINGER_TIPS,
        TRIFINGER_TIP_RADIUS,
        "trifinger",
        package_dirs=(str(example_robot_data_share(path)),),
    )


def _dex3_hand() -> BuiltinHand:
    """The G1's right Dex3 hand from example-robot-data, mounted palm-up (:mod:`.dex3`)."""
    text, path = _erd_urdf(G1_URDF, "dex3")
    return BuiltinHand(
        mount_urdf(dex3_urdf(text), DEX3_MOUNT_RPY),
        DEX3_TIPS,
        DEX3_TIP_RADIUS,
        "dex3",
        package_dirs=(str(example_robot_data_share(path)),),
    )


def with_collision_shapes(
    urdf_xml: str, shapes: Mapping[str, Sequence[CollisionShape]], *, what: str = "URDF"
) -> str:
    """The URDF text with the ``<collision>`` elements of some links replaced.

    Args:
        urdf_xml: URDF text.
        shapes: the new collision shapes, by link name (other links keep theirs).
        what: the hand named in error messages.

    Returns:
        The URDF text (comments kept); each rewritten link says so in a comment.

    Raises:
        ModelError: malformed XML, or a link name the URDF has not.
    """
    try:
        root = ET.fromstring(
            urdf_xml, parser=ET.XMLParser(target=ET.TreeBuilder(insert_comments=True))
        )
    except ET.ParseError as exc:
        raise ModelError(f"{what}: malformed URDF XML: {exc}") from None
    links = {link.get("name", ""): link for link in root.iter("link")}
    for name, link_shapes in shapes.items():
        link = links.get(name)
        if link is None:
            raise ModelError(f"{what}: the URDF has no link {name!r} to give collision shapes")
        for col in link.findall("collision"):
            link.remove(col)
        if len(link):
            link[-1].tail = "\n    "
        link.append(ET.Comment(" dexplan: collision shapes fitted to the visual meshes "))
        link[-1].tail = "\n    "
        for shape in link_shapes:
            elem = shape.element()
            ET.indent(elem, space="  ", level=2)
            elem.tail = "\n    "
            link.append(elem)
        link[-1].tail = "\n  "
    return ET.tostring(root, encoding="unicode")
