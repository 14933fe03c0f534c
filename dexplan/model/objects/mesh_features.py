"""Sharp convex edges and vertices of a triangle mesh, where a fingertip pushes along a cone.

A fingertip sphere touching a mesh on a sharp convex edge pushes along any
direction between the normals of the two faces that meet there; at a sharp
convex vertex, along any direction inside the cone of the incident faces'
normals. Such contacts are the landings no face point offers (a mesh cube
held on two opposite faces: the way onto a third one), as on a
:class:`~dexplan.model.objects.primitives.Box`.

Only sharp, convex features are kept: an edge whose faces' normals differ by
less than :data:`SHARP_EDGE_MIN` is a tessellated curve (the face points
already cover it), and a sphere cannot touch a concave edge's line or a
concave vertex. Adjacency, dihedral angles and convexity come from trimesh.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import trimesh

from dexplan.core.typing import FloatArray, IntArray
from dexplan.model.objects.primitives import EDGE_NORMAL_MIN

__all__ = ["SHARP_EDGE_MIN", "SharpFeatures", "sharp_features"]

#: Smallest angle (rad) between the two faces' normals of a sharp edge.
SHARP_EDGE_MIN = math.radians(20.0)

#: Rounds of rejection sampling of a vertex normal before the vertex's own
#: pseudo-normal (always inside its cone) is used instead.
_VERTEX_ROUNDS = 64


@dataclass(frozen=True)
class SharpFeatures:
    """The sharp convex edges and vertices of a mesh (object frame).

    Attributes:
        edge_a: (E, 3) first end of each sharp edge (m).
        edge_b: (E, 3) second end (m).
        edge_n1: (E, 3) outward unit normal of one face at the edge.
        edge_n2: (E, 3) outward unit normal of the other face.
        vertex_p: (K, 3) sharp convex vertices (m).
        vertex_pn: (K, 3) their unit pseudo-normals (inside their cones).
        vertex_normals: K arrays (m_k, 3), the distinct incident face normals.
        vertex_edges: K arrays (e_k, 3), unit directions of the incident edges,
            pointing away from the vertex.
    """

    edge_a: FloatArray
    edge_b: FloatArray
    edge_n1: FloatArray
    edge_n2: FloatArray
    vertex_p: FloatArray
    vertex_pn: FloatArray
    vertex_normals: tuple[FloatArray, ...]
    vertex_edges: tuple[FloatArray, ...]

    def sample_edges(self, n: int, rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
        """``n`` points on the sharp edges (uniform in length), normals between the faces'.

        The normal is the slerp of the two face normals at an angle from the
        first drawn uniformly in ``[m, phi - m]`` (``phi`` the angle between
        them, ``m = min(EDGE_NORMAL_MIN, phi / 4)``): perpendicular to the
        edge and inside its wedge, so a fingertip centre at ``p + r n`` lies in
        the edge's Voronoi region and its closest surface point is ``p``.
        Nothing is drawn from ``rng`` when ``n`` is 0 or there are no sharp edges.

        Returns:
            ``(points, normals_out)``: (m, 3) each, m = n (0 without sharp edges).
        """
        if n == 0 or len(self.edge_a) == 0:
            return np.zeros((0, 3)), np.zeros((0, 3))
        length = np.linalg.norm(self.edge_b - self.edge_a, axis=1)
        e = rng.choice(len(length), size=n, p=length / length.sum())
        t = rng.random(n)[:, None]
        pts = (1.0 - t) * self.edge_a[e] + t * self.edge_b[e]
        n1, n2 = self.edge_n1[e], self.edge_n2[e]
        phi = np.arccos(np.clip(np.einsum("ij,ij->i", n1, n2), -1.0, 1.0))
        margin = np.minimum(EDGE_NORMAL_MIN, phi / 4.0)
        theta = margin + rng.random(n) * (phi - 2.0 * margin)
        s = np.sin(phi)[:, None]
        normals = (np.sin(phi - theta)[:, None] * n1 + np.sin(theta)[:, None] * n2) / s
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        return pts, normals

    def sample_vertices(self, n: int, rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
        """``n`` points at the sharp vertices (uniform), normals inside their cones.

        Each normal is a random convex combination (flat Dirichlet weights) of
        the vertex's distinct incident face normals, normalised, and kept only
        if it makes at least :data:`EDGE_NORMAL_MIN` beyond a right angle
        with every incident edge: a fingertip centre at ``p + r n`` is then
        in the vertex's Voronoi region, so its closest surface point is the
        vertex. Nothing is drawn from ``rng`` when ``n`` is 0 or there are no
        sharp vertices.

        Returns:
            ``(points, normals_out)``: (m, 3) each, m = n (0 without sharp vertices).
        """
        if n == 0 or len(self.vertex_p) == 0:
            return np.zeros((0, 3)), np.zeros((0, 3))
        which = rng.integers(len(self.vertex_p), size=n)
        low = math.sin(EDGE_NORMAL_MIN)
        normals = self.vertex_pn[which].copy()
        for i, k in enumerate(which.tolist()):
            cone, edges = self.vertex_normals[k], self.vertex_edges[k]
            for _ in range(_VERTEX_ROUNDS):
                v = rng.dirichlet(np.ones(len(cone))) @ cone
                v /= np.linalg.norm(v)
                if np.all(edges @ v <= -low):
                    normals[i] = v
                    break
        return self.vertex_p[which], normals


def sharp_features(vertices: FloatArray, faces: IntArray, vertex_pn: FloatArray) -> SharpFeatures:
    """The sharp convex edges and vertices of a closed, outward-wound mesh.

    Args:
        vertices: (V, 3) vertex positions, object frame (m).
        faces: (F, 3) vertex indices, counter-clockwise seen from outside.
        vertex_pn: (V, 3) unit angle-weighted pseudo-normals of the vertices.

    Returns:
        The edges whose faces' normals differ by at least
        :data:`SHARP_EDGE_MIN` on the convex side, and the vertices whose
        pseudo-normal makes at least :data:`EDGE_NORMAL_MIN` beyond a right
        angle with every incident edge (convex corners with a cone to sample).
    """
    tm = trimesh.Trimesh(vertices, faces, process=False)
    adj = tm.face_adjacency
    sharp = tm.face_adjacency_convex & (tm.face_adjacency_angles >= SHARP_EDGE_MIN)
    ends = tm.face_adjacency_edges[sharp]
    fn = tm.face_normals
    low = math.sin(EDGE_NORMAL_MIN)
    # a vertex is a corner when its pseudo-normal points at least EDGE_NORMAL_MIN
    # beyond a right angle from every incident edge (flat and edge-line vertices
    # have an edge at a right angle, concave ones one at an acute angle)
    ij = tm.edges_unique
    d = vertices[ij[:, 1]] - vertices[ij[:, 0]]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    worst = np.full(len(vertices), -np.inf)
    np.maximum.at(worst, ij[:, 0], np.einsum("ij,ij->i", d, vertex_pn[ij[:, 0]]))
    np.maximum.at(worst, ij[:, 1], -np.einsum("ij,ij->i", d, vertex_pn[ij[:, 1]]))
    worst[np.setdiff1d(np.arange(len(vertices)), ij)] = np.inf  # vertices of no face
    idx = np.flatnonzero(worst <= -low)
    cones: list[FloatArray] = []
    dirs: list[FloatArray] = []
    for k in idx.tolist():
        out = vertices[tm.vertex_neighbors[k]] - vertices[k]
        dirs.append(out / np.linalg.norm(out, axis=1, keepdims=True))
        around = tm.vertex_faces[k]
        cones.append(np.unique(np.round(fn[around[around >= 0]], 12), axis=0))
    return SharpFeatures(
        edge_a=np.asarray(vertices[ends[:, 0]], dtype=np.float64),
        edge_b=np.asarray(vertices[ends[:, 1]], dtype=np.float64),
        edge_n1=np.asarray(fn[adj[sharp, 0]], dtype=np.float64),
        edge_n2=np.asarray(fn[adj[sharp, 1]], dtype=np.float64),
        vertex_p=np.asarray(vertices[idx], dtype=np.float64).reshape(-1, 3),
        vertex_pn=np.asarray(vertex_pn[idx], dtype=np.float64).reshape(-1, 3),
        vertex_normals=tuple(cones),
        vertex_edges=tuple(dirs),
    )
