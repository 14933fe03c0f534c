"""Closest points on triangles, with the Voronoi region (feature) they lie in.

Ericson's Voronoi-region test (*Real-Time Collision Detection*, 5.1.5), one
point in scalar arithmetic (:func:`closest_on_triangle`, the fast path of a
single query) or many point-triangle pairs vectorised
(:func:`closest_on_triangles`).
"""

from __future__ import annotations

import numpy as np

from dexplan.core.typing import FloatArray, IntArray

__all__ = [
    "EAB",
    "EAC",
    "EBC",
    "FACE",
    "VA",
    "VB",
    "VC",
    "closest_on_triangle",
    "closest_on_triangles",
]

#: Voronoi regions of a triangle ABC: its vertices, its edges, its face.
VA, VB, VC, EAB, EAC, EBC, FACE = range(7)


def closest_on_triangle(
    px: float, py: float, pz: float, tri: list[list[float]]
) -> tuple[float, float, float, float, float, int]:
    """Closest point of triangle ``tri = [A, B, C]`` to ``p`` (scalar Ericson).

    Returns:
        ``(qx, qy, qz, u, v, region)`` with ``q = A + u (B - A) + v (C - A)``.

    """
    (ax, ay, az), (bx, by, bz), (cx, cy, cz) = tri
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return ax, ay, az, 0.0, 0.0, VA
    bpx, bpy, bpz = px - bx, py - by, pz - bz
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return bx, by, bz, 1.0, 0.0, VB
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        w = d1 / (d1 - d3)
        return ax + w * abx, ay + w * aby, az + w * abz, w, 0.0, EAB
    cpx, cpy, cpz = px - cx, py - cy, pz - cz
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return cx, cy, cz, 0.0, 1.0, VC
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        return ax + w * acx, ay + w * acy, az + w * acz, 0.0, w, EAC
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return bx + w * (cx - bx), by + w * (cy - by), bz + w * (cz - bz), 1.0 - w, w, EBC
    den = 1.0 / (va + vb + vc)
    u = vb * den
    v = vc * den
    return (
        ax + u * abx + v * acx,
        ay + u * aby + v * acy,
        az + u * abz + v * acz,
        u,
        v,
        FACE,
    )


def closest_on_triangles(
    p: FloatArray, a: FloatArray, b: FloatArray, c: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, IntArray]:
    """Vectorized :func:`closest_on_triangle`: point ``p[i]`` against triangle ``i``.

    Args:
        p: (N, 3) points.
        a: (N, 3) first corners.
        b: (N, 3) second corners.
        c: (N, 3) third corners.

    Returns:
        ``(q (N, 3), u (N,), v (N,), region (N,))``.

    """
    ab = b - a
    ac = c - a
    ap = p - a
    bp = p - b
    cp = p - c
    d1 = np.einsum("ij,ij->i", ab, ap)
    d2 = np.einsum("ij,ij->i", ac, ap)
    d3 = np.einsum("ij,ij->i", ab, bp)
    d4 = np.einsum("ij,ij->i", ac, bp)
    d5 = np.einsum("ij,ij->i", ab, cp)
    d6 = np.einsum("ij,ij->i", ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        den = va + vb + vc
        u = vb / den
        v = vc / den
        region = np.full(len(p), FACE)
        # Assign from the lowest-priority region to the highest (Ericson's test
        # order reversed) so that the first region that holds wins.
        m = (va <= 0.0) & (d4 - d3 >= 0.0) & (d5 - d6 >= 0.0)
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        u[m], v[m], region[m] = 1.0 - w[m], w[m], EBC
        m = (vb <= 0.0) & (d2 >= 0.0) & (d6 <= 0.0)
        w = d2 / (d2 - d6)
        u[m], v[m], region[m] = 0.0, w[m], EAC
        m = (d6 >= 0.0) & (d5 <= d6)
        u[m], v[m], region[m] = 0.0, 1.0, VC
        m = (vc <= 0.0) & (d1 >= 0.0) & (d3 <= 0.0)
        w = d1 / (d1 - d3)
        u[m], v[m], region[m] = w[m], 0.0, EAB
        m = (d3 >= 0.0) & (d4 <= d3)
        u[m], v[m], region[m] = 1.0, 0.0, VB
        m = (d1 <= 0.0) & (d2 <= 0.0)
        u[m], v[m], region[m] = 0.0, 0.0, VA
    q = a + u[:, None] * ab + v[:, None] * ac
    # exact corners (the formula above can be off by one ulp there)
    q[region == VB] = b[region == VB]
    q[region == VC] = c[region == VC]
    return q, u, v, region
