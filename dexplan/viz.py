"""Rerun recordings of plans and roadmaps (optional extra ``viz``).

This is the only dexplan module that imports ``rerun``, and it does so lazily,
inside functions: the planner, the plan files and the CLI work without
rerun-sdk, and asking for a recording without it raises
:class:`~dexplan.exceptions.DependencyError` naming the extra to install.

Three entry points write ``.rrd`` files that the Rerun viewer opens directly:

- :func:`record_plan`: a ``dexplan-plan/1`` document (and optionally the
  roadmap it came from), animated on the ``plan_step`` and ``time`` timelines;
- :func:`record_roadmap`: a GSn roadmap alone, with or without the hand,
  object and obstacles of a plan document or scenario;
- :func:`write_recording`: either of the above from a file name (plan
  ``.json`` or roadmap ``.npz``), as ``dexplan show --save`` needs.

:func:`show` records to a temporary file and opens the native viewer.

Entity paths, timelines and colours are documented in ``docs/viz.md``. The
world frame is the palm frame, right-handed, z up; all lengths are metres.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
import uuid
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dexplan.exceptions import DependencyError, DexplanError, InvalidInputError, PlanFileError
from dexplan.files import atomic_output
from dexplan.typing import FloatArray

if TYPE_CHECKING:  # pragma: no cover - typing only
    from types import ModuleType

    from dexplan.hand import Hand
    from dexplan.objects import Shape
    from dexplan.planning.roadmap import Roadmap
    from dexplan.segments import Segment

#: Oldest rerun-sdk whose API and ``.rrd`` format this module is written for.
MIN_RERUN_VERSION: tuple[int, int] = (0, 41)
#: Rerun application id of every dexplan recording (the viewer keys layouts on it).
APPLICATION_ID = "dexplan"
#: Seconds per waypoint on the ``time`` timeline.
STEP_SECONDS = 0.05

INSTALL_HINT = "pip install 'dexplan[viz]'"

# Colours (RGBA).
_GREY = (170, 174, 184, 255)
_PALM = (120, 124, 134, 255)
_OBJECT = (90, 150, 230, 200)
_GOAL = (60, 200, 90, 255)
_OBSTACLE = (150, 120, 90, 255)
_LINK_COLOR = (230, 40, 200, 255)
_FINGERS = (
    (230, 80, 60, 255),
    (250, 170, 30, 255),
    (60, 180, 90, 255),
    (150, 90, 220, 255),
    (40, 170, 200, 255),
    (220, 110, 170, 255),
)
_COMPONENTS = (
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (127, 127, 127),
    (188, 189, 34),
    (23, 190, 207),
)

# Default 3D camera (the hand's workspace, seen from the front right).
_EYE = [0.19, -0.22, 0.21]
_LOOK_AT = [0.0, 0.0, 0.06]

# Timelines.
PLAN_STEP = "plan_step"
TIME = "time"
ROADMAP_NODE = "roadmap_node"
REJECTED_SAMPLE = "rejected_sample"


# ------------------------------------------------------------------ rerun
def require_rerun() -> None:
    """Check that a usable rerun-sdk is installed.

    Raises:
        DependencyError: rerun-sdk is missing or older than
            :data:`MIN_RERUN_VERSION`; the message says what to install.

    """
    _rerun()


def _rerun() -> ModuleType:
    """Import and return the ``rerun`` module, or raise DependencyError."""
    try:
        import rerun as rr
    except ImportError as exc:
        raise DependencyError(
            f"Rerun recordings need rerun-sdk, which is not installed: {INSTALL_HINT}"
        ) from exc
    version = str(getattr(rr, "__version__", "0"))
    parts = [int(p) for p in version.split(".")[:2] if p.isdigit()]
    if tuple(parts) < MIN_RERUN_VERSION:
        need = ".".join(str(v) for v in MIN_RERUN_VERSION)
        raise DependencyError(
            f"Rerun recordings need rerun-sdk >= {need}, found {version}: "
            f"pip install -U 'rerun-sdk>={need}'"
        )
    return rr


@contextmanager
def _recording(path: str | Path, name: str, blueprint: Any) -> Iterator[Any]:
    """Yield a recording stream whose data lands in ``path`` once the block succeeds.

    The stream saves to a temporary file beside ``path`` (with ``blueprint``
    as its active and default layout); on success the file is renamed onto
    ``path``, so a reader never sees half a recording, and on error it is
    removed.
    """
    rr = _rerun()
    path = Path(path)
    with atomic_output(path, "recording") as tmp:
        rec = rr.RecordingStream(APPLICATION_ID, recording_id=uuid.uuid4())
        try:
            rec.save(str(tmp))
            rec.set_log_time_enabled(False)
            rec.set_log_tick_enabled(False)
            rec.send_recording_name(name)
            rec.send_blueprint(blueprint, make_active=True, make_default=True)
            yield rec
        finally:
            rec.flush()
            rec.disconnect()


def _rgba(c: Sequence[int]) -> list[int]:
    return [int(v) for v in c]


def _entity(*parts: str) -> str:
    """Entity path from raw names (each part escaped)."""
    rr = _rerun()
    return "/".join(rr.escape_entity_path_part(p) for p in parts)


# ----------------------------------------------------------------- models
@dataclass
class _Scene:
    """Models rebuilt from a plan document or a scenario."""

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


def _hand_from_doc(h: Mapping[str, Any], base_dir: Path) -> Hand:
    from dexplan.hand import example_robot_data_file
    from dexplan.plan_file import hand_from_plan

    package_dirs: list[str | Path] = [base_dir]
    try:  # the allegro hand's meshes live in example-robot-data's share folder
        urdf = example_robot_data_file("allegro_hand_description/urdf/allegro_right_hand.urdf")
        package_dirs.append(urdf.parents[4])  # .../share, holding example-robot-data/
    except DependencyError:
        pass
    return hand_from_plan(h, package_dirs)


def _obstacles(items: Sequence[Mapping[str, Any]], base_dir: Path) -> list:
    from dexplan.objects import shape_from_dict

    out = []
    for k, ob in enumerate(items):
        shape = {key: v for key, v in ob.items() if key not in ("pose_xyzquat", "name")}
        pose = np.asarray(ob.get("pose_xyzquat", [0, 0, 0, 0, 0, 0, 1]), dtype=float)
        out.append(
            (
                str(ob.get("name", f"obstacle{k}")),
                shape_from_dict(shape, base_dir, field=f"obstacles[{k}]"),
                pose,
            )
        )
    return out


def _scene_from_doc(doc: Mapping[str, Any], base_dir: Path) -> _Scene:
    """Hand, object and obstacles of a ``dexplan-plan/1`` document.

    Raises:
        PlanFileError: the document is malformed (the message names the
            field; :func:`dexplan.plan_schema.validate_plan`) or its hand does
            not build.
    """
    from dexplan.plan_file import models_from_document
    from dexplan.plan_schema import validate_plan

    validate_plan(doc, base_dir)
    m = models_from_document(doc, base_dir, hand=_hand_from_doc(doc["hand"], base_dir))
    goal = doc["goal"]
    start = doc["start"]
    return _Scene(
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


def _scene_from_scenario(scenario: Any) -> _Scene:
    """Hand, object and obstacles of a :class:`~dexplan.scenario.Scenario`."""
    from dexplan.objects import shape_from_dict
    from dexplan.planning.context import build_hand

    base = Path(scenario.base_dir)
    return _Scene(
        hand=build_hand(scenario, check_contacts=False),
        obj=shape_from_dict(scenario.object, base),
        obstacles=_obstacles(scenario.obstacles, base),
        mu=float(scenario.mu),
        friction_edges=int(scenario.friction_edges),
        contact_model=str(scenario.contact_model),
        torsion=float(scenario.torsion),
        goal_pose=_pose_or_none(scenario.goal.object_pose_xyzquat),
        start_pose=_pose_or_none(scenario.start.object_pose_xyzquat),
        start_q=None if scenario.start.q is None else np.asarray(scenario.start.q, dtype=float),
    )


def _pose_or_none(value: Any) -> FloatArray | None:
    if value is None:
        return None
    pose = np.asarray(value, dtype=float)
    if pose.shape != (7,) or not np.all(np.isfinite(pose)):
        raise PlanFileError(f"a pose must be 7 finite numbers, got {np.ravel(pose).tolist()}")
    return pose


# -------------------------------------------------------------- geometry
def _se3_xyzquat(M: Any) -> FloatArray:
    """``pin.SE3`` as ``[x, y, z, qx, qy, qz, qw]``."""
    import pinocchio as pin

    return np.asarray(pin.SE3ToXYZQUAT(M), dtype=float)


def _mesh_archetype(vertices: FloatArray, faces: np.ndarray, color: Sequence[int]) -> Any:
    rr = _rerun()
    import trimesh

    tm = trimesh.Trimesh(np.asarray(vertices, float), np.asarray(faces, int), process=False)
    return rr.Mesh3D(
        vertex_positions=tm.vertices,
        triangle_indices=tm.faces,
        vertex_normals=tm.vertex_normals,
        albedo_factor=_rgba(color),
    )


def _shape_archetype(shape: Shape, color: Sequence[int], *, wireframe: bool = False) -> Any:
    """Return a Rerun archetype drawing a dexplan shape in its own frame."""
    rr = _rerun()
    from dexplan.objects import Box, Capsule, Cylinder, Mesh, Sphere

    fill = rr.components.FillMode.MajorWireframe if wireframe else rr.components.FillMode.Solid
    c = [_rgba(color)]
    if isinstance(shape, Sphere):
        return rr.Ellipsoids3D(half_sizes=[[shape.radius] * 3], colors=c, fill_mode=fill)
    if isinstance(shape, Box):
        return rr.Boxes3D(sizes=[np.asarray(shape.size)], colors=c, fill_mode=fill)
    if isinstance(shape, Capsule):  # rerun capsules start at the origin and extend along +z
        return rr.Capsules3D(
            lengths=[shape.length],
            radii=[shape.radius],
            translations=[[0.0, 0.0, -shape.length / 2]],
            colors=c,
            fill_mode=fill,
        )
    if isinstance(shape, Cylinder):
        return rr.Cylinders3D(
            lengths=[shape.length], radii=[shape.radius], colors=c, fill_mode=fill
        )
    if isinstance(shape, Mesh):
        if wireframe:
            edges = shape.vertices[shape.faces[:, [0, 1, 2, 0]]]
            return rr.LineStrips3D(edges, colors=c, radii=[0.0003])
        return _mesh_archetype(shape.vertices, shape.faces, color)
    raise InvalidInputError(f"cannot draw shape {shape!r}")


def _coal_archetype(geom: Any, color: Sequence[int]) -> Any | None:
    """Return a Rerun archetype for a Pinocchio geometry object's coal shape (own frame)."""
    rr = _rerun()
    import coal

    g = geom.geometry
    c = [_rgba(color)]
    solid = rr.components.FillMode.Solid
    if isinstance(g, coal.Box):
        return rr.Boxes3D(half_sizes=[np.asarray(g.halfSide)], colors=c, fill_mode=solid)
    if isinstance(g, coal.Sphere):
        return rr.Ellipsoids3D(half_sizes=[[g.radius] * 3], colors=c, fill_mode=solid)
    if isinstance(g, coal.Ellipsoid):
        return rr.Ellipsoids3D(half_sizes=[np.asarray(g.radii)], colors=c, fill_mode=solid)
    if isinstance(g, coal.Cylinder):
        return rr.Cylinders3D(
            lengths=[2 * g.halfLength], radii=[g.radius], colors=c, fill_mode=solid
        )
    if isinstance(g, coal.Capsule):
        return rr.Capsules3D(
            lengths=[2 * g.halfLength],
            radii=[g.radius],
            translations=[[0.0, 0.0, -g.halfLength]],
            colors=c,
            fill_mode=solid,
        )
    if hasattr(g, "num_tris") and hasattr(g, "tri_indices"):
        n_t = int(g.num_tris)
        verts = np.asarray(g.vertices(), dtype=float)
        if n_t and len(verts):
            faces = np.array([[t[0], t[1], t[2]] for t in (g.tri_indices(i) for i in range(n_t))])
            return _mesh_archetype(verts, faces, color)
    mesh_path = getattr(geom, "meshPath", "")
    if mesh_path and Path(mesh_path).is_file():
        import trimesh

        try:
            tm = trimesh.load(mesh_path, force="mesh")
        except (ValueError, OSError):
            return None
        return _mesh_archetype(tm.vertices * np.asarray(geom.meshScale), tm.faces, color)
    return None


