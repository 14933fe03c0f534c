"""Velocities of points on fingertips, and the damped joint steps that produce them.

A fingertip's material point at a contact moves with its link: its Jacobian
comes from the tip frame's (:func:`point_jacobian`), and a finger's joint
step that moves it by a given displacement is the damped least-norm
solution of three equations (:func:`damped_step`). The rolling of several
fingers (:mod:`dexplan.model.grasp.rolling`) stacks them: each stacked
product and solve below gives each finger exactly what its own would.

Frames: world quantities are the hand's base frame; a Jacobian ``J6`` is
``LOCAL_WORLD_ALIGNED`` (linear velocity of the frame's origin, then angular
velocity, world axes).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from dexplan.core.typing import FloatArray

__all__ = ["damped_step", "damped_steps", "point_jacobian", "point_jacobians", "rotate_rows"]


def point_jacobian(J6: FloatArray, p_world: FloatArray, c_world: FloatArray) -> FloatArray:
    """Jacobian ``(3, m)`` of a point fixed on a link, from the link frame's.

    Args:
        J6: (6, m) the frame's Jacobian, ``LOCAL_WORLD_ALIGNED`` (linear
            velocity of its origin, then angular velocity, world axes).
        p_world: (3,) the point, world frame.
        c_world: (3,) the frame's origin, world frame.

    Returns:
        ``J_p = J_v - [p - c]x J_w``: ``v_p = v_c + w x (p - c)``.
    """
    return J6[:3] - pin.skew(p_world - c_world) @ J6[3:]


def damped_step(J: FloatArray, rhs: FloatArray, damping: float) -> FloatArray:
    """Least-norm (damped) solution of ``J x = rhs`` for any shape of ``J``."""
    if J.shape[0] <= J.shape[1]:
        A = J @ J.T
        A.flat[:: A.shape[0] + 1] += damping
        return np.asarray(J.T @ np.linalg.solve(A, rhs), dtype=np.float64)
    A = J.T @ J
    A.flat[:: A.shape[0] + 1] += damping
    return np.asarray(np.linalg.solve(A, J.T @ rhs), dtype=np.float64)


def damped_steps(J: FloatArray, rhs: FloatArray, damping: float) -> FloatArray:
    """:func:`damped_step` of each ``(J[i], rhs[i])``: ``(F, m)``.

    ``J: (F, 3, m)`` the fingers' point Jacobians, ``rhs: (F, 3)`` their
    points' displacements.

    Fingers of 3 joints or more solve 3 x 3 systems: all in one batched
    call (each exactly as alone); fingers of fewer one by one.
    """
    J = np.ascontiguousarray(J)
    if J.shape[2] < 3:
        return np.array([damped_step(J[i], rhs[i], damping) for i in range(len(J))])
    JT = J.transpose(0, 2, 1)
    A = J @ JT
    A[:, [0, 1, 2], [0, 1, 2]] += damping
    y = np.linalg.solve(A, np.ascontiguousarray(rhs)[:, :, None])
    return np.asarray((JT @ y)[:, :, 0], dtype=np.float64)


def rotate_rows(R: FloatArray, v: FloatArray) -> FloatArray:
    """``R @ v[i]`` of each row of ``v: (F, k)``, ``R: (n, k)`` or ``(F, n, k)``: ``(F, n)``.

    One stacked product; each row's is exactly ``R @ v[i]`` alone.
    """
    return np.ascontiguousarray(np.matmul(R, v[:, :, None])[:, :, 0])


def point_jacobians(J6: FloatArray, p_world: FloatArray, c_world: FloatArray) -> FloatArray:
    """Each finger's :func:`point_jacobian`: ``(F, 3, m)``.

    ``J6: (F, 6, m)`` the tip frames' Jacobians, ``p_world, c_world: (F, 3)``.
    """
    r = p_world - c_world
    S = np.zeros((len(r), 3, 3))  # pin.skew of each row
    S[:, 0, 1], S[:, 0, 2] = -r[:, 2], r[:, 1]
    S[:, 1, 0], S[:, 1, 2] = r[:, 2], -r[:, 0]
    S[:, 2, 0], S[:, 2, 1] = -r[:, 1], r[:, 0]
    return np.asarray(J6[:, :3] - S @ J6[:, 3:], dtype=np.float64)
