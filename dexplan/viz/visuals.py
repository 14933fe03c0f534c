"""The hand as the robot looks: its URDF's visual geometry, where it has one.

Planning only needs collision geometry (the Allegro's 16 boxes and 4 tip
spheres); a viewer should show the links as the robot looks, so a recording
draws the URDF's ``<visual>`` elements (the Allegro's STL meshes) when every
one of them loads, and falls back to the collision geometry otherwise (the
builtin paper and three-finger hands have no visuals; a plan file moved to a
machine without the hand's meshes still shows something true).

Mesh files are resolved like the hand's own: ``package://`` and relative
paths against the search folders the scene was built with (the plan's or
URDF's folder, and example-robot-data's ``share`` folder when installed).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dexplan.exceptions import DependencyError

if TYPE_CHECKING:  # pragma: no cover - typing only
    from dexplan.hand import Hand


def hand_package_dirs(base_dir: Path) -> list[str | Path]:
    """Folders a hand's mesh files are searched in: ``base_dir``, then example-robot-data's.

    Args:
        base_dir: the plan's or scenario's folder.
    """
    from dexplan.hand import example_robot_data_file

    dirs: list[str | Path] = [base_dir]
    try:  # the Allegro hand's meshes live in example-robot-data's share folder
        urdf = example_robot_data_file("allegro_hand_description/urdf/allegro_right_hand.urdf")
        dirs.append(urdf.parents[4])  # .../share, holding example-robot-data/
    except DependencyError:
        pass
    return dirs


def visual_geometry(hand: Hand, package_dirs: Sequence[str | Path]) -> Any | None:
    """The hand's visual ``pin.GeometryModel``, or None to draw its collision geometry.

    None when the URDF has no ``<visual>`` element, or when any visual mesh
    cannot be found or read (a partial hand would look like a broken one).
    What the native loaders print is captured and dropped.

    Args:
        hand: the hand (its ``urdf_xml`` and Pinocchio ``model``).
        package_dirs: folders ``package://`` and relative mesh paths resolve against.
    """
    import pinocchio as pin

    from dexplan.native_output import captured_stderr

    if "<visual" not in hand.urdf_xml:
        return None
    dirs = [str(d) for d in package_dirs]
    try:
        with captured_stderr():
            model = pin.buildGeomFromUrdfString(
                hand.model, hand.urdf_xml, pin.VISUAL, package_dirs=dirs
            )
    except (ValueError, RuntimeError, OSError):
        return None
    if model.ngeoms == 0:
        return None
    return model
