"""The scene of a recording: hand, object, goal and obstacles, static and per configuration.

The models are rebuilt from a ``dexplan-plan/2`` document or a
:class:`~dexplan.model.scenario.scenario.Scenario` (:class:`Scene`); the hand's link
geometry, the object, goal and obstacles are logged once, statically
(:func:`log_scene_static`), and configurations (object pose and every moving
link's pose) as columns on a timeline (:func:`send_configurations`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin

from dexplan.core.errors import PlanFileError
from dexplan.core.typing import FloatArray
from dexplan.model.hand.hand import Hand
from dexplan.model.objects import Shape, shape_from_dict
from dexplan.model.scenario import Scenario
from dexplan.planfile import hand_from_plan, models_from_document, shape_of, validate_plan
from dexplan.viz.session import (
    GOAL,
    GREY,
    OBJECT,
    OBSTACLE,
    PALM,
    entity,
    finger_color,
    rerun_module,
    transform,
)
from dexplan.viz.shapes import coal_archetype, shape_archetype
from dexplan.viz.visuals import hand_package_dirs, visual_geometry

if TYPE_CHECKING:  # rerun's types for annotations; at run time rerun loads on first use
    import rerun


@dataclass(frozen=True)
class Scene:
    """Models rebuilt from a plan document or a scenario.

    Attributes:
        hand: the hand (None: none to draw).
        obj: the object's shape (None: none to draw).
        obstacles: ``(name, shape, pose_xyzquat (7,))`` per obstacle, world frame.
        mu: friction coefficient.
        friction_edges: edges of the linearized friction cone.
        contact_model: ``point`` or ``soft``.
        torsion: soft-contact torsion coefficient (m).
        goal_pose: ``(7,)`` goal object pose, world frame (None: no goal).
        start_pose: ``(7,)`` start object pose, world frame (None: not given).
        start_q: ``(nq,)`` start joints (None: not given).
    """

    hand: Hand | None
    obj: Shape | None
    obstacles: list[tuple[str, Shape, FloatArray]] = field(default_factory=list)
    mu: float = 0.8
    friction_edges: int = 8
    contact_model: str = "point"
    torsion: float = 0.0
    goal_pose: FloatArray | None = None
    start_pose: FloatArray | None = None
    start_q: FloatArray | None = None


@dataclass(frozen=True)
class HandLayout:
    """Where each hand link and geometry is logged."""

    links: list[tuple[str, int, bool]]
    """Per link: its entity, frame id, and whether it moves with the joints."""
    geoms: list[tuple[str, type[rerun.AsComponents], int | None]]
    """Per drawn geometry: its entity, archetype type and finger (None: not recoloured)."""


# ------------------------------------------------------------------ models
def _hand_from_doc(h: Mapping[str, Any], base_dir: Path) -> Hand:
    """The hand of a plan document (meshes found beside it or in example-robot-data)."""
    return hand_from_plan(h, hand_package_dirs(base_dir))


def obstacles_from_dicts(
    items: Sequence[Mapping[str, Any]], base_dir: Path
) -> list[tuple[str, Shape, FloatArray]]:
    """Obstacles as ``(name, shape, pose_xyzquat)`` from their plan or scenario entries.

    Args:
        items: the ``obstacles`` entries (a shape's fields, ``pose_xyzquat``
            and an optional ``name``, default ``obstacle<k>``).
        base_dir: folder relative mesh paths resolve against.

    Returns:
        One triple per entry, in order.
    """
    out = []
    for k, ob in enumerate(items):
        pose = np.asarray(ob.get("pose_xyzquat", [0, 0, 0, 0, 0, 0, 1]), dtype=float)
        name = str(ob.get("name", f"obstacle{k}"))
        out.append((name, shape_of(ob, base_dir, f"obstacles[{k}]"), pose))
    return out


def scene_from_doc(doc: Mapping[str, Any], base_dir: Path) -> Scene:
    """Hand, object and obstacles of a ``dexplan-plan/2`` document.

    Raises:
        PlanFileError: the document is malformed (the message names the
            field; :func:`dexplan.planfile.schema.validate_plan`) or its hand does
            not build.
    """
    validate_plan(doc, base_dir)
    m = models_from_document(doc, base_dir, hand=_hand_from_doc(doc["hand"], base_dir))
    goal = doc["goal"]
    start = doc["start"]
    return Scene(
        hand=m.hand,
        obj=m.obj,
        obstacles=[(o.name, o.shape, np.asarray(o.pose_xyzquat)) for o in m.obstacles],
        mu=m.mu,
        friction_edges=m.friction_edges,
        contact_model=m.contact_model,
        torsion=m.torsion,
        goal_pose=_pose_or_none(goal.get("object_pose_xyzquat")),
        start_pose=_pose_or_none(start.get("object_pose_xyzquat")),
        start_q=None if start.get("q") is None else np.asarray(start["q"], dtype=float),
    )


def scene_from_scenario(scenario: Scenario) -> Scene:
    """Hand, object and obstacles of a :class:`~dexplan.model.scenario.scenario.Scenario`."""
    base = Path(scenario.base_dir)
    return Scene(
        hand=Hand.from_spec(scenario.hand),
        obj=shape_from_dict(scenario.object, base),
        obstacles=obstacles_from_dicts(scenario.obstacles, base),
        mu=float(scenario.mu),
        friction_edges=int(scenario.friction_edges),
        contact_model=str(scenario.contact_model),
        torsion=float(scenario.torsion),
        goal_pose=_pose_or_none(scenario.goal.object_pose_xyzquat),
        start_pose=_pose_or_none(scenario.start.object_pose_xyzquat),
        start_q=None if scenario.start.q is None else np.asarray(scenario.start.q, dtype=float),
    )


def scene_from(scene: Mapping[str, Any] | Scenario, base_dir: Path) -> Scene:
    """The models of a plan document (a mapping) or of a scenario."""
    if isinstance(scene, Mapping):
        return scene_from_doc(scene, Path(base_dir))
    return scene_from_scenario(scene)


def _pose_or_none(value: Any) -> FloatArray | None:
    """A pose as 7 floats, or None.

    Raises:
        PlanFileError: the value is not 7 finite numbers.
    """
    if value is None:
        return None
    pose = np.asarray(value, dtype=float)
    if pose.shape != (7,) or not np.all(np.isfinite(pose)):
        raise PlanFileError(f"a pose must be 7 finite numbers, got {np.ravel(pose).tolist()}")
    return pose


# ------------------------------------------------------------------- hand
def _se3_xyzquat(M: pin.SE3) -> FloatArray:
    """``pin.SE3`` as ``[x, y, z, qx, qy, qz, qw]``."""
    return np.asarray(pin.SE3ToXYZQUAT(M), dtype=float)


def _finger_of_frame(hand: Hand) -> dict[int, int | None]:
    """Per frame id of the hand's model, the finger moving it (None: the palm)."""
    model = hand.model
    finger_of_joint: dict[int, int] = {}
    for i, idx in enumerate(hand.finger_q_index):
        for j in range(1, model.njoints):
            if model.idx_qs[j] in set(int(v) for v in idx):
                finger_of_joint[j] = i

    def finger_of(fid: int) -> int | None:
        j = int(model.frames[fid].parentJoint)
        while j > 0:
            if j in finger_of_joint:
                return finger_of_joint[j]
            j = int(model.parents[j])
        return None

    return {fid: finger_of(fid) for fid in range(model.nframes)}