@dataclass
class _HandLayout:
    """Where each hand link and geometry is logged."""

    links: list[tuple[str, int, bool]]  # (entity, frame id, moves)
    geoms: list[tuple[str, type, int | None]]  # (entity, archetype type, finger or None)


def _log_hand_static(rec: Any, hand: Hand) -> _HandLayout:
    """Hand link geometry (static, in each link's frame) and the palm frame axes."""
    rr = _rerun()
    import pinocchio as pin

    model, data = hand.model, hand.data
    q0 = hand.neutral
    pin.framesForwardKinematics(model, data, q0)
    finger_of_joint: dict[int, int] = {}
    for i, idx in enumerate(hand.finger_q_index):
        for j in range(1, model.njoints):
            if model.idx_qs[j] in set(int(v) for v in idx):
                finger_of_joint[j] = i
    tip_ids = set(hand.tip_frame_ids)

    def finger_of_frame(fid: int) -> int | None:
        j = int(model.frames[fid].parentJoint)
        while j > 0:
            if j in finger_of_joint:
                return finger_of_joint[j]
            j = int(model.parents[j])
        return None

    rec.log("world/hand", rr.TransformAxes3D(0.03), static=True)
    links: dict[int, tuple[str, int, bool]] = {}
    geoms: list[tuple[str, type, int | None]] = []
    for k, g in enumerate(hand.geom_model.geometryObjects):
        fid = int(g.parentFrame)
        if not 0 <= fid < model.nframes:
            fid = next(
                (i for i, f in enumerate(model.frames) if int(f.parentJoint) == g.parentJoint), 0
            )
        link_name = model.frames[fid].name
        link_path = "world/hand/" + _entity(link_name)
        if fid not in links:
            links[fid] = (link_path, fid, int(model.frames[fid].parentJoint) != 0)
        finger = finger_of_frame(fid)
        color = _PALM if finger is None else _GREY
        if fid in tip_ids and finger is not None:
            color = _FINGERS[finger % len(_FINGERS)]
        arche = _coal_archetype(g, color)
        if arche is None:
            continue
        oMg = data.oMi[g.parentJoint] * g.placement
        local = data.oMf[fid].inverse() * oMg
        pose = _se3_xyzquat(local)
        gpath = f"{link_path}/{_entity(g.name or f'geom{k}')}"
        rec.log(gpath, rr.Transform3D(translation=pose[:3], quaternion=pose[3:]), static=True)
        rec.log(gpath, arche, static=True)
        recolor = finger is not None and fid not in tip_ids
        geoms.append((gpath, type(arche), finger if recolor else None))
    for fid in hand.tip_frame_ids:  # fingertip frames, even without geometry
        if fid not in links:
            name = model.frames[fid].name
            links[fid] = ("world/hand/" + _entity(name), fid, True)
    for path, fid, moves in links.values():
        if not moves:
            pose = _se3_xyzquat(data.oMf[fid])
            rec.log(path, rr.Transform3D(translation=pose[:3], quaternion=pose[3:]), static=True)
    return _HandLayout(list(links.values()), geoms)


