"""The GSn roadmap: vertices, GSn edges, module-2 links, components and paths.

A :class:`Roadmap` is what module 1 explored (ambient GSn states joined by
GSn motions) plus the transfer-regrasp links module 2 made between its
components. It can be saved (``.npz``, :mod:`dexplan.planning.roadmap.file`)
and loaded to answer later queries; :func:`scenario_key` names the models it
belongs to.
"""

from __future__ import annotations

import hashlib
import itertools
import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components as _csgraph_components
from scipy.sparse.csgraph import dijkstra

from dexplan.core.errors import InvalidInputError, RoadmapFileError, shorten
from dexplan.core.files import atomic_output
from dexplan.core.pose import quat_angle
from dexplan.core.typing import FloatArray
from dexplan.model.scenario import scenario_description
from dexplan.planning.gsn.space import POSE_DIM
from dexplan.planning.roadmap.file import ROADMAP_FORMAT, read_roadmap_arrays

if TYPE_CHECKING:  # annotation only: the planning context loads OMPL, a roadmap does not need it
    from dexplan.planning.context import PlanningContext

__all__ = [
    "Geodesic",
    "Roadmap",
    "connected_components",
    "pose_distance",
    "pose_distances",
    "scenario_key",
]


Geodesic = Callable[[FloatArray, FloatArray], FloatArray | None]
"""``(a, b) -> (K, n)`` states of the GSn motion from a to b, or None."""