def _log_hand_static(rec: rerun.RecordingStream, hand: Hand) -> HandLayout:
    """Hand link geometry (static, in each link's frame) and the palm frame axes.

    The URDF's visual geometry when it loads (:func:`visual_geometry`), else
    the collision geometry the planner checks.
    """
    rr = rerun_module()
    model, data = hand.model, hand.data
    geometry = visual_geometry(hand) or hand.geom_model
    pin.framesForwardKinematics(model, data, hand.neutral)
    finger_of_frame = _finger_of_frame(hand)
    tip_ids = set(hand.tip_frame_ids)
    rec.log("world/hand", rr.TransformAxes3D(0.03), static=True)
    links: dict[int, tuple[str, int, bool]] = {}
    geoms: list[tuple[str, type[rerun.AsComponents], int | None]] = []
    for k, g in enumerate(geometry.geometryObjects):
        fid = int(g.parentFrame)
        if not 0 <= fid < model.nframes:
            fid = next(
                (i for i, f in enumerate(model.frames) if int(f.parentJoint) == g.parentJoint), 0
            )
        link_path = "world/hand/" + entity(model.frames[fid].name)
        if fid not in links:
            links[fid] = (link_path, fid, int(model.frames[fid].parentJoint) != 0)
        finger = finger_of_frame[fid]
        color = PALM if finger is None else GREY
        if fid in tip_ids and finger is not None:
            color = finger_color(finger)
        arche = coal_archetype(g, color)
        if arche is None:
            continue
        local = data.oMf[fid].inverse() * (data.oMi[g.parentJoint] * g.placement)
        gpath = f"{link_path}/{entity(g.name or f'geom{k}')}"
        rec.log(gpath, transform(_se3_xyzquat(local)), static=True)
        rec.log(gpath, arche, static=True)
        recolor = finger is not None and fid not in tip_ids
        geoms.append((gpath, type(arche), finger if recolor else None))
    for fid in hand.tip_frame_ids:  # fingertip frames, even without geometry
        if fid not in links:
            links[fid] = ("world/hand/" + entity(model.frames[fid].name), fid, True)
    for path, fid, moves in links.values():
        if not moves:
            rec.log(path, transform(_se3_xyzquat(data.oMf[fid])), static=True)
    return HandLayout(list(links.values()), geoms)