def _link_poses(hand: Hand, layout: _HandLayout, qs: FloatArray) -> dict[str, FloatArray]:
    """Per moving link entity, its world poses ``(S, 7)`` at configurations ``qs: (S, nq)``."""
    import pinocchio as pin

    model, data = hand.model, hand.data
    moving = [(p, fid) for p, fid, moves in layout.links if moves]
    out = {p: np.empty((len(qs), 7)) for p, _ in moving}
    for s, q in enumerate(qs):
        pin.framesForwardKinematics(model, data, q)
        for p, fid in moving:
            out[p][s] = pin.SE3ToXYZQUAT(data.oMf[fid])
    return out


def _log_scene_static(rec: Any, scene: _Scene) -> _HandLayout | None:
    """World axes convention, hand geometry, object shape, obstacles and the goal."""
    rr = _rerun()
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    layout = _log_hand_static(rec, scene.hand) if scene.hand is not None else None
    if scene.obj is not None:
        size = scene.obj.bounding_radius
        rec.log("world/object/shape", _shape_archetype(scene.obj, _OBJECT), static=True)
        rec.log("world/object", rr.TransformAxes3D(0.6 * size), static=True)
        if scene.goal_pose is not None:
            g = scene.goal_pose
            rec.log(
                "world/goal",
                rr.Transform3D(translation=g[:3], quaternion=g[3:]),
                rr.TransformAxes3D(0.6 * size),
                static=True,
            )
            rec.log(
                "world/goal/shape",
                _shape_archetype(scene.obj, _GOAL, wireframe=True),
                static=True,
            )
    for name, shape, pose in scene.obstacles:
        path = "world/obstacles/" + _entity(name)
        rec.log(path, rr.Transform3D(translation=pose[:3], quaternion=pose[3:]), static=True)
        rec.log(path + "/shape", _shape_archetype(shape, _OBSTACLE), static=True)
    return layout


def _send_configurations(
    rec: Any,
    scene: _Scene,
    layout: _HandLayout | None,
    indexes: list[Any] | None,
    poses: FloatArray,
    qs: FloatArray | None,
) -> None:
    """Object pose and every moving link's pose, as columns on the given timelines.

    With ``indexes`` None, the single configuration ``poses[0]``, ``qs[0]``
    is logged as static data.
    """
    rr = _rerun()
    series: dict[str, FloatArray] = {}
    if scene.obj is not None:
        series["world/object"] = poses
    if layout is not None and scene.hand is not None and qs is not None:
        series.update(_link_poses(scene.hand, layout, qs))
    for path, P in series.items():
        if indexes is None:
            rec.log(path, rr.Transform3D(translation=P[0, :3], quaternion=P[0, 3:]), static=True)
        else:
            rec.send_columns(
                path,
                indexes=indexes,
                columns=rr.Transform3D.columns(translation=P[:, :3], quaternion=P[:, 3:]),
            )


# ---------------------------------------------------------------- roadmap
def _component_color(k: int) -> tuple[int, int, int]:
    return _COMPONENTS[k % len(_COMPONENTS)]


def _quat_matrices(q_xyzw: FloatArray) -> FloatArray:
    """Rotation matrices ``(N, 3, 3)`` of quaternions ``(N, 4)`` XYZW."""
    q = q_xyzw / np.linalg.norm(q_xyzw, axis=1, keepdims=True)
    x, y, z, w = q.T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=1,
    )


