"""The models a plan file describes: hand, object, obstacles and collision world.

A plan document carries everything needed to rebuild its models
(the hand's URDF text and fingertips, the object and obstacle shapes, friction):
:func:`models_from_document` rebuilds them from the document alone, for the
verifier, the viewer, the trajectory export and the replay. :func:`hand_table`
is the inverse of :func:`hand_from_plan`: the ``hand`` table a plan is written with.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

from dexplan.core.errors import DexplanError, PlanFileError, one_line, shorten
from dexplan.model.collision import CollisionWorld, Obstacle
from dexplan.model.grasp import ContactModel
from dexplan.model.grasp.grip_forces import DEFAULT_GRAVITY, DEFAULT_MASS, ForceSettings
from dexplan.model.grasp.holds import DEFAULT_HOLD_SHIFT
from dexplan.model.grasp.rolling import ContactMotion
from dexplan.model.hand.hand import Hand
from dexplan.model.hand.packages import mesh_mismatches, search_dirs
from dexplan.model.objects import Shape, shape_from_dict

__all__ = [
    "NOT_SHAPE_FIELDS",
    "PlanModels",
    "cached_plan_hand",
    "hand_from_plan",
    "hand_table",
    "models_from_document",
    "plan_force_settings",
    "shape_of",
]


def hand_table(hand: Hand) -> dict[str, Any]:
    """The plan file's ``hand`` table: everything :func:`hand_from_plan` rebuilds it from.

    The URDF text keeps its mesh URIs as given (``package://...``), so the
    file names no folder of this machine; ``mesh_sha256`` pins the meshes.
    """
    table: dict[str, Any] = {
        "urdf_xml": hand.urdf_xml,
        "joint_names": list(hand.joint_names),
        "fingertip_frames": list(hand.fingertip_frames),
        "fingertip_radius": hand.fingertip_radius,
        "collision_exclude": [list(p) for p in hand.collision_exclude],
    }
    if hand.mesh_sha256:
        table["mesh_sha256"] = dict(sorted(hand.mesh_sha256.items()))
    return table


def hand_from_plan(h: Mapping[str, Any], package_dirs: Sequence[str | Path] = ()) -> Hand:
    """The :class:`~dexplan.model.hand.hand.Hand` of a validated plan's ``hand`` table.

    Args:
        h: the ``hand`` table.
        package_dirs: folders ``package://`` mesh URIs resolve against.

    Raises:
        PlanFileError: the URDF text does not build a hand with these
            fingertip frames, or its joints are not ``hand.joint_names``.
    """
    try:
        hand = Hand(
            h["urdf_xml"],
            h["fingertip_frames"],
            h["fingertip_radius"],
            collision_exclude=[tuple(p) for p in h.get("collision_exclude", [])],
            name="plan hand",
            package_dirs=package_dirs,
            solvers=False,  # verification never solves IK; export and replay build them on use
        )
    except DexplanError as exc:
        # a mesh that did not resolve: say where meshes are searched
        hint = _MESH_HINT if "package_dirs" in str(exc) else ""
        raise PlanFileError(f"hand: {one_line(str(exc), 200)}{hint}") from exc
    wrong = mesh_mismatches(h.get("mesh_sha256", {}), hand.mesh_sha256, hand.package_dirs)
    if wrong:
        raise PlanFileError(f"hand.mesh_sha256: {wrong[0]}")
    if list(hand.joint_names) != list(h["joint_names"]):
        raise PlanFileError(
            f"hand.joint_names must be the URDF's joints {shorten(list(hand.joint_names))}, "
            f"got {shorten(list(h['joint_names']))}"
        )
    return hand


#: Said after a hand that does not build: where its meshes are looked for.
_MESH_HINT = (
    " (package:// meshes are searched in the plan's folder, --package-dir, "
    "ROS_PACKAGE_PATH and example-robot-data's share folder)"
)

#: Fields of an object or obstacle table that are not shape (mass, placement, label).
NOT_SHAPE_FIELDS = ("mass", "pose_xyzquat", "name")


@dataclass(frozen=True)
class PlanModels:
    """The models a plan file describes, rebuilt from the file alone.

    Attributes:
        hand: the hand (its URDF text, fingertips, exclusions).
        obj: the object shape.
        obstacles: static obstacles, world frame.
        world: the collision world of hand, object and obstacles.
        mu: friction coefficient. friction_edges: edges of the linearized cone.
        contact_model: ``point`` or ``soft``. torsion: soft-finger torsion (m).
        hold_shift: how far each contact is moved when a hold is checked (m).
        forces: the object's mass and gravity (the file's, else the defaults).
        contact_motion: how transfers move the contacts (``fixed`` for ``/1`` files).
    """

    hand: Hand
    obj: Shape
    obstacles: tuple[Obstacle, ...]
    world: CollisionWorld
    mu: float
    friction_edges: int
    contact_model: ContactModel
    torsion: float
    hold_shift: float = DEFAULT_HOLD_SHIFT
    forces: ForceSettings = field(default_factory=ForceSettings)
    contact_motion: ContactMotion = ContactMotion.FIXED


def shape_of(table: Mapping[str, Any], base_dir: Path, field: str) -> Shape:
    """The shape of an object or obstacle table (its non-shape fields set aside)."""
    shape = {k: v for k, v in table.items() if k not in NOT_SHAPE_FIELDS}
    return shape_from_dict(shape, base_dir, field=field)


def models_from_document(
    doc: Mapping[str, Any],
    base_dir: str | Path = ".",
    *,
    hand: Hand | None = None,
    package_dirs: Sequence[str | Path] = (),
) -> PlanModels:
    """Hand, object, obstacles and collision world of a validated plan document.

    The one way to rebuild a plan's models: the verifier, the viewer, the
    trajectory export and the replay all use it.

    Args:
        doc: a plan document (see :func:`~dexplan.planfile.document.read_plan`).
        base_dir: folder relative mesh paths resolve against.
        hand: the hand if already rebuilt (:func:`hand_from_plan`).
        package_dirs: folders ``package://`` mesh URIs of the URDF resolve against.

    Raises:
        PlanFileError: the hand does not build from the file.
    """
    base = Path(base_dir)
    hand = hand if hand is not None else hand_from_plan(doc["hand"], package_dirs)
    obj = shape_of(doc["object"], base, "object")
    obstacles = tuple(
        Obstacle(
            shape_of(ob, base, f"obstacles[{k}]"),
            tuple(float(v) for v in ob["pose_xyzquat"]),
            str(ob.get("name", f"obstacle{k}")),
        )
        for k, ob in enumerate(doc.get("obstacles", []))
    )
    return PlanModels(
        hand=hand,
        obj=obj,
        obstacles=obstacles,
        world=CollisionWorld(hand, obj, list(obstacles)),
        mu=float(doc["mu"]),
        friction_edges=int(doc.get("friction_edges", 8)),
        # one of CONTACT_MODELS: validate_plan checked it
        contact_model=cast("ContactModel", str(doc.get("contact_model", "point"))),
        torsion=float(doc.get("torsion", 0.0)),
        hold_shift=float(doc.get("hold_shift", DEFAULT_HOLD_SHIFT)),
        contact_motion=ContactMotion(doc.get("contact_motion", ContactMotion.FIXED)),
        forces=plan_force_settings(doc),
    )


def plan_force_settings(doc: Mapping[str, Any]) -> ForceSettings:
    """The load a plan's holds carry: ``object.mass`` and ``world.gravity``, else the defaults."""
    g = doc.get("world", {}).get("gravity", DEFAULT_GRAVITY)
    return ForceSettings(
        mass=float(doc["object"].get("mass", DEFAULT_MASS)),
        gravity=(float(g[0]), float(g[1]), float(g[2])),
    )