def _link_poses(hand: Hand, layout: HandLayout, qs: FloatArray) -> dict[str, FloatArray]:
    """Per moving link entity, its world poses ``(S, 7)`` at configurations ``qs: (S, nq)``."""
    model, data = hand.model, hand.data
    moving = [(p, fid) for p, fid, moves in layout.links if moves]
    out = {p: np.empty((len(qs), 7)) for p, _ in moving}
    for s, q in enumerate(qs):
        pin.framesForwardKinematics(model, data, q)
        for p, fid in moving:
            out[p][s] = pin.SE3ToXYZQUAT(data.oMf[fid])
    return out


# ---------------------------------------------------------------- logging
def log_scene_static(rec: rerun.RecordingStream, scene: Scene) -> HandLayout | None:
    """Log the world axes convention, hand geometry, object shape, obstacles and the goal.

    Returns:
        Where the hand's links and geometries were logged (None without a hand).
    """
    rr = rerun_module()
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    layout = _log_hand_static(rec, scene.hand) if scene.hand is not None else None
    if scene.obj is not None:
        size = scene.obj.bounding_radius
        rec.log("world/object/shape", shape_archetype(scene.obj, OBJECT), static=True)
        rec.log("world/object", rr.TransformAxes3D(0.6 * size), static=True)
        if scene.goal_pose is not None:
            rec.log(
                "world/goal",
                transform(scene.goal_pose),
                rr.TransformAxes3D(0.6 * size),
                static=True,
            )
            rec.log(
                "world/goal/shape",
                shape_archetype(scene.obj, GOAL, wireframe=True),
                static=True,
            )
    for name, shape, pose in scene.obstacles:
        path = "world/obstacles/" + entity(name)
        rec.log(path, transform(pose), static=True)
        rec.log(path + "/shape", shape_archetype(shape, OBSTACLE), static=True)
    return layout


def send_configurations(
    rec: rerun.RecordingStream,
    scene: Scene,
    layout: HandLayout | None,
    indexes: list[rerun.TimeColumn] | None,
    poses: FloatArray,
    qs: FloatArray | None,
) -> None:
    """Log the object pose and every moving link's pose, as columns on the given timelines.

    With ``indexes`` None, the single configuration ``poses[0]``, ``qs[0]``
    is logged as static data.

    Args:
        rec: the recording stream.
        scene: the models.
        layout: where the hand's links are logged (None: no hand).
        indexes: the time columns, one row per configuration, or None.
        poses: ``(S, 7)`` object poses.
        qs: ``(S, nq)`` joint values, or None.
    """
    rr = rerun_module()
    series: dict[str, FloatArray] = {}
    if scene.obj is not None:
        series["world/object"] = poses
    if layout is not None and scene.hand is not None and qs is not None:
        series.update(_link_poses(scene.hand, layout, qs))
    for path, P in series.items():
        if indexes is None:
            rec.log(path, transform(P[0]), static=True)
        else:
            rec.send_columns(
                path,
                indexes=indexes,
                columns=rr.Transform3D.columns(translation=P[:, :3], quaternion=P[:, 3:]),
            )