@dataclass(frozen=True)
class RoadmapSummary:
    """What :func:`record_roadmap` logged: node, edge and link counts per component.

    Attributes:
        components: number of GSn connected components (edges only).
        merged_components: number of components once module-2 links are added.
        nodes: per GSn component, its vertex count.
        edges: per GSn component, its edge count.
        links: per GSn component, the module-2 links touching it.
        merged: per GSn component, the merged component it belongs to.

    """

    components: int
    merged_components: int
    nodes: tuple[int, ...]
    edges: tuple[int, ...]
    links: tuple[int, ...]
    merged: tuple[int, ...]

    def markdown(self) -> str:
        """Return the summary as a Markdown table."""
        rows = [
            "| component | nodes | edges | links | merged into |",
            "|---:|---:|---:|---:|---:|",
        ]
        for k in range(self.components):
            rows.append(
                f"| {k} | {self.nodes[k]} | {self.edges[k]} | {self.links[k]} | {self.merged[k]} |"
            )
        head = (
            f"**{sum(self.nodes)} nodes, {sum(self.edges)} GSn edges, "
            f"{self.components} GSn components, {self.merged_components} after module-2 links**"
        )
        return head + "\n\n" + "\n".join(rows) + "\n"


def summarize_roadmap(roadmap: Roadmap) -> RoadmapSummary:
    """Per-component counts of a roadmap (no Rerun needed).

    Components are those of the GSn edges alone; ``merged`` maps each to its
    component once the module-2 links join them.
    """
    n_c, labels = roadmap.components(with_links=False)
    n_m, merged_labels = roadmap.components(with_links=True)
    nodes = np.bincount(labels, minlength=n_c) if n_c else np.zeros(0, int)
    e = np.asarray(roadmap.edges, dtype=np.int64).reshape(-1, 2)
    li = np.asarray(roadmap.links, dtype=np.int64).reshape(-1, 2)
    edges = np.bincount(labels[e[:, 0]], minlength=n_c) if len(e) else np.zeros(n_c, int)
    links = np.zeros(n_c, dtype=int)
    for a, b in li:
        links[labels[a]] += 1
        if labels[b] != labels[a]:
            links[labels[b]] += 1
    merged = np.zeros(n_c, dtype=int)
    for k in range(n_c):
        merged[k] = int(merged_labels[np.flatnonzero(labels == k)[0]])
    return RoadmapSummary(
        n_c,
        n_m,
        tuple(int(v) for v in nodes),
        tuple(int(v) for v in edges),
        tuple(int(v) for v in links),
        tuple(int(v) for v in merged),
    )


def _log_roadmap(rec: Any, roadmap: Roadmap, axis_length: float) -> RoadmapSummary:
    """Nodes (coloured by component), orientation axes, edges and module-2 links (static)."""
    rr = _rerun()
    summary = summarize_roadmap(roadmap)
    _, labels = roadmap.components(with_links=False)
    V = np.asarray(roadmap.vertices, dtype=float)
    P = V[:, :3]
    rec.log(
        "world/roadmap",
        rr.AnnotationContext(
            [
                (k, f"component {k} ({summary.nodes[k]} nodes)", _component_color(k))
                for k in range(summary.components)
            ]
        ),
        static=True,
    )
    rec.log(
        "world/roadmap",
        rr.AnyValues(
            component=list(range(summary.components)),
            nodes_per_component=list(summary.nodes),
            edges_per_component=list(summary.edges),
            links_per_component=list(summary.links),
            merged_component=list(summary.merged),
            n_nodes=int(roadmap.n_vertices),
            n_edges=len(roadmap.edges),
            n_links=len(roadmap.links),
            n_components=summary.components,
            n_merged_components=summary.merged_components,
            planner=str(roadmap.planner),
        ),
        static=True,
    )
    rec.log(
        "world/roadmap/nodes",
        rr.Points3D(P, class_ids=labels.astype(np.uint16), radii=[0.0015], show_labels=False),
        static=True,
    )
    if len(V):
        R = _quat_matrices(V[:, 3:7])
        strips, colors = [], []
        for axis, col in ((0, (230, 60, 60)), (1, (60, 200, 60)), (2, (60, 90, 230))):
            ends = P + axis_length * R[:, :, axis]
            strips.extend(np.stack([P, ends], axis=1))
            colors.extend([col] * len(P))
        rec.log(
            "world/roadmap/axes",
            rr.LineStrips3D(np.asarray(strips), colors=colors, radii=[0.0003]),
            static=True,
        )
    e = np.asarray(roadmap.edges, dtype=np.int64).reshape(-1, 2)
    rec.log(
        "world/roadmap/edges",
        rr.LineStrips3D(
            np.stack([P[e[:, 0]], P[e[:, 1]]], axis=1) if len(e) else np.zeros((0, 2, 3)),
            class_ids=labels[e[:, 0]].astype(np.uint16) if len(e) else None,
            radii=[0.0005],
            show_labels=False,
        ),
        static=True,
    )
    li = np.asarray(roadmap.links, dtype=np.int64).reshape(-1, 2)
    rec.log(
        "world/roadmap/links",
        rr.LineStrips3D(
            np.stack([P[li[:, 0]], P[li[:, 1]]], axis=1) if len(li) else np.zeros((0, 2, 3)),
            colors=[_rgba(_LINK_COLOR)],
            radii=[0.0012],
        ),
        static=True,
    )
    rec.log(
        "roadmap/summary",
        rr.TextDocument(summary.markdown(), media_type=rr.MediaType.MARKDOWN),
        static=True,
    )
    rec.send_property(
        "roadmap",
        rr.AnyValues(
            nodes=int(roadmap.n_vertices),
            edges=len(roadmap.edges),
            links=len(roadmap.links),
            components=summary.components,
            merged_components=summary.merged_components,
            planner=str(roadmap.planner),
        ),
    )
    return summary


# ------------------------------------------------------------------- plan
def _friction_cone(
    apex: FloatArray, axis: FloatArray, mu: float, edges: int, height: float
) -> list[FloatArray]:
    """Line strips of a linearized friction cone: ``edges`` generators and the rim.

    The cone opens from ``apex`` along the unit ``axis`` with half-angle
    ``atan(mu)``; generators end at axial distance ``height``.
    """
    a = axis / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t1 = np.cross(a, helper)
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(a, t1)
    th = 2 * np.pi * np.arange(edges) / edges
    ends = apex + height * (a + mu * (np.cos(th)[:, None] * t1 + np.sin(th)[:, None] * t2))
    strips = [np.stack([apex, e]) for e in ends]
    strips.append(np.vstack([ends, ends[:1]]))
    return strips


def _contact_strips(
    apex: FloatArray, axis: FloatArray, scene: _Scene, height: float
) -> list[FloatArray]:
    """The friction cone's strips, and for soft contacts the torsion ring.

    The ring is a circle of radius ``torsion`` about the contact in its tangent
    plane: the lever arm of the largest torsional moment per unit normal force
    (``|tau_n| <= torsion f_n``), drawn at scale.
    """
    strips = _friction_cone(apex, axis, scene.mu, scene.friction_edges, height)
    if scene.contact_model == "soft":
        a = axis / np.linalg.norm(axis)
        rim = _friction_cone(np.zeros(3), a, 1.0, 24, 1.0)[-1]  # a + unit circle
        strips.append(apex + scene.torsion * (rim - a))
    return strips