def connected_components(n: int, edges: object) -> tuple[np.ndarray, np.ndarray]:
    """Label the connected components of an undirected graph.

    Args:
        n: number of vertices N (vertices are ``0..N-1``).
        edges: ``(E, 2)`` integer vertex pairs; direction is ignored, self-loops and
            duplicates are allowed.

    Returns:
        ``(labels, sizes)``: ``labels`` ``(N,)`` int64, the component of each vertex,
        numbered ``0..C-1`` by first appearance; ``sizes`` ``(C,)`` int64 vertex counts.

    Raises:
        InvalidInputError: negative ``n``, wrong edge shape or an index out of range.

    """
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 0:
        raise InvalidInputError(f"n must be an integer >= 0, got {n!r}")
    n = int(n)
    arr = np.asarray(edges)
    if arr.size == 0:
        arr = np.zeros((0, 2), dtype=np.int64)
    if arr.ndim != 2 or arr.shape[1] != 2 or not np.issubdtype(arr.dtype, np.integer):
        raise InvalidInputError(f"edges must be an (E, 2) integer array, got shape {arr.shape}")
    arr = arr.astype(np.int64, copy=False)
    if arr.size and (arr.min() < 0 or arr.max() >= n):
        raise InvalidInputError(
            f"edges index vertices outside 0..{n - 1}: min {arr.min()}, max {arr.max()}"
        )
    if n == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    graph = coo_matrix(
        (np.ones(arr.shape[0], dtype=np.int8), (arr[:, 0], arr[:, 1])), shape=(n, n)
    ).tocsr()
    _, raw = _csgraph_components(graph, directed=False)
    # renumber by first appearance so labels do not depend on scipy's internals
    _, first, inverse = np.unique(raw, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    labels = rank[inverse].astype(np.int64)
    sizes = np.bincount(labels, minlength=order.size).astype(np.int64)
    return labels, sizes


def pose_distance(a: FloatArray, b: FloatArray, length: float = 0.05) -> float:
    """Object-pose distance of two states: translation / length + rotation angle."""
    return float(np.linalg.norm(a[:3] - b[:3])) / length + quat_angle(a[3:7], b[3:7])


def pose_distances(a: FloatArray, b: FloatArray, length: float = 0.05) -> FloatArray:
    """:func:`pose_distance` of broadcast arrays of states ``(..., 7 + nq)``: ``(...)``.

    The angle is ``2 acos |<qa, qb>|`` of the normalised quaternions (q and -q
    are the same orientation).
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    dp = np.linalg.norm(a[..., :3] - b[..., :3], axis=-1)
    qa = a[..., 3:POSE_DIM] / np.linalg.norm(a[..., 3:POSE_DIM], axis=-1, keepdims=True)
    qb = b[..., 3:POSE_DIM] / np.linalg.norm(b[..., 3:POSE_DIM], axis=-1, keepdims=True)
    dot = np.clip(np.abs(np.sum(qa * qb, axis=-1)), 0.0, 1.0)
    return dp / length + 2.0 * np.arccos(dot)


@dataclass
class Roadmap:
    """A GSn roadmap with module-2 links.

    Attributes:
        vertices: (N, 7 + nq) ambient GSn states.
        edges: (E, 2) vertex index pairs joined by a GSn motion.
        links: (L, 2) vertex index pairs joined by a transfer-regrasp sequence.
        planner: name of the OMPL planner that built it.
        scenario_key: hash of the models it belongs to (hand, object, obstacles, friction).
        build: how it was built (the learning phase's statistics,
            :class:`~dexplan.planning.roadmap.learning.BuildStats` as a mapping), or empty.
    """

    vertices: FloatArray
    edges: np.ndarray
    links: np.ndarray
    planner: str
    scenario_key: str
    build: dict[str, Any] = field(default_factory=dict)

    @property
    def n_vertices(self) -> int:
        """Number of vertices."""
        return len(self.vertices)

    def components(self, with_links: bool = True) -> tuple[int, np.ndarray]:
        """Connected components (:func:`connected_components`): ``(count, labels (N,))``."""
        pairs = [self.edges]
        if with_links and len(self.links):
            pairs.append(self.links)
        e = np.vstack(pairs).astype(np.int64).reshape(-1, 2)
        labels, sizes = connected_components(self.n_vertices, e)
        return len(sizes), labels

    def add_vertex(self, x: FloatArray) -> int:
        """Append a vertex; returns its index."""
        self.vertices = np.vstack([self.vertices, x[None]])
        return self.n_vertices - 1

    def add_link(self, a: int, b: int) -> None:
        """Record a module-2 link between vertices a and b."""
        self.links = np.vstack([self.links, [[a, b]]]).astype(np.int64)

    def shortest_path(self, source: int, targets: list[int]) -> list[int] | None:
        """Vertex sequence from ``source`` to the nearest of ``targets`` (object-pose metric)."""
        e = np.vstack([self.edges, self.links]) if len(self.links) else self.edges
        if len(e) == 0 or not targets:
            return None
        e = np.asarray(e, dtype=np.int64).reshape(-1, 2)
        w = pose_distances(self.vertices[e[:, 0]], self.vertices[e[:, 1]]) + 1e-9
        n = self.n_vertices
        g = coo_matrix(
            (
                np.concatenate([w, w]),
                (np.concatenate([e[:, 0], e[:, 1]]), np.concatenate([e[:, 1], e[:, 0]])),
            ),
            shape=(n, n),
        ).tocsr()
        dist, pred = dijkstra(g, indices=source, return_predecessors=True)
        best = min(targets, key=lambda t: dist[t])
        if not np.isfinite(dist[best]):
            return None
        path = [best]
        while path[-1] != source:
            path.append(int(pred[path[-1]]))
        return path[::-1]

    def path_states(self, ids: list[int], geodesic: Geodesic | None = None) -> FloatArray:
        """States along a vertex path: GSn edges densified by ``geodesic``, links as they are.

        Args:
            ids: vertex indices, consecutive ones joined by an edge or a link.
            geodesic: ``(a, b) -> (K, n)`` states of the GSn motion a -> b (ends
                included), or None when it cannot give one; None keeps the vertices.

        Returns:
            (M, 7 + nq) states. Without densification the object would move on
            the chord between two GSn states, which need not clear the obstacles
            the GSn motion clears.
        """
        links = {tuple(sorted(pair)) for pair in self.links.tolist()}
        out = [self.vertices[ids[0]]]
        for a, b in itertools.pairwise(ids):
            if geodesic is not None and tuple(sorted((a, b))) not in links:
                states = geodesic(self.vertices[a], self.vertices[b])
                if states is not None:
                    out.extend(states[1:])
                    continue
            out.append(self.vertices[b])
        return np.array(out)

    # ------------------------------------------------------------------ files
    def save(self, path: str | Path) -> None:
        """Write the roadmap to ``path`` (``.npz``, :data:`ROADMAP_FORMAT`), atomically.

        A reader never sees a half-written file: the archive is written next to
        ``path`` and renamed over it once complete.
        """
        path = Path(path)
        fields: dict[str, Any] = {
            "format": ROADMAP_FORMAT,
            "planner": self.planner,
            "scenario_key": self.scenario_key,
        }
        if self.build:
            fields["build"] = dict(self.build)
        meta = json.dumps(fields, sort_keys=True)
        with atomic_output(path, "roadmap") as tmp, open(tmp, "wb") as fh:
            np.savez_compressed(
                fh,
                vertices=np.asarray(self.vertices, dtype=np.float64),
                edges=np.asarray(self.edges, dtype=np.int64).reshape(-1, 2),
                links=np.asarray(self.links, dtype=np.int64).reshape(-1, 2),
                meta=np.array(meta),
            )

    @classmethod
    def load(
        cls, path: str | Path, scenario_key: str | None = None, *, ambient_dim: int | None = None
    ) -> Roadmap:
        """Read and validate a roadmap file (see :func:`read_roadmap_arrays` for the checks).

        Args:
            path: a ``.npz`` file written by :meth:`save`.
            scenario_key: when given, refuse a roadmap built for other models.
            ambient_dim: when given, the vertex width the hand needs (7 + nq).

        Raises:
            RoadmapFileError: missing, unreadable or malformed file (the message
                names the array or field), or a roadmap of other models. It is a
                :class:`~dexplan.core.errors.PlanFileError`.
        """
        path = Path(path)
        where = shorten(str(path))
        vertices, edges, links, meta = read_roadmap_arrays(path, ambient_dim=ambient_dim)
        if scenario_key is not None and meta["scenario_key"] != scenario_key:
            raise RoadmapFileError(
                f"{where}: roadmap was built for other models (hand, object, obstacles or "
                "friction differ)"
            )
        return cls(
            vertices, edges, links, meta["planner"], meta["scenario_key"], meta.get("build", {})
        )


def scenario_key(ctx: PlanningContext) -> str:
    """Hash of the models a roadmap depends on (the scenario identity, models only).

    The hand enters by its URDF text too, so a builtin hand whose model
    changes between versions does not reuse old roadmaps.
    """
    payload = json.dumps(
        {
            "models": scenario_description(ctx.scenario, models_only=True),
            "urdf": hashlib.sha256(ctx.hand.urdf_xml.encode()).hexdigest(),
        },
        sort_keys=True,
    )
    return hashlib.sha256(payload.encode()).hexdigest()[:16]
