"""The time law of a plan's segments: limits, per-segment profiles, states at any time.

:class:`TimingLimits` bounds the time parameterisation; :class:`SegmentTiming`
is one segment's time law (the path velocity on a grid of the path parameter,
constant path acceleration between grid points) and gives the states at any
time (:meth:`SegmentTiming.sample`, a :class:`TrajectorySample`);
:class:`PlanTiming` plays the segments one after the other. The laws are
computed by :mod:`dexplan.execution.timing` (toppra).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from dexplan.core.errors import DexplanError, InvalidInputError
from dexplan.core.segments import SegmentKind
from dexplan.core.typing import FloatArray

__all__ = [
    "DEFAULT_JOINT_VELOCITY",
    "PlanTiming",
    "SegmentTiming",
    "TimingError",
    "TimingLimits",
    "TrajectorySample",
    "joint_velocity_limits",
]

#: Joint velocity limit (rad/s) for a URDF joint without (or with a zero) ``velocity``.
DEFAULT_JOINT_VELOCITY = 1.0


class TimingError(DexplanError):
    """A segment cannot be time-parameterised (toppra found no feasible profile)."""


@dataclass(frozen=True)
class TimingLimits:
    """Limits of the time parameterisation (all > 0).

    Attributes:
        max_acceleration: joint acceleration limit (rad/s^2), every joint.
        object_speed: object speed limit (m/s), quasi-static (default 2 cm/s).
        object_angular_speed: object angular speed limit (rad/s) (default 0.5).
        object_acceleration: object linear acceleration limit (m/s^2).
        object_angular_acceleration: object angular acceleration limit (rad/s^2).
        approach_scale: factor on the joint velocity limits near a regrasp's
            lift-off and landing, in (0, 1].
        approach_steps: planner steps at each end of a regrasp that are slowed.
        grid_per_step: toppra grid points per planner step.
        joint_velocity: per-joint velocity limits (rad/s) overriding the URDF's,
            or None (the URDF's).
    """

    max_acceleration: float = 5.0
    object_speed: float = 0.02
    object_angular_speed: float = 0.5
    object_acceleration: float = 0.1
    object_angular_acceleration: float = 1.0
    approach_scale: float = 0.25
    approach_steps: int = 2
    grid_per_step: int = 4
    joint_velocity: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        for name in (
            "max_acceleration",
            "object_speed",
            "object_angular_speed",
            "object_acceleration",
            "object_angular_acceleration",
            "approach_scale",
        ):
            v = getattr(self, name)
            if (
                isinstance(v, bool)
                or not isinstance(v, int | float)
                or not (math.isfinite(v) and v > 0)
            ):
                raise InvalidInputError(f"{name} must be a finite number > 0, got {v!r}")
            if v > 1e6:
                raise InvalidInputError(f"{name} must be at most 1e6, got {v!r}")
        if self.approach_scale > 1.0:
            raise InvalidInputError(f"approach_scale must be in (0, 1], got {self.approach_scale}")
        if not 0 <= self.approach_steps <= 1000:
            raise InvalidInputError(
                f"approach_steps must be in [0, 1000], got {self.approach_steps}"
            )
        if not 1 <= self.grid_per_step <= 100:
            raise InvalidInputError(f"grid_per_step must be in [1, 100], got {self.grid_per_step}")

    def as_dict(self) -> dict[str, Any]:
        """JSON form (the ``limits`` table of a trajectory document, without joints)."""
        return {
            "max_acceleration": self.max_acceleration,
            "object_speed": self.object_speed,
            "object_angular_speed": self.object_angular_speed,
            "object_acceleration": self.object_acceleration,
            "object_angular_acceleration": self.object_angular_acceleration,
            "approach_scale": self.approach_scale,
            "approach_steps": self.approach_steps,
        }


@dataclass(frozen=True)
class TrajectorySample:
    """States of a segment at given times (``m`` samples).

    Attributes:
        t: (m,) time from the segment's start (s).
        s: (m,) path parameter.
        q, qd, qdd: (m, nq) joint positions (rad), velocities (rad/s) and
            accelerations (rad/s^2), in ``hand.joint_names`` order.
        object_pose: (m, 7) object pose ``[x, y, z, qx, qy, qz, qw]``, world frame.
        object_velocity: (m, 6) object twist ``[v, w]``: linear velocity of the
            object-frame origin and angular velocity, both in the world frame.
        object_acceleration: (m, 6) ``[dv/dt, d2c/dt2]``: the linear acceleration
            (world frame) and the rotation coordinate's second derivative
            (object frame; its norm is the angular acceleration's to first order).
        step: (m,) index of the waypoint (of the segment, duplicates included)
            that starts the step each sample lies in.
    """

    t: FloatArray
    s: FloatArray
    q: FloatArray
    qd: FloatArray
    qdd: FloatArray
    object_pose: FloatArray
    object_velocity: FloatArray
    object_acceleration: FloatArray
    step: np.ndarray


@dataclass(frozen=True)
class SegmentTiming:
    """The time law of one segment.

    Attributes:
        kind: ``"transfer"`` or ``"regrasp"``.
        finger: the regrasp's free finger, or None.
        duration: seconds (0 for a segment that does not move).
        waypoint_s: (K,) path parameter of each waypoint (duplicates repeat).
        waypoint_times: (K,) time of each waypoint from the segment's start (s).
        gridpoints: (N,) toppra's grid over ``s``.
        sd: (N,) path velocity ``ds/dt`` at the grid points (0 at both ends).
        times: (N,) time of each grid point (s).
        poses: (K, 7) the waypoints' object poses (world frame), for the orientation.
        knots_c: (K, 3) the rotation coordinate at each waypoint (rad).
        nq: number of joints.
        rest_q: (nq,) the first waypoint's joints (the state of a segment that
            does not move).
        x0: (nq + 6,) path coordinates ``(q, p, c)`` at the start.
        moving: indices of the coordinates of ``x0`` that move (toppra's path).
    """

    kind: SegmentKind
    finger: int | None
    duration: float
    waypoint_s: FloatArray
    waypoint_times: FloatArray
    gridpoints: FloatArray
    sd: FloatArray
    times: FloatArray
    poses: FloatArray
    knots_c: FloatArray
    nq: int
    rest_q: FloatArray
    x0: FloatArray | None = None
    moving: np.ndarray | None = None
    _path: Callable[..., FloatArray] | None = field(repr=False, compare=False, default=None)

    def sample(self, times: Sequence[float] | FloatArray) -> TrajectorySample:
        """States at ``times`` (s from the segment's start, clipped to [0, duration])."""
        t = np.clip(np.asarray(times, dtype=float).reshape(-1), 0.0, self.duration)
        m, nq = t.size, self.nq
        if self._path is None or self.x0 is None or self.moving is None:  # at rest
            pose = np.repeat(self.poses[:1], m, axis=0)
            q0 = np.repeat(self.rest_q[None, :], m, axis=0)
            z = np.zeros((m, nq))
            return TrajectorySample(
                t,
                np.zeros(m),
                q0,
                z,
                z.copy(),
                pose,
                np.zeros((m, 6)),
                np.zeros((m, 6)),
                np.zeros(m, dtype=int),
            )
        s, sd, sdd = self._profile(t)
        x = np.repeat(self.x0[None, :], m, axis=0)
        x1 = np.zeros_like(x)
        x2 = np.zeros_like(x)
        mv = self.moving
        x[:, mv] = self._path(s).reshape(m, -1)
        x1[:, mv] = self._path(s, 1).reshape(m, -1)
        x2[:, mv] = self._path(s, 2).reshape(m, -1)
        xd = x1 * sd[:, None]
        xdd = x2 * (sd**2)[:, None] + x1 * sdd[:, None]
        # waypoint step of each sample (the last of equal s values)
        k = np.clip(np.searchsorted(self.waypoint_s, s, side="right") - 1, 0, len(self.poses) - 1)
        k = np.minimum(k, len(self.poses) - 1)
        pose = np.empty((m, 7))
        vel = np.empty((m, 6))
        for i in range(m):
            R = pin.Quaternion(*self.poses[k[i], [6, 3, 4, 5]]).toRotationMatrix()
            R = R @ pin.exp3(x[i, nq + 3 : nq + 6] - self.knots_c[k[i]])
            qt = pin.Quaternion(R)
            qt.normalize()
            pose[i, :3] = x[i, nq : nq + 3]
            pose[i, 3:] = (qt.x, qt.y, qt.z, qt.w)
            if pose[i, 6] * self.poses[k[i], 6] + pose[i, 3:6] @ self.poses[k[i], 3:6] < 0:
                pose[i, 3:] *= -1.0  # the waypoints' hemisphere
            vel[i, :3] = xd[i, nq : nq + 3]
            vel[i, 3:] = R @ xd[i, nq + 3 : nq + 6]
        return TrajectorySample(
            t, s, x[:, :nq], xd[:, :nq], xdd[:, :nq], pose, vel, xdd[:, nq:], k.astype(int)
        )

    def _profile(self, t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(s, sdot, sddot) at times ``t``: constant ``sddot`` per grid interval."""
        ts, ss, sd = self.times, self.gridpoints, self.sd
        idx = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(ts) - 2)
        ds = ss[idx + 1] - ss[idx]
        u = 0.5 * (sd[idx + 1] ** 2 - sd[idx] ** 2) / ds
        dt = t - ts[idx]
        v = np.maximum(sd[idx] + u * dt, 0.0)
        s = np.clip(ss[idx] + sd[idx] * dt + 0.5 * u * dt * dt, ss[idx], ss[idx + 1])
        return s, v, u


@dataclass(frozen=True)
class PlanTiming:
    """Time laws of every segment of a plan, played one after the other.

    Attributes:
        segments: one :class:`SegmentTiming` per plan segment.
        start_times: (S,) start time of each segment (s from the plan's start).
        joint_velocity: (nq,) joint velocity limits used (rad/s).
        limits: the :class:`TimingLimits`.
    """

    segments: tuple[SegmentTiming, ...]
    start_times: FloatArray
    joint_velocity: FloatArray
    limits: TimingLimits

    @property
    def duration(self) -> float:
        """Total execution time (s)."""
        if not self.segments:
            return 0.0
        return float(self.start_times[-1] + self.segments[-1].duration)


def joint_velocity_limits(model: pin.Model) -> FloatArray:
    """URDF joint velocity limits (rad/s), :data:`DEFAULT_JOINT_VELOCITY` where missing.

    Args:
        model: the hand's Pinocchio model (``model.velocityLimit``, (nv,)).

    Returns:
        (nv,) limits > 0, in the model's joint order (``hand.joint_names``).
    """
    v = np.array(model.velocityLimit, dtype=float).reshape(-1)
    bad = ~np.isfinite(v) | (v <= 0.0)
    v[bad] = DEFAULT_JOINT_VELOCITY
    return v