def _fc_functions() -> tuple[Any, Any] | None:
    try:
        from dexplan.grasp import (
            force_closure_quality,
            min_subgrasp_quality,
        )
    except ImportError:
        return None
    return force_closure_quality, min_subgrasp_quality


def _plan_blueprint(has_roadmap: bool) -> Any:
    import rerun.blueprint as rrb

    side = [
        rrb.TimeSeriesView(
            origin="plan/fc",
            name="Force-closure quality",
            plot_legend=rrb.PlotLegend(corner=rrb.Corner2D.RightTop),
        ),
        rrb.StateTimelineView(origin="plan/state", name="Mode and free finger"),
        rrb.TextLogView(origin="plan/segment", name="Segments"),
        rrb.Tabs(
            rrb.TextDocumentView(origin="plan/summary", name="Plan"),
            *(
                [rrb.TextDocumentView(origin="roadmap/summary", name="Roadmap")]
                if has_roadmap
                else []
            ),
        ),
    ]
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(
                origin="world",
                name="Hand, object, roadmap",
                eye_controls=rrb.EyeControls3D(
                    position=_EYE, look_target=_LOOK_AT, eye_up=[0.0, 0.0, 1.0]
                ),
            ),
            rrb.Vertical(*side, row_shares=[3, 1.2, 2, 2]),
            column_shares=[3, 2],
        ),
        rrb.TimePanel(timeline=PLAN_STEP, state="collapsed"),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        collapse_panels=False,
    )


def _plan_summary_markdown(doc: Mapping[str, Any], n_steps: int, segments: Sequence) -> str:
    stats = doc.get("stats") or {}
    n_tr = sum(s.kind == "transfer" for s in segments)
    n_rg = sum(s.kind == "regrasp" for s in segments)
    lines = [
        f"## Plan {doc.get('scenario', '')}".rstrip(),
        "",
        f"- segments: **{len(segments)}** ({n_tr} transfers, {n_rg} regrasps)",
        f"- waypoints (`plan_step` steps): **{n_steps}**, "
        f"{STEP_SECONDS:g} s each on the `time` timeline",
        f"- friction: mu = {doc.get('mu')}, {doc.get('friction_edges', 8)} cone edges, "
        f"{doc.get('contact_model', 'point')} contacts"
        + (f" (torsion {doc.get('torsion')} m)" if doc.get("contact_model") == "soft" else ""),
    ]
    if stats:
        lines += ["", "| stat | value |", "|---|---|"]
        lines += [f"| {k} | {v} |" for k, v in stats.items() if not isinstance(v, dict | list)]
    return "\n".join(lines) + "\n"


def record_plan(
    doc: Mapping[str, Any],
    path: str | Path,
    *,
    roadmap: Roadmap | None = None,
    base_dir: Path = Path("."),
) -> None:
    """Write a Rerun recording (``.rrd``) of a ``dexplan-plan/1`` document.

    The recording holds the static scene (hand link geometry, object, goal,
    obstacles, palm frame, in a right-handed z-up world), the roadmap when
    given, and the plan animated on two timelines: ``plan_step`` (one step
    per waypoint of every segment; a waypoint shared by two consecutive
    segments is counted twice, once as the last step of a segment and once
    as the first of the next, so the number of steps is
    ``sum(len(segment.waypoints))``, the plan's ``stats.waypoints``) and
    ``time`` (:data:`STEP_SECONDS` per step). Per step: object pose, every
    moving hand link's pose, contacts with friction cones, the segment kind
    and free finger, and the force-closure quality of the holding grasp and
    the minimum over its subgrasps. A blueprint lays out a 3D view, the FC
    plot, mode lanes and the segment log.

    Args:
        doc: the plan document (as from :func:`dexplan.plan_file.read_plan` or
            :func:`dexplan.plan_file.build_plan_document`).
        path: output ``.rrd`` file.
        roadmap: the GSn roadmap the plan came from, drawn statically.
        base_dir: folder relative mesh paths resolve against (the plan's).

    Raises:
        DependencyError: rerun-sdk missing.
        PlanFileError: the document is malformed (the message names the
            field) or its hand does not build.
        InvalidInputError: the output folder does not exist.

    """
    rr = _rerun()
    from dexplan.plan_file import segments_from_dicts

    scene = _scene_from_doc(doc, Path(base_dir))  # validates the document
    segments = segments_from_dicts(doc["segments"])
    hand, obj = scene.hand, scene.obj
    assert hand is not None and obj is not None
    waypoints = [(si, wi, w) for si, s in enumerate(segments) for wi, w in enumerate(s.waypoints)]

    name = f"dexplan plan {doc.get('scenario', '')}".strip()
    with _recording(path, name, _plan_blueprint(roadmap is not None)) as rec:
        layout = _log_scene_static(rec, scene)
        if roadmap is not None:
            _log_roadmap(rec, roadmap, 0.25 * obj.bounding_radius)
        S = len(waypoints)
        indexes = _plan_index(np.arange(S))
        rec.log(
            "plan/summary",
            rr.TextDocument(
                _plan_summary_markdown(doc, S, segments), media_type=rr.MediaType.MARKDOWN
            ),
            static=True,
        )
        if S:
            poses = np.array([w.object_pose_xyzquat for _, _, w in waypoints])
            qs = np.array([w.q for _, _, w in waypoints])
            _send_configurations(rec, scene, layout, indexes, poses, qs)
            _log_plan_states(rec, scene, layout, segments)
            _log_contacts_and_fc(rec, scene, segments, indexes)


def _set_step(rec: Any, step: int) -> None:
    rec.set_time(PLAN_STEP, sequence=step)
    rec.set_time(TIME, duration=step * STEP_SECONDS)


