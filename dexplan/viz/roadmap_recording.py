"""Recordings of GSn roadmaps: per-component counts, nodes, edges and module-2 links."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from dexplan.core.errors import PlanFileError
from dexplan.core.typing import FloatArray, IntArray
from dexplan.model.scenario import Scenario
from dexplan.planning.roadmap.graph import Roadmap
from dexplan.viz.blueprints import roadmap_blueprint
from dexplan.viz.scene import (
    HandLayout,
    Scene,
    log_scene_static,
    scene_from,
    send_configurations,
)
from dexplan.viz.session import COMPONENTS, LINK_COLOR, ROADMAP_NODE, recording, rerun_module, rgba

if TYPE_CHECKING:  # rerun's types for annotations; at run time rerun loads on first use
    import rerun


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
    if len(li):
        np.add.at(links, labels[li[:, 0]], 1)
        other = labels[li[:, 1]] != labels[li[:, 0]]
        np.add.at(links, labels[li[other, 1]], 1)
    first = np.unique(labels, return_index=True)[1] if n_c else np.zeros(0, int)
    merged = merged_labels[first] if n_c else np.zeros(0, int)
    return RoadmapSummary(
        n_c,
        n_m,
        tuple(int(v) for v in nodes),
        tuple(int(v) for v in edges),
        tuple(int(v) for v in links),
        tuple(int(v) for v in merged),
    )


# ---------------------------------------------------------------- logging
def _component_color(k: int) -> tuple[int, int, int]:
    return COMPONENTS[k % len(COMPONENTS)]


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


def _pairs(index_pairs: npt.ArrayLike) -> IntArray:
    """Vertex index pairs as an ``(E, 2)`` int64 array."""
    return np.asarray(index_pairs, dtype=np.int64).reshape(-1, 2)


def _segments(P: FloatArray, pairs: IntArray) -> FloatArray:
    """``(E, 2, 3)`` line segments between the points of each index pair."""
    return np.stack([P[pairs[:, 0]], P[pairs[:, 1]]], axis=1) if len(pairs) else np.zeros((0, 2, 3))


def _log_counts(rec: rerun.RecordingStream, roadmap: Roadmap, summary: RoadmapSummary) -> None:
    """Component classes and per-component counts on ``world/roadmap`` (static)."""
    rr = rerun_module()
    _log_component_classes(rec, "world/roadmap", summary)
    rec.log(
        "world/roadmap",
        rr.AnyValues(
            component=list(range(summary.components)),
            nodes_per_component=list(summary.nodes),
            edges_per_component=list(summary.edges),
            links_per_component=list(summary.links),
            merged_component=list(summary.merged),
            **{f"n_{k}": v for k, v in _totals(roadmap, summary).items()},
            planner=str(roadmap.planner),
        ),
        static=True,
    )


def _totals(roadmap: Roadmap, summary: RoadmapSummary) -> dict[str, int]:
    """Node, edge, link and component counts of the whole roadmap."""
    return {
        "nodes": int(roadmap.n_vertices),
        "edges": len(roadmap.edges),
        "links": len(roadmap.links),
        "components": summary.components,
        "merged_components": summary.merged_components,
    }


def _log_node_axes(rec: rerun.RecordingStream, V: FloatArray, axis_length: float) -> None:
    """Small x, y, z axes (red, green, blue) at each node's object orientation.

    ``V: (N, 7 + nq)`` are the roadmap's states (object pose in the world frame first).
    """
    rr = rerun_module()
    P = V[:, :3]
    R = _quat_matrices(V[:, 3:7])
    palette = np.array([(230, 60, 60), (60, 200, 60), (60, 90, 230)], dtype=np.uint8)
    ends = P[:, None, :] + axis_length * np.moveaxis(R, 2, 1)  # (N, axis, 3)
    strips = np.stack([np.repeat(P[None], 3, axis=0), np.moveaxis(ends, 1, 0)], axis=2)
    rec.log(
        "world/roadmap/axes",
        rr.LineStrips3D(
            strips.reshape(-1, 2, 3), colors=np.repeat(palette, len(P), axis=0), radii=[0.0003]
        ),
        static=True,
    )


def rotation_vectors(q_xyzw: FloatArray) -> FloatArray:
    """Rotation vectors ``(N, 3)`` (axis times angle, rad, angle in [0, pi]) of quaternions.

    q and -q give the same vector (the one with ``w >= 0`` is used).
    """
    q = np.asarray(q_xyzw, dtype=float).reshape(-1, 4)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    q = np.where(q[:, 3:4] < 0.0, -q, q)
    s = np.linalg.norm(q[:, :3], axis=1)
    angle = 2.0 * np.arctan2(s, q[:, 3])
    scale = np.where(s > 1e-12, angle / np.maximum(s, 1e-12), 2.0)
    return q[:, :3] * scale[:, None]


def log_orientations(rec: rerun.RecordingStream, roadmap: Roadmap) -> None:
    """The roadmap in orientation space (static, under ``orientation``).

    Nodes at the object's rotation vector (rad; the ball of radius pi),
    coloured by GSn component, GSn edges in the component's colour, module-2
    links in their own colour: one archetype each, so 10k nodes stay light.
    """
    rr = rerun_module()
    summary = summarize_roadmap(roadmap)
    _, labels = roadmap.components(with_links=False)
    V = np.asarray(roadmap.vertices, dtype=float)
    P = rotation_vectors(V[:, 3:7]) if len(V) else np.zeros((0, 3))
    rec.log("orientation", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    _log_component_classes(rec, "orientation", summary)
    rec.log(
        "orientation/nodes",
        rr.Points3D(P, class_ids=labels.astype(np.uint16), radii=[0.02], show_labels=False),
        static=True,
    )
    _log_graph_lines(rec, "orientation", roadmap, P, labels, (0.004, 0.01))


def log_roadmap(rec: rerun.RecordingStream, roadmap: Roadmap, axis_length: float) -> RoadmapSummary:
    """Log nodes (coloured by component), orientation axes, edges and module-2 links (static).

    Returns:
        The per-component counts that were logged.
    """
    rr = rerun_module()
    summary = summarize_roadmap(roadmap)
    _, labels = roadmap.components(with_links=False)
    V = np.asarray(roadmap.vertices, dtype=float)
    P = V[:, :3]
    _log_counts(rec, roadmap, summary)
    rec.log(
        "world/roadmap/nodes",
        rr.Points3D(P, class_ids=labels.astype(np.uint16), radii=[0.0015], show_labels=False),
        static=True,
    )
    if len(V):
        _log_node_axes(rec, V, axis_length)
    _log_graph_lines(rec, "world/roadmap", roadmap, P, labels, (0.0005, 0.0012))
    rec.log(
        "roadmap/summary",
        rr.TextDocument(summary.markdown(), media_type=rr.MediaType.MARKDOWN),
        static=True,
    )
    rec.send_property(
        "roadmap", rr.AnyValues(**_totals(roadmap, summary), planner=str(roadmap.planner))
    )
    return summary


# ------------------------------------------------------------- recording
def record_roadmap(
    roadmap: Roadmap,
    path: str | Path,
    *,
    scene: Mapping[str, Any] | Scenario | None = None,
    base_dir: Path = Path("."),
    browse_nodes: bool = True,
) -> RoadmapSummary:
    """Write a Rerun recording (``.rrd``) of a GSn roadmap.

    Always logged (static): the nodes as object positions coloured by GSn
    connected component, small orientation axes per node, the GSn edges, the
    module-2 links in their own colour, and the per-component counts (as
    entity values on ``world/roadmap``, a Markdown table and recording
    properties); the same graph in orientation space under ``orientation``
    (nodes at the object's rotation vector, :func:`log_orientations`).

    With ``scene`` (a plan document or a :class:`~dexplan.model.scenario.scenario.Scenario`)
    the hand geometry, object, goal and obstacles are drawn too, and with
    ``browse_nodes`` every node's configuration (object pose and hand links)
    is put on a ``roadmap_node`` sequence timeline, one step per vertex.

    Args:
        roadmap: the roadmap (e.g. :meth:`Roadmap.load`).
        path: output ``.rrd`` file.
        scene: models to draw: a ``dexplan-plan/2`` document, a scenario, or
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
    rr = rerun_module()
    models = scene_from(scene, Path(base_dir)) if scene is not None else None
    V = np.asarray(roadmap.vertices, dtype=float)
    if models is not None:
        _check_state_size(models, V)
    browse = models is not None and browse_nodes and len(V) > 0
    name = f"dexplan roadmap ({roadmap.planner})"
    with recording(path, name, roadmap_blueprint(browse)) as rec:
        log_orientations(rec, roadmap)
        if models is None:
            rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
            return log_roadmap(rec, roadmap, 0.01)
        layout = log_scene_static(rec, models)
        assert models.obj is not None and models.hand is not None
        if browse:
            idx = [rr.TimeColumn(ROADMAP_NODE, sequence=np.arange(len(V), dtype=np.int64))]
            send_configurations(rec, models, layout, idx, V[:, :7], V[:, 7:])
        else:
            _send_still_configuration(rec, models, layout, V)
        return log_roadmap(rec, roadmap, 0.25 * models.obj.bounding_radius)


def _check_state_size(models: Scene, V: FloatArray) -> None:
    """Raise PlanFileError unless the states ``V: (N, d)`` are object pose + the hand's joints."""
    if models.hand is not None and len(V):
        want = 7 + models.hand.nq
        if V.ndim != 2 or V.shape[1] != want:
            raise PlanFileError(
                f"roadmap states have {V.shape[-1]} coordinates, the hand needs {want}"
            )


def _send_still_configuration(
    rec: rerun.RecordingStream, models: Scene, layout: HandLayout | None, V: FloatArray
) -> None:
    """One static configuration: the scene's start, else the first node, else neutral.

    ``V: (N, 7 + nq)`` are the roadmap's states (object pose in the world frame first).
    """
    assert models.hand is not None
    pose = models.start_pose if models.start_pose is not None else (
        V[0, :7] if len(V) else np.array([0, 0, 0, 0, 0, 0, 1.0])
    )  # fmt: skip
    q = models.start_q if models.start_q is not None else (
        V[0, 7:] if len(V) else models.hand.neutral
    )  # fmt: skip
    send_configurations(rec, models, layout, None, np.asarray(pose)[None], np.asarray(q)[None])


def _log_graph_lines(
    rec: rerun.RecordingStream,
    prefix: str,
    roadmap: Roadmap,
    P: FloatArray,
    labels: IntArray,
    radii: tuple[float, float],
) -> None:
    """GSn edges (coloured by component) and module-2 links (one colour) as two line batches.

    Args:
        rec: the recording stream.
        prefix: entity path the ``edges`` and ``links`` go under.
        roadmap: the roadmap.
        P: (V, 3) where each vertex is drawn.
        labels: (V,) component label of each vertex.
        radii: line radii of the edges and the links.
    """
    rr = rerun_module()
    e = _pairs(roadmap.edges)
    rec.log(
        f"{prefix}/edges",
        rr.LineStrips3D(
            _segments(P, e),
            class_ids=labels[e[:, 0]].astype(np.uint16) if len(e) else None,
            radii=[radii[0]],
            show_labels=False,
        ),
        static=True,
    )
    rec.log(
        f"{prefix}/links",
        rr.LineStrips3D(
            _segments(P, _pairs(roadmap.links)), colors=[rgba(LINK_COLOR)], radii=[radii[1]]
        ),
        static=True,
    )


def _log_component_classes(rec: rerun.RecordingStream, path: str, summary: RoadmapSummary) -> None:
    """One annotation class per component (its colour and node count) at ``path``, static."""
    rr = rerun_module()
    rec.log(
        path,
        rr.AnnotationContext(
            [
                (k, f"component {k} ({summary.nodes[k]} nodes)", _component_color(k))
                for k in range(summary.components)
            ]
        ),
        static=True,
    )
