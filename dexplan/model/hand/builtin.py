"""The builtin hands: the URDF, fingertips and mounting each is built from.

``"paper"`` (4 x 3 DOF, after the paper) and ``"three_finger"`` (3 x 3 DOF,
capsule links) ship with dexplan; ``"allegro"`` and ``"allegro_left"``
(4 x 4 DOF) are read from the installed ``example-robot-data`` distribution
and mounted palm-up (see :data:`ALLEGRO_MOUNT_RPY`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum
from importlib import metadata, resources
from pathlib import Path

from dexplan.core.errors import DependencyError, InvalidInputError, shorten
from dexplan.model.hand.urdf import mount_urdf, urdf_text

#: Frames the builtin hands use for their fingertips.
PAPER_HAND_TIPS: tuple[str, ...] = ("f0_tip", "f1_tip", "f2_tip", "f3_tip")
PAPER_HAND_TIP_RADIUS = 0.012
THREE_FINGER_TIPS: tuple[str, ...] = ("f0_tip", "f1_tip", "f2_tip")
THREE_FINGER_TIP_RADIUS = 0.012
#: Allegro fingers: index, middle, ring, thumb. The joints follow Pinocchio's
#: order (index q[0:4], thumb q[4:8], middle q[8:12], ring q[12:16]).
ALLEGRO_TIPS: tuple[str, ...] = ("link_3.0_tip", "link_7.0_tip", "link_11.0_tip", "link_15.0_tip")
ALLEGRO_TIP_RADIUS = 0.012
#: The palm box and the thumb's second link overlap by design (for joint_12.0 < 0.9).
ALLEGRO_COLLISION_EXCLUDE: tuple[tuple[str, str], ...] = (("palm_link", "link_13.0"),)
#: Roll, pitch, yaw (URDF fixed-axis XYZ) of palm_link in the world frame: the
#: palm normal (palm_link +x) is world +z, the fingers (palm_link +z) point
#: along world +x, palm_link +y is world -y. palm_link's origin is the world origin.
ALLEGRO_MOUNT_RPY: tuple[float, float, float] = (math.pi, -math.pi / 2, 0.0)


class BuiltinHandName(StrEnum):
    """Names of the builtin hands (``hand.builtin``; members equal their strings)."""

    PAPER = "paper"
    THREE_FINGER = "three_finger"
    ALLEGRO = "allegro"
    ALLEGRO_LEFT = "allegro_left"


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


def _allegro_hand(*, left: bool) -> BuiltinHand:
    """The Allegro right (or left) hand from example-robot-data, mounted palm-up."""
    hand_name = "allegro_left" if left else "allegro"
    side = "left" if left else "right"
    try:
        path = example_robot_data_file(f"allegro_hand_description/urdf/allegro_{side}_hand.urdf")
    except DependencyError as exc:
        raise DependencyError(f"hand {hand_name!r}: {exc}") from None
    text = urdf_text(path.read_bytes(), f"URDF file {str(path)!r}")
    return BuiltinHand(
        mount_urdf(text, ALLEGRO_MOUNT_RPY),
        ALLEGRO_TIPS,
        ALLEGRO_TIP_RADIUS,
        hand_name,
        collision_exclude=ALLEGRO_COLLISION_EXCLUDE,
        package_dirs=(str(example_robot_data_share(path)),),
    )
