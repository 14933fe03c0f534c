"""The hand as the robot looks: its URDF's visual geometry, where it has one.

Planning only needs collision geometry (the Allegro's 16 boxes and 4 tip
spheres); a viewer should show the links as the robot looks, so a recording
draws the URDF's ``<visual>`` elements (the Allegro's STL meshes) when every
one of them loads, and falls back to the collision geometry otherwise (the
builtin paper and three-finger hands have no visuals; a plan file moved to a
machine without the hand's meshes still shows something true).

Mesh files are resolved like the hand's collision meshes, in the folders the
hand was built with (:attr:`Hand.package_dirs`: the URDF's or plan's folder,
and example-robot-data's ``share`` folder for the Allegro hands).
"""

from __future__ import annotations

import contextlib
from pathlib import Path

import pinocchio as pin

from dexplan.core.errors import DependencyError
from dexplan.core.native_output import captured_stderr
from dexplan.model.hand.builtin import example_robot_data_share
from dexplan.model.hand.hand import Hand


def hand_package_dirs(base_dir: Path) -> list[str | Path]:
    """Folders the mesh files of a plan's embedded hand are searched in.

    ``base_dir`` (the plan's folder), then example-robot-data's ``share``
    folder when installed (the Allegro hands' ``package://`` meshes).
    """
    dirs: list[str | Path] = [base_dir]
    with contextlib.suppress(DependencyError):  # no Allegro meshes to find then
        dirs.append(example_robot_data_share())
    return dirs


def visual_geometry(hand: Hand) -> pin.GeometryModel | None:
    """The hand's visual ``pin.GeometryModel``, or None to draw its collision geometry.

    None when the URDF has no ``<visual>`` element, or when any visual mesh
    cannot be found or read (a partial hand would look like a broken one).
    What the native loaders print is captured and dropped.

    Args:
        hand: the hand (its ``urdf_xml``, Pinocchio ``model`` and the
            ``package_dirs`` its meshes were found in).
    """
    if "<visual" not in hand.urdf_xml:
        return None
    try:
        with captured_stderr():
            model = pin.buildGeomFromUrdfString(
                hand.model, hand.urdf_xml, pin.VISUAL, package_dirs=list(hand.package_dirs)
            )
    except (ValueError, RuntimeError, OSError):
        return None
    if model.ngeoms == 0:
        return None
    return model
