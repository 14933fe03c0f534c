"""Rigid poses as ``pose_xyzquat: (7,)`` = position then quaternion XYZW.

Small, allocation-light NumPy helpers used in hot paths (the GSn constraint,
transfers). Quaternions are XYZW everywhere, as in Pinocchio's XYZQUAT; ``q``
and ``-q`` are the same orientation.
"""

from __future__ import annotations

import math

import numpy as np

from dexplan.core.typing import FloatArray

IDENTITY_XYZQUAT: FloatArray = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0])


def length(v: FloatArray) -> float:
    """Euclidean length of a contiguous float64 vector ``v: (k,)``, as ``np.linalg.norm(v)``.

    Bit for bit: ``np.linalg.norm`` computes ``sqrt(v . v)`` too, after a few
    microseconds of argument handling, and the hot paths (a waypoint's
    contacts, a roll's substeps) ask for thousands of lengths a plan.
    """
    return math.sqrt(float(v.dot(v)))


def quat_to_matrix(q_xyzw: FloatArray) -> FloatArray:
    """Rotation matrix ``R: (3, 3)`` of a unit quaternion ``q_xyzw: (4,)``."""
    # Python floats: the same products as NumPy's scalars, at half the cost
    x, y, z, w = q_xyzw.tolist() if isinstance(q_xyzw, np.ndarray) else q_xyzw
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    return np.array(
        [
            [1 - 2 * (yy + zz), 2 * (xy - wz), 2 * (xz + wy)],
            [2 * (xy + wz), 1 - 2 * (xx + zz), 2 * (yz - wx)],
            [2 * (xz - wy), 2 * (yz + wx), 1 - 2 * (xx + yy)],
        ]
    )


def normalize_quat(q_xyzw: FloatArray) -> FloatArray:
    """Unit quaternion with ``w >= 0`` (canonical member of the double cover)."""
    q = np.asarray(q_xyzw, dtype=float)
    q = q / length(q)
    return -q if q[3] < 0 else q


def quat_multiply(a_xyzw: FloatArray, b_xyzw: FloatArray) -> FloatArray:
    """Hamilton product ``a * b`` (rotation b, then a)."""
    ax, ay, az, aw = a_xyzw
    bx, by, bz, bw = b_xyzw
    return np.array(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ]
    )


def quat_from_axis_angle(axis: FloatArray, angle: float) -> FloatArray:
    """Quaternion XYZW of a rotation of ``angle`` rad about ``axis: (3,)``."""
    a = np.asarray(axis, dtype=float)
    a = a / length(a)
    s = math.sin(0.5 * angle)
    return np.array([a[0] * s, a[1] * s, a[2] * s, math.cos(0.5 * angle)])


def quat_angle(a_xyzw: FloatArray, b_xyzw: FloatArray) -> float:
    """Rotation angle (rad, in [0, pi]) between two orientations, double cover aware."""
    a, b = np.asarray(a_xyzw, dtype=float), np.asarray(b_xyzw, dtype=float)
    d = abs(float(np.dot(a, b)))
    d /= length(a) * length(b)
    return 2.0 * math.acos(min(1.0, d))


def slerp(a_xyzw: FloatArray, b_xyzw: FloatArray, s: float) -> FloatArray:
    """Spherical interpolation from ``a`` (s=0) to ``b`` (s=1) along the short arc."""
    a = np.asarray(a_xyzw, dtype=float)
    b = np.asarray(b_xyzw, dtype=float)
    d = float(np.dot(a, b))
    if d < 0.0:
        b, d = -b, -d
    if d > 0.9995:
        out = a + s * (b - a)
        return out / length(out)
    theta = math.acos(d)
    sin_t = math.sin(theta)
    return (math.sin((1 - s) * theta) * a + math.sin(s * theta) * b) / sin_t


def interpolate_pose(a_xyzquat: FloatArray, b_xyzquat: FloatArray, s: float) -> FloatArray:
    """Straight line in position, slerp in orientation (the paper's transfer motion)."""
    out = np.empty(7)
    out[:3] = (1 - s) * a_xyzquat[:3] + s * b_xyzquat[:3]
    q = slerp(a_xyzquat[3:], b_xyzquat[3:], s)
    out[3:] = q / length(q)
    return out


def random_quaternion(rng: np.random.Generator) -> FloatArray:
    """Uniformly distributed unit quaternion XYZW (Shoemake's method)."""
    u1, u2, u3 = rng.random(3)
    r1, r2 = math.sqrt(1 - u1), math.sqrt(u1)
    t1, t2 = 2 * math.pi * u2, 2 * math.pi * u3
    return np.array([r1 * math.sin(t1), r1 * math.cos(t1), r2 * math.sin(t2), r2 * math.cos(t2)])


def transform_points(pose_xyzquat: FloatArray, p_local: FloatArray) -> FloatArray:
    """World coordinates of ``p_local: (N, 3)`` given in the frame at ``pose_xyzquat``."""
    R = quat_to_matrix(pose_xyzquat[3:7] / length(pose_xyzquat[3:7]))
    return np.asarray(p_local) @ R.T + pose_xyzquat[:3]


def inverse_transform_points(pose_xyzquat: FloatArray, p_world: FloatArray) -> FloatArray:
    """Coordinates in the frame at ``pose_xyzquat`` of world points ``p_world: (N, 3)``."""
    R = quat_to_matrix(pose_xyzquat[3:7] / length(pose_xyzquat[3:7]))
    return (np.asarray(p_world) - pose_xyzquat[:3]) @ R