def _log_plan_states(
    rec: Any, scene: _Scene, layout: _HandLayout | None, segments: Sequence[Segment]
) -> None:
    """Segment log, mode and free-finger lanes, and the free finger's colour."""
    rr = _rerun()
    n = scene.hand.n_fingers if scene.hand is not None else 0
    rec.log(
        "plan/state/mode",
        rr.StateConfiguration(
            values=["transfer", "regrasp"], colors=[[70, 130, 220, 255], [240, 150, 40, 255]]
        ),
        static=True,
    )
    rec.log(
        "plan/state/free_finger",
        rr.StateConfiguration(
            values=["none"] + [f"finger {i}" for i in range(n)],
            colors=[[120, 120, 120, 255]] + [_rgba(_FINGERS[i % len(_FINGERS)]) for i in range(n)],
        ),
        static=True,
    )
    step = 0
    for si, seg in enumerate(segments):
        _set_step(rec, step)
        last = step + len(seg.waypoints) - 1
        if seg.kind == "regrasp":
            text = (
                f"segment {si}: regrasp of finger {seg.finger} "
                f"({len(seg.waypoints)} waypoints, steps {step}-{last})"
            )
            color = [240, 150, 40, 255]
        else:
            text = f"segment {si}: transfer ({len(seg.waypoints)} waypoints, steps {step}-{last})"
            color = [70, 130, 220, 255]
        rec.log("plan/segment", rr.TextLog(text, level=rr.TextLogLevel.INFO, color=color))
        rec.log("plan/state/mode", rr.StateChange(state=seg.kind))
        free = seg.finger if seg.kind == "regrasp" else None
        rec.log(
            "plan/state/free_finger",
            rr.StateChange(state="none" if free is None else f"finger {free}"),
        )
        if layout is not None:
            for gpath, kind, finger in layout.geoms:
                if finger is None:
                    continue
                color = _FINGERS[finger % len(_FINGERS)] if finger == free else _GREY
                rec.log(gpath, kind.from_fields(**_color_fields(kind, color)))
        step = last + 1


def _color_fields(kind: type, color: Sequence[int]) -> dict[str, Any]:
    rr = _rerun()
    if kind is rr.Mesh3D:
        return {"albedo_factor": _rgba(color)}
    return {"colors": [_rgba(color)]}


def _log_contacts_and_fc(
    rec: Any, scene: _Scene, segments: Sequence[Segment], indexes: list[Any]
) -> None:
    """Contact points, friction cones and force-closure quality per step (as columns).

    A free finger's contact point and cone are empty batches at its steps, so
    they disappear; the FC series are cleared where they are undefined (fewer
    than two holding fingers; for ``min_subgrasp``, while a finger is free).
    """
    rr = _rerun()
    from dexplan.plan_file import fingertip_contact
    from dexplan.pose import inverse_transform_points, transform_points

    hand, obj = scene.hand, scene.obj
    assert hand is not None and obj is not None
    n = hand.n_fingers
    fc = _fc_functions()
    ts = obj.characteristic_length
    cone_h = min(0.025, 0.5 * ts)
    n_edges = scene.friction_edges
    # generators (2 points each), then the rim, then the soft torsion ring
    strip_sizes = [2] * n_edges + ([n_edges + 1] if scene.contact_model == "soft" else [])
    for i in range(n):
        col = [_rgba(_FINGERS[i % len(_FINGERS)])]
        path = f"world/contacts/finger_{i}"
        rec.log(
            path,
            rr.Points3D.from_fields(colors=col, radii=[0.002], labels=[f"f{i}"]),
            static=True,
        )
        rec.log(
            path + "/cone", rr.LineStrips3D.from_fields(colors=col, radii=[0.0004]), static=True
        )
    rec.log(
        "plan/fc/full",
        rr.SeriesLines(colors=[[40, 120, 220, 255]], names=["holding grasp"], widths=[2.0]),
        static=True,
    )
    rec.log(
        "plan/fc/min_subgrasp",
        rr.SeriesLines(colors=[[230, 90, 40, 255]], names=["min over subgrasps"], widths=[2.0]),
        static=True,
    )
    if fc is None:
        rec.log(
            "plan/segment",
            rr.TextLog(
                "force-closure quality not recorded: dexplan.grasp is unavailable",
                level=rr.TextLogLevel.WARN,
            ),
            static=True,
        )

    # per stated contact (object frame): surface point, outward normal, [c; cone points]
    local: dict[tuple[bytes, bytes], FloatArray] = {}  # (contact, normal) -> cone points
    fc_cache: dict[bytes, tuple[float | None, float | None]] = {}
    points: list[list[FloatArray]] = [[] for _ in range(n)]  # per finger, per step (k, 3)
    strips: list[list[FloatArray]] = [[] for _ in range(n)]  # per finger, cone strips
    n_strips: list[list[int]] = [[] for _ in range(n)]
    full_q: list[float | None] = []
    sub_q: list[float | None] = []
    r = hand.fingertip_radius
    for seg in segments:
        for w in seg.waypoints:
            pose = w.object_pose_xyzquat
            tips = inverse_transform_points(pose, hand.fingertip_positions(w.q))
            pts_obj, nrm_in = [], []
            for i, c in enumerate(w.contacts):
                if c is None:
                    points[i].append(np.zeros((0, 3)))
                    n_strips[i].append(0)
                    continue
                c = np.asarray(c, dtype=float)
                # the verifier's rule (a fingertip on a box edge pushes along
                # the normal at its own closest point)
                p_s, n_s, _ = fingertip_contact(obj, c, tips[i], r)
                key = (c.tobytes(), n_s.tobytes())
                if key not in local:  # along a transfer the same cone repeats
                    local[key] = np.vstack([c[None], *_contact_strips(c, n_s, scene, cone_h)])
                pts_local = local[key]
                pts_obj.append(p_s)
                nrm_in.append(-n_s)
                pts_w = transform_points(pose, pts_local)
                points[i].append(pts_w[:1])
                strips[i].extend(np.split(pts_w[1:], np.cumsum(strip_sizes)))
                n_strips[i].append(len(strip_sizes) + 1)
            full, sub = None, None
            if fc is not None:
                key = b"".join(p.tobytes() for p in pts_obj) + bytes(w.contact_mask())
                if key not in fc_cache:
                    fc_cache[key] = _fc_values(fc, pts_obj, nrm_in, scene, ts, n)
                full, sub = fc_cache[key]
            full_q.append(full)
            sub_q.append(sub)

    for i in range(n):
        path = f"world/contacts/finger_{i}"
        lengths = [len(p) for p in points[i]]
        pos = np.concatenate(points[i]) if points[i] else np.zeros((0, 3))
        rec.send_columns(
            path, indexes=indexes, columns=rr.Points3D.columns(positions=pos).partition(lengths)
        )
        rec.send_columns(
            path + "/cone",
            indexes=indexes,
            columns=rr.LineStrips3D.columns(strips=strips[i]).partition(n_strips[i]),
        )
    if fc is None:
        return
    for path, values in (("plan/fc/full", full_q), ("plan/fc/min_subgrasp", sub_q)):
        have = np.array([v is not None for v in values], dtype=bool)
        if have.any():
            sub_idx = _plan_index(np.flatnonzero(have))
            vals = np.array([v for v in values if v is not None], dtype=float)
            rec.send_columns(path, indexes=sub_idx, columns=rr.Scalars.columns(scalars=vals))
        for step in np.flatnonzero(~have):  # break the line where it is undefined
            _set_step(rec, int(step))
            rec.log(path, rr.Clear(recursive=False))
    rec.reset_time()