#: Hands rebuilt from plan files, by the ``hand`` table's content (most recent
#: last), and how many are kept.
_HANDS: dict[str, Hand] = {}
_HANDS_SIZE = 4


def cached_plan_hand(table: Mapping[str, Any], package_dirs: Sequence[str | Path] = ()) -> Hand:
    """The hand of a plan's ``hand`` table, rebuilt once per distinct table.

    Many queries of one process carry the same hand: rebuilding its model
    (URDF parsing, Pinocchio and coal geometry) for each plan costs about as much as
    checking a third of its waypoints. The key is the whole table (URDF text,
    fingertip frames and radius, exclusions, joint names), so a plan of any
    other hand is rebuilt from its own file. The folders mesh files are
    searched in (``package_dirs`` first, :func:`search_dirs`) are part of the
    key: the same table elsewhere may resolve its ``package://`` meshes to
    other files (checked against ``mesh_sha256``).
    """
    key = json.dumps([table, search_dirs(package_dirs)], sort_keys=True)
    hand = _HANDS.pop(key, None)
    if hand is None:
        hand = hand_from_plan(table, package_dirs)
        if len(_HANDS) >= _HANDS_SIZE:
            _HANDS.pop(next(iter(_HANDS)))
    _HANDS[key] = hand
    return hand