def _plan_index(steps: np.ndarray) -> list[Any]:
    """The ``plan_step`` and ``time`` columns of the given steps."""
    rr = _rerun()
    steps = np.asarray(steps, dtype=np.int64)
    return [
        rr.TimeColumn(PLAN_STEP, sequence=steps),
        rr.TimeColumn(TIME, duration=steps * STEP_SECONDS),
    ]


def _fc_values(
    fc: tuple[Any, Any],
    pts: list[FloatArray],
    nrm: list[FloatArray],
    scene: _Scene,
    ts: float,
    n: int,
) -> tuple[float | None, float | None]:
    """(quality of the holding grasp, min over its subgrasps when all n fingers hold)."""
    quality, min_sub = fc
    if len(pts) < 2:
        return None, None
    P, N = np.array(pts), np.array(nrm)
    kw = {
        "edges": scene.friction_edges,
        "torque_scale": ts,
        "contact_model": scene.contact_model,
        "torsion": scene.torsion,
    }
    try:
        full = float(quality(P, N, scene.mu, **kw))
        sub = float(min_sub(P, N, scene.mu, **kw)) if len(pts) == n else None
    except DexplanError:
        return None, None
    return full, sub


# --------------------------------------------------------- roadmap alone
def _roadmap_blueprint(with_scene: bool) -> Any:
    import rerun.blueprint as rrb

    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(
                origin="world",
                name="GSn roadmap",
                eye_controls=rrb.EyeControls3D(
                    position=_EYE, look_target=_LOOK_AT, eye_up=[0.0, 0.0, 1.0]
                ),
            ),
            rrb.TextDocumentView(origin="roadmap/summary", name="Components"),
            column_shares=[3, 1],
        ),
        rrb.TimePanel(timeline=ROADMAP_NODE, state="collapsed" if with_scene else "hidden"),
        rrb.BlueprintPanel(state="collapsed"),
        collapse_panels=False,
    )


def record_roadmap(
    roadmap: Roadmap,
    path: str | Path,
    *,
    scene: Mapping[str, Any] | Any | None = None,
    base_dir: Path = Path("."),
    browse_nodes: bool = True,
) -> RoadmapSummary:
    """Write a Rerun recording (``.rrd``) of a GSn roadmap.

    Always logged (static): the nodes as object positions coloured by GSn
    connected component, small orientation axes per node, the GSn edges, the
    module-2 links in their own colour, and the per-component counts (as
    entity values on ``world/roadmap``, a Markdown table and recording
    properties).

    With ``scene`` (a plan document or a :class:`~dexplan.scenario.Scenario`)
    the hand geometry, object, goal and obstacles are drawn too, and with
    ``browse_nodes`` every node's configuration (object pose and hand links)
    is put on a ``roadmap_node`` sequence timeline, one step per vertex.

    Args:
        roadmap: the roadmap (e.g. :meth:`Roadmap.load`).
        path: output ``.rrd`` file.
        scene: models to draw: a ``dexplan-plan/1`` document, a scenario, or
            None for the roadmap alone.
        base_dir: folder relative mesh paths of a plan document resolve against.
        browse_nodes: put each node's configuration on ``roadmap_node``.

    Returns:
        The counts that were logged.

    Raises:
        DependencyError: rerun-sdk missing.
        PlanFileError: the roadmap's state size does not match the scene's hand.
        InvalidInputError: the output folder does not exist.

    """
    rr = _rerun()
    models: _Scene | None = None
    if scene is not None:
        if isinstance(scene, Mapping):
            models = _scene_from_doc(scene, Path(base_dir))
        else:
            models = _scene_from_scenario(scene)
    V = np.asarray(roadmap.vertices, dtype=float)
    if models is not None and models.hand is not None and len(V):
        want = 7 + models.hand.nq
        if V.ndim != 2 or V.shape[1] != want:
            raise PlanFileError(
                f"roadmap states have {V.shape[-1]} coordinates, the hand needs {want}"
            )
    browse = models is not None and browse_nodes and len(V) > 0
    name = f"dexplan roadmap ({roadmap.planner})"
    with _recording(path, name, _roadmap_blueprint(browse)) as rec:
        axis = 0.01
        if models is not None:
            layout = _log_scene_static(rec, models)
            assert models.obj is not None and models.hand is not None
            axis = 0.25 * models.obj.bounding_radius
            if browse:
                idx = [rr.TimeColumn(ROADMAP_NODE, sequence=np.arange(len(V), dtype=np.int64))]
                _send_configurations(rec, models, layout, idx, V[:, :7], V[:, 7:])
            else:  # one still configuration: the start (or the first node)
                pose = models.start_pose if models.start_pose is not None else (
                    V[0, :7] if len(V) else np.array([0, 0, 0, 0, 0, 0, 1.0])
                )  # fmt: skip
                q = models.start_q if models.start_q is not None else (
                    V[0, 7:] if len(V) else models.hand.neutral
                )  # fmt: skip
                _send_configurations(
                    rec, models, layout, None, np.asarray(pose)[None], np.asarray(q)[None]
                )
        else:
            rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        return _log_roadmap(rec, roadmap, axis)


def record_rejections(samples: Sequence[Any], path: str | Path, *, scenario: Any) -> int:
    """Write a Rerun recording of states the validity checker rejected (``--debug-rrd``).

    Each sample (a :class:`~dexplan.planning.validity.RejectedSample`) is one
    step of the ``rejected_sample`` timeline: the hand and the object at that
    state, with its reason and detail (the colliding pair, the force-closure
    quality) as a text entry, so the user sees why the sampler's states fail.

    Args:
        samples: the rejected states, e.g. ``PlanResult.rejections.samples``.
        path: output ``.rrd`` file.
        scenario: the :class:`~dexplan.scenario.Scenario` they belong to.

    Returns:
        The number of samples recorded.

    Raises:
        DependencyError: rerun-sdk missing.
        InvalidInputError: the output folder does not exist.
    """
    import rerun.blueprint as rrb

    rr = _rerun()
    models = _scene_from_scenario(scenario)
    assert models.hand is not None
    X = np.array([s.x for s in samples], dtype=float).reshape(-1, 7 + models.hand.nq)
    blueprint = rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(
                origin="world",
                name="Rejected samples",
                eye_controls=rrb.EyeControls3D(
                    position=_EYE, look_target=_LOOK_AT, eye_up=[0.0, 0.0, 1.0]
                ),
            ),
            rrb.TextLogView(origin="rejected", name="Why"),
            column_shares=[3, 1],
        ),
        rrb.TimePanel(timeline=REJECTED_SAMPLE, state="expanded"),
        collapse_panels=False,
    )
    with _recording(path, "dexplan rejected samples", blueprint) as rec:
        layout = _log_scene_static(rec, models)
        if len(X):
            steps = np.arange(len(X), dtype=np.int64)
            idx = [rr.TimeColumn(REJECTED_SAMPLE, sequence=steps)]
            _send_configurations(rec, models, layout, idx, X[:, :7], X[:, 7:])
            for k, smp in enumerate(samples):
                rec.set_time(REJECTED_SAMPLE, sequence=k)
                text = smp.reason + (f": {smp.detail}" if smp.detail else "")
                rec.log("rejected", rr.TextLog(text, level=rr.TextLogLevel.WARN))
    return len(X)


# ----------------------------------------------------------- files, viewer
def write_recording(
    source: str | Path | Mapping[str, Any],
    path: str | Path,
    *,
    roadmap: Roadmap | str | Path | None = None,
    plan: Mapping[str, Any] | str | Path | None = None,
    base_dir: str | Path | None = None,
) -> Path:
    """Write a recording of a plan or a roadmap, chosen by what ``source`` is.

    Args:
        source: a plan document, a plan ``.json`` file, or a roadmap ``.npz``
            file (recognised by its suffix).
        path: output ``.rrd`` file.
        roadmap: for a plan, the roadmap (object or ``.npz`` file) to add.
        plan: for a roadmap file, a plan (document or ``.json`` file) whose
            hand, object and obstacles are drawn with it, each node's
            configuration on the ``roadmap_node`` timeline.
        base_dir: folder relative mesh paths resolve against (default: the
            plan file's folder, or the working directory for a document).

    Returns:
        ``path`` as a :class:`~pathlib.Path`.

    Raises:
        DependencyError: rerun-sdk missing.
        PlanFileError: unreadable plan or roadmap file.

    """
    from dexplan.plan_file import read_plan
    from dexplan.planning.roadmap import Roadmap

    require_rerun()
    path = Path(path)

    def load_doc(item: Mapping[str, Any] | str | Path) -> tuple[Mapping[str, Any], Path]:
        if isinstance(item, Mapping):
            return item, Path(base_dir or ".")
        return read_plan(item, base_dir), Path(base_dir or Path(item).resolve().parent)

    if not isinstance(source, Mapping) and Path(source).suffix == ".npz":
        scene, folder = load_doc(plan) if plan is not None else (None, Path(base_dir or "."))
        record_roadmap(Roadmap.load(source), path, scene=scene, base_dir=folder)
        return path
    doc, folder = load_doc(source)
    rm = Roadmap.load(roadmap) if isinstance(roadmap, str | Path) else roadmap
    record_plan(doc, path, roadmap=rm, base_dir=folder)
    return path


def _has_display() -> bool:
    if sys.platform.startswith("linux"):
        return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    return True


def _viewer_command() -> list[str]:
    exe = shutil.which("rerun")
    if exe is not None:
        return [exe]
    return [sys.executable, "-m", "rerun"]


def show(
    source: str | Path | Mapping[str, Any],
    *,
    roadmap: Roadmap | str | Path | None = None,
    plan: Mapping[str, Any] | str | Path | None = None,
    base_dir: str | Path | None = None,
    wait_s: float = 1.5,
) -> Path:
    """Open a plan, roadmap or recording in the native Rerun viewer.

    A plan (document or ``.json``) or roadmap (``.npz``) is first recorded to
    a temporary ``.rrd`` (kept, so it can be reopened); an ``.rrd`` is opened
    as is. The viewer runs detached; this returns once it has started.

    Args:
        source: plan document, or a ``.json``, ``.npz`` or ``.rrd`` file.
        roadmap: roadmap to add to a plan's recording.
        plan: for a roadmap file, the plan whose models are drawn with it.
        base_dir: folder relative mesh paths resolve against.
        wait_s: seconds to watch the viewer for an immediate failure.

    Returns:
        The path of the ``.rrd`` opened.

    Raises:
        DependencyError: rerun-sdk missing, or no display to open a window on
            (headless machine: write the file with :func:`write_recording`
            and open it elsewhere, or serve it with ``rerun --serve-web``).
        DexplanError: the viewer exited at once (its message is included).
        PlanFileError: the file does not exist or cannot be read.

    """
    require_rerun()
    if isinstance(source, str | Path) and not Path(source).is_file():
        raise PlanFileError(f"file not found: {str(source)!r}")
    if not _has_display():
        raise DependencyError(
            "cannot open the Rerun viewer: no display (DISPLAY/WAYLAND_DISPLAY unset); "
            "write the recording to a file instead (dexplan show PLAN --save out.rrd) and "
            "open it with `rerun out.rrd` on a machine with a display, or serve it to a "
            "browser with `rerun --serve-web out.rrd`"
        )
    if isinstance(source, str | Path) and Path(source).suffix == ".rrd":
        rrd = Path(source)
    else:
        fd, tmp = tempfile.mkstemp(prefix="dexplan-", suffix=".rrd")
        os.close(fd)
        rrd = write_recording(source, tmp, roadmap=roadmap, plan=plan, base_dir=base_dir)
    cmd = [*_viewer_command(), str(rrd)]
    log = tempfile.TemporaryFile()  # noqa: SIM115 - the viewer's stderr, read back on failure
    try:
        proc = subprocess.Popen(
            cmd,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=log,
            start_new_session=True,
        )
    except OSError as exc:
        log.close()
        raise DependencyError(f"cannot start the Rerun viewer ({cmd[0]}): {exc}") from exc
    deadline = time.monotonic() + max(0.0, wait_s)
    try:
        while time.monotonic() < deadline:
            if proc.poll() is not None:
                log.seek(0)
                err = log.read().decode(errors="replace")
                tail = "\n".join(err.strip().splitlines()[-5:])
                raise DexplanError(
                    f"the Rerun viewer exited at once (code {proc.returncode}) on {rrd}: {tail}"
                )
            time.sleep(0.05)
    finally:
        log.close()
    return rrd
