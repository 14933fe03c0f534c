"""Time parameterisation of a plan: time-optimal, quasi-static, at rest at every segment end.

A plan (``dexplan-plan/2``) is geometric: waypoints without time. Each segment
is parameterised on its own with toppra (time-optimal path parameterisation by
reachability analysis, Pham & Pham 2018); nothing of the optimisation is
written here.

Path of a segment
-----------------
The path coordinates are ``x = (q, p, c)``: the ``nq`` joint values, the
object position ``p`` (world frame, m) and a rotation coordinate ``c`` (rad):
the cumulative sum of the body-frame rotation vectors between consecutive
waypoints, ``c_{k+1} = c_k + log(R_k^T R_{k+1})``, so that ``|dc/dt|`` is the
object's angular speed on each waypoint step (the planner interpolates a
step along one geodesic). The waypoints (consecutive duplicates dropped) are
joined by a cubic spline (``bc_type="not-a-knot"``: zero end slopes would
leave the acceleration at a resting end unconstrained) over a path parameter
``s`` that grows by ``max(|dq|_inf / 0.05, |dp| / 0.01, |dtheta| / 0.05)``
per step (one planner step is about one unit of ``s``).
The object orientation at ``s`` in step ``k`` is ``R_k exp(c(s) - c_k)``.

Constraints
-----------
- joint velocity: ``|dq_j/dt| <= v_j``, ``v_j`` the URDF ``velocity`` limit
  (Pinocchio ``model.velocityLimit``); a missing or zero limit gets
  :data:`~dexplan.execution.segment_timing.DEFAULT_JOINT_VELOCITY`;
- joint acceleration: ``|d2q_j/dt2| <= a`` (:attr:`TimingLimits.max_acceleration`);
- object (quasi-static): speed ``|dp/dt| <= v_o`` and angular speed
  ``|dc/dt| <= w_o`` (Euclidean norms, defaults 2 cm/s and 0.5 rad/s, enforced
  exactly by a custom toppra constraint on ``sdot^2``), and accelerations
  (per component ``<= a_o / sqrt(3)``, so that the norm is ``<= a_o``);
- regrasp lift-off and landing: over the first and last
  :attr:`TimingLimits.approach_steps` steps of a regrasp, every joint
  velocity limit is scaled by :attr:`TimingLimits.approach_scale`;
- rest: ``sdot = 0`` at both ends of every segment.

toppra enforces the constraints at its grid points (``grid_per_step`` per
step, ``Collocation`` discretisation: with toppra 0.6's seidel solver the
``Interpolation`` scheme reports feasible regrasps uncontrollable). The limits
handed to it are first scaled by :data:`SAFETY`; the profile is then sampled
:data:`DENSE` times per grid interval and, where a velocity or acceleration still exceeds
its limit (collocation can chatter where the path's curvature limits the
speed), that kind of limit is tightened by the excess and toppra solves again
(at most :data:`MAX_TIGHTENING` times). :func:`dexplan.execution.check.check_trajectory`
checks the exported samples against the full limits.

The time law between grid points is toppra's own constant-acceleration
interpretation (``toppra.parametrizer.ParametrizeConstAccel``): ``sddot``
constant on each grid interval. The time laws and their states are
:mod:`dexplan.execution.segment_timing`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import pinocchio as pin
from toppra import SplineInterpolator
from toppra.algorithm import TOPPRA
from toppra.algorithm.algorithm import ParameterizationReturnCode
from toppra.constraint import DiscretizationType, JointAccelerationConstraint, LinearConstraint

from dexplan.core.errors import InvalidInputError
from dexplan.core.segments import SegmentKind
from dexplan.core.typing import FloatArray, IntArray
from dexplan.execution.segment_timing import (
    PlanTiming,
    SegmentTiming,
    TimingError,
    TimingLimits,
    joint_velocity_limits,
)
from dexplan.model.hand.hand import Hand
from dexplan.planfile import hand_from_plan

__all__ = [
    "DEFAULT_LIMITS",
    "SAFETY",
    "time_plan",
    "time_segment",
]

#: Fraction of every limit handed to toppra (the samples between its grid points
#: then stay within the full limits).
SAFETY = 0.95
_STEP_M = 0.01  # normalisation of a step: the verifier's step bounds (m, rad)
_STEP_RAD = 0.05
_DUPLICATE = 1e-12  # steps of fewer path units are dropped
#: A path coordinate whose range is below this (rad or m) does not move.
_STILL = 1e-9
#: Times a segment is solved again with tightened limits when toppra's profile
#: exceeds a limit between its grid points.
MAX_TIGHTENING = 8
#: Samples per toppra grid interval at which the limits are checked.
DENSE = 16
#: An interior path velocity whose square is below this fraction of the largest
#: controllable one is a stalled forward pass (:func:`_stalled`), solved again
#: backward, then on grids of STALL_GRIDS more points.
STALL_FRACTION = 1e-6
STALL_GRIDS = (1, 2, 3, 5, 8)
#: The limits when none are given (module docstring).
DEFAULT_LIMITS = TimingLimits()


def _rotation(qxyzw: FloatArray) -> FloatArray:
    return pin.Quaternion(qxyzw[3], qxyzw[0], qxyzw[1], qxyzw[2]).normalized().toRotationMatrix()


class _QuasiStaticVelocity(LinearConstraint):
    """toppra constraint ``sdot^2 <= bound(s)``: joint boxes and object speed norms.

    Args:
        vj: joint velocity limits (rad/s) of the joints that move.
        vo: object speed limit (m/s).
        wo: object angular speed limit (rad/s).
        kinds: each path coordinate's role: 0 joint, 1 object position, 2 object rotation.
        slow: factor on the joint limits along the path parameter (:func:`_approach_slowdown`).
    """

    def __init__(
        self,
        vj: FloatArray,
        vo: float,
        wo: float,
        kinds: FloatArray,
        slow: Callable[[FloatArray], FloatArray],
    ) -> None:
        super().__init__()
        self.vj, self.vo, self.wo, self.kinds, self.slow = vj, vo, wo, kinds, slow

    def compute_constraint_params(
        self, path: Any, gridpoints: FloatArray, *args: Any, **kwargs: Any
    ) -> tuple[None, None, None, None, None, None, FloatArray]:
        """Toppra's constraint parameters: only ``xbound``, ``[0, bound(s)]`` on ``sdot^2``."""
        x1 = path(gridpoints, 1).reshape(len(gridpoints), -1)
        ub = np.full(len(gridpoints), 1e6)
        j, p, c = (self.kinds == 0), (self.kinds == 1), (self.kinds == 2)
        tiny = 1e-300
        if j.any():
            vj = self.vj[None, :] * self.slow(gridpoints)[:, None]
            ub = np.minimum(ub, np.min(vj / np.maximum(np.abs(x1[:, j]), tiny), axis=1))
        if p.any():
            ub = np.minimum(ub, self.vo / np.maximum(np.linalg.norm(x1[:, p], axis=1), tiny))
        if c.any():
            ub = np.minimum(ub, self.wo / np.maximum(np.linalg.norm(x1[:, c], axis=1), tiny))
        xbound = np.stack([np.zeros_like(ub), ub**2], axis=1)
        return None, None, None, None, None, None, xbound


def time_segment(
    kind: SegmentKind,
    finger: int | None,
    q: FloatArray,
    poses: FloatArray,
    joint_velocity: FloatArray,
    limits: TimingLimits = DEFAULT_LIMITS,
    *,
    name: str = "segment",
) -> SegmentTiming:
    """Time-optimal parameterisation of one segment, at rest at both ends.

    Args:
        kind: ``"transfer"`` or ``"regrasp"``.
        finger: the regrasp's free finger (None for a transfer).
        q: (K, nq) joint values of the waypoints (rad).
        poses: (K, 7) object poses of the waypoints, world frame, XYZW.
        joint_velocity: (nq,) joint velocity limits (rad/s), > 0.
        limits: the other limits.
        name: the segment in error messages (``segment 3``).

    Raises:
        TimingError: toppra finds no feasible parameterisation.
    """
    q = np.asarray(q, dtype=float)
    poses = np.asarray(poses, dtype=float)
    K, nq = q.shape
    c, steps = _rotation_and_steps(q, poses)
    ws = np.cumsum(steps)
    keep = np.concatenate([[True], steps[1:] > 0.0])
    xs, ss, moving, kinds, path, backward = _toppra_path(q, poses, c, ws, keep)
    if keep.sum() < 2 or path is None:  # nothing moves: a point at rest
        return SegmentTiming(
            kind, finger, 0.0, ws, np.zeros(K), np.zeros(1), np.zeros(1), np.zeros(1),
            poses, c, nq, q[0].copy(), None, None, None,
        )  # fmt: skip
    n_grid = max(2, round(ss[-1] * limits.grid_per_step) + 1)
    grid = np.linspace(0.0, ss[-1], n_grid)
    slow = _approach_slowdown(kind, limits, float(ss[-1]))
    alim = _acceleration_limits(nq, limits)[moving]
    vj = np.asarray(joint_velocity, dtype=float)
    fv = fa = SAFETY
    for _ in range(MAX_TIGHTENING):
        vel = _QuasiStaticVelocity(
            fv * vj[moving[kinds == 0]],
            fv * limits.object_speed,
            fv * limits.object_angular_speed,
            kinds,
            slow,
        )
        acc = JointAccelerationConstraint(
            fa * np.stack([-alim, alim], axis=1),
            discretization_scheme=DiscretizationType.Collocation,
        )
        grid, sd, times = _solve([vel, acc], (path, backward), grid, name)
        seg = SegmentTiming(
            kind, finger, float(times[-1]), ws, _times_at(ws, grid, sd, times), grid, sd, times,
            poses, c, nq, q[0].copy(), xs[0].copy(), moving, path,
        )  # fmt: skip
        rv, ra = _dense_ratios(seg, vj, limits)
        if rv <= 1.0 and ra <= 1.0:
            return seg
        # collocation enforces the limits at the grid points only; tighten the
        # violated kind by the measured excess and solve again
        fv *= min(1.0, 0.97 / rv)
        fa *= min(1.0, 0.97 / ra)
    raise TimingError(
        f"{name}: toppra's profile exceeds the limits between its grid points "
        f"(velocity x{rv:.3f}, acceleration x{ra:.3f}) after {MAX_TIGHTENING} tightenings"
    )


def _toppra_path(
    q: FloatArray, poses: FloatArray, c: FloatArray, ws: FloatArray, keep: np.ndarray
) -> tuple[FloatArray, FloatArray, IntArray, FloatArray, Any, Any]:
    """The spline toppra parameterises, through the waypoints that move.

    Args:
        q: (K, nq) joint values (rad).
        poses: (K, 7) object poses, world frame, XYZW.
        c: (K, 3) rotation coordinate of each waypoint.
        ws: (K,) path coordinate of each waypoint.
        keep: (K,) the waypoints kept (a step of zero length is dropped).

    Returns:
        ``(xs, ss, moving, kinds, path)``: (K', nq + 6) kept waypoint coordinates
        ``[q, position, rotation]``, (K',) their path coordinates, the indices of
        the coordinates that move, their kinds (0 joint, 1 position, 2 rotation),
        the ``toppra.SplineInterpolator`` through them (None when nothing moves)
        and the same path backward (``s -> s_end - s``).
    """
    nq = q.shape[1]
    xs = np.concatenate([q, poses[:, :3], c], axis=1)[keep]
    ss = ws[keep]
    # only the coordinates that move are toppra's path (constant rows would be
    # all-zero constraint rows, on which its seidel solver reports a feasible
    # instance uncontrollable). A coordinate that moves by round-off only (a
    # regrasp's object rotation coordinate wobbles by 1e-16 rad) counts as
    # constant too: its rows are all but zero, and on one Allegro regrasp
    # seidel then left the path velocity 2e-4 before the end, which timed the
    # last grid interval at 2726 s.
    moving = np.flatnonzero(np.ptp(xs, axis=0) > _STILL)
    kinds = np.concatenate([np.zeros(nq), np.ones(3), np.full(3, 2.0)])[moving]
    if moving.size == 0 or ss.size < 2:
        return xs, ss, moving, kinds, None, None
    path = SplineInterpolator(ss, xs[:, moving], bc_type="not-a-knot")
    # a cubic spline through the reversed knots is the same curve run backward
    backward = SplineInterpolator(ss[-1] - ss[::-1], xs[::-1][:, moving], bc_type="not-a-knot")
    return xs, ss, moving, kinds, path, backward


def _rotation_and_steps(q: FloatArray, poses: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The rotation coordinate at each waypoint and the path length of each step.

    Args:
        q: (K, nq) joint values of the waypoints (rad).
        poses: (K, 7) object poses of the waypoints, world frame, XYZW.

    Returns:
        ``(c, steps)``: (K, 3) the summed body-frame rotation vectors (rad) and
        (K,) each waypoint's step from the previous one in path units
        (``steps[0] = 0``; steps shorter than the duplicate threshold are 0).
    """
    K, nq = q.shape
    c = np.zeros((K, 3))
    steps = np.zeros(K)
    Rs = [_rotation(p[3:]) for p in poses]
    for k in range(1, K):
        w = pin.log3(Rs[k - 1].T @ Rs[k])
        c[k] = c[k - 1] + w
        dq = float(np.max(np.abs(q[k] - q[k - 1]))) if nq else 0.0
        dp = float(np.linalg.norm(poses[k, :3] - poses[k - 1, :3]))
        steps[k] = max(dq / _STEP_RAD, dp / _STEP_M, float(np.linalg.norm(w)) / _STEP_RAD)
    steps[steps < _DUPLICATE] = 0.0
    return c, steps


def _approach_slowdown(
    kind: SegmentKind, limits: TimingLimits, total: float
) -> Callable[[FloatArray], FloatArray]:
    """Factor on the joint velocity limits along ``s``: slower near a regrasp's ends.

    Args:
        kind: ``"transfer"`` or ``"regrasp"`` (a transfer is never slowed).
        limits: ``approach_steps`` and ``approach_scale``.
        total: the path length of the segment.
    """
    approach = float(limits.approach_steps)

    def slow(sv: FloatArray) -> FloatArray:
        out = np.ones_like(sv)
        if kind == "regrasp" and approach > 0:
            near = (sv <= approach) | (sv >= total - approach)
            out[near] = limits.approach_scale
        return out

    return slow


def _acceleration_limits(nq: int, limits: TimingLimits) -> FloatArray:
    """(nq + 6,) acceleration bounds of the path coordinates ``(q, p, c)``.

    The object's are per component, ``limit / sqrt(3)``, so that the norm stays
    within the limit.
    """
    return np.concatenate(
        [
            np.full(nq, limits.max_acceleration),
            np.full(3, limits.object_acceleration / math.sqrt(3.0)),
            np.full(3, limits.object_angular_acceleration / math.sqrt(3.0)),
        ]
    )


def _solve(
    constraints: list[Any], paths: tuple[Any, Any], grid: FloatArray, name: str
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Path velocities of toppra on ``grid``, at rest at both ends; (grid, sd, times).

    ``paths`` is the path and the same path backward. Where toppra's forward
    pass stalls (:func:`_stalled`) the backward path is solved (every limit is
    symmetric: its profile run backward is a valid forward one), then both on
    grids of :data:`STALL_GRIDS` more points, until one does not stall; the
    fastest profile found is kept (each is feasible; a stall only wastes time).
    """
    best: tuple[FloatArray, FloatArray, FloatArray] | None = None
    for extra in (0, *STALL_GRIDS):
        g = grid if extra == 0 else np.linspace(grid[0], grid[-1], grid.size + extra)
        for back in (False, True):
            sd, stalled = _toppra_velocities(constraints, paths[back], g, name, back)
            found = _profile_times(g, sd, name)
            if best is None or found[2][-1] < best[2][-1]:
                best = found
            if not stalled:
                return best
    assert best is not None
    return best


def _toppra_velocities(
    constraints: list[Any], path: Any, grid: FloatArray, name: str, backward: bool
) -> tuple[FloatArray, bool]:
    """The path velocities toppra finds on ``grid`` (forward order) and whether its pass stalled."""
    instance = TOPPRA(constraints, path, gridpoints=grid, solver_wrapper="seidel")
    try:
        instance.compute_parameterization(0.0, 0.0)
    except Exception as exc:  # toppra's own errors
        raise TimingError(f"{name}: toppra failed: {exc}") from exc
    data = instance.problem_data
    if data.return_code != ParameterizationReturnCode.Ok or data.sd_vec is None:
        raise TimingError(f"{name}: no feasible time parameterisation (toppra: {data.return_code})")
    sd = np.asarray(data.sd_vec, dtype=float)
    K = np.asarray(data.K, dtype=float)
    if sd.shape != grid.shape or not np.all(np.isfinite(sd)):
        raise TimingError(f"{name}: toppra returned a non-finite velocity profile")
    if backward:  # the backward profile on the mirrored uniform grid, in forward order
        sd, K = sd[::-1].copy(), K[::-1]
    return sd, _stalled(sd, K)


def _profile_times(
    grid: FloatArray, sd: FloatArray, name: str
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(grid, sd, times) of a profile at rest at both ends (constant acceleration per interval)."""
    grid = np.asarray(grid, dtype=float)
    sd = np.maximum(sd, 0.0)
    sd[0] = sd[-1] = 0.0
    vsum = sd[:-1] + sd[1:]
    if np.any(vsum <= 0.0):
        raise TimingError(f"{name}: the path velocity vanishes inside the segment (toppra)")
    times = np.concatenate([[0.0], np.cumsum(2.0 * np.diff(grid) / vsum)])
    return grid, sd, times


def _stalled(sd: FloatArray, K: FloatArray) -> bool:
    """Whether toppra's forward pass all but stopped at an interior grid point.

    Its seidel solver now and then (one Allegro regrasp of 44 grid points)
    picks a next velocity of nearly zero where the controllable set allows a
    thousand times more: never time-optimal, and next to the final rest it
    timed the last grid interval at 2726 s (``2 ds / (sd_a + sd_b)`` with both
    near zero). The same path solved backward does not meet the degenerate step.

    Args:
        sd: (N,) the path velocities toppra chose.
        K: (N, 2) its controllable sets of squared path velocities.
    """
    inner = slice(1, sd.size - 1)
    return bool(np.any(sd[inner] ** 2 < STALL_FRACTION * K[inner, 1]))


def _dense_ratios(seg: SegmentTiming, vj: FloatArray, limits: TimingLimits) -> tuple[float, float]:
    """Largest velocity and acceleration over their limits, :data:`DENSE` per grid interval."""
    f = np.append(np.linspace(0.0, 1.0, DENSE + 1)[:-1], 1.0 - 1e-9)  # and each end's left limit
    ts = (seg.times[:-1, None] + f[None, :] * np.diff(seg.times)[:, None]).ravel()
    smp = seg.sample(np.concatenate([ts, seg.times[-1:]]))
    ov, oa = smp.object_velocity, smp.object_acceleration
    rv = max(
        float(np.max(np.abs(smp.qd) / vj[None, :])) if seg.nq else 0.0,
        float(np.max(np.linalg.norm(ov[:, :3], axis=1))) / limits.object_speed,
        float(np.max(np.linalg.norm(ov[:, 3:], axis=1))) / limits.object_angular_speed,
    )
    ra = max(
        float(np.max(np.abs(smp.qdd))) / limits.max_acceleration if seg.nq else 0.0,
        float(np.max(np.linalg.norm(oa[:, :3], axis=1))) / limits.object_acceleration,
        float(np.max(np.linalg.norm(oa[:, 3:], axis=1))) / limits.object_angular_acceleration,
    )
    return rv, ra


def _times_at(sv: FloatArray, grid: FloatArray, sd: FloatArray, times: FloatArray) -> FloatArray:
    """Times at path parameters ``sv`` under the constant-acceleration law."""
    idx = np.clip(np.searchsorted(grid, sv, side="right") - 1, 0, len(grid) - 2)
    ds = grid[idx + 1] - grid[idx]
    u = 0.5 * (sd[idx + 1] ** 2 - sd[idx] ** 2) / ds
    d = sv - grid[idx]
    v0 = sd[idx]
    # d = v0 dt + u dt^2 / 2  ->  dt = 2 d / (v0 + sqrt(v0^2 + 2 u d))
    root = np.sqrt(np.maximum(v0 * v0 + 2.0 * u * d, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        dt = np.where(d > 0.0, 2.0 * d / (v0 + root), 0.0)
    return times[idx] + dt


def time_plan(
    doc: Mapping[str, Any], limits: TimingLimits = DEFAULT_LIMITS, hand: Hand | None = None
) -> PlanTiming:
    """Time-parameterise every segment of a validated ``dexplan-plan/2`` document.

    Args:
        doc: the plan (:func:`dexplan.planfile.document.read_plan`).
        limits: the limits (defaults: module docstring).
        hand: the plan's :class:`~dexplan.model.hand.hand.Hand` (built from the file when None).

    Raises:
        TimingError: a segment cannot be parameterised.
        InvalidInputError: ``limits.joint_velocity`` has the wrong length.
        PlanFileError: the hand cannot be rebuilt from the file.
    """
    if hand is None:
        hand = hand_from_plan(doc["hand"])
    if limits.joint_velocity is None:
        vj = joint_velocity_limits(hand.model)
    else:
        vj = np.asarray(limits.joint_velocity, dtype=float)
        if vj.shape != (hand.nq,) or not np.all(np.isfinite(vj) & (vj > 0)):
            raise InvalidInputError(
                f"joint_velocity must be {hand.nq} finite numbers > 0, got {vj.tolist()}"
            )
    segs = []
    starts = []
    t0 = 0.0
    for si, s in enumerate(doc["segments"]):
        wps = s["waypoints"]
        q = np.array([w["q"] for w in wps], dtype=float).reshape(len(wps), hand.nq)
        poses = np.array([w["object_pose_xyzquat"] for w in wps], dtype=float)
        seg = time_segment(s["kind"], s["finger"], q, poses, vj, limits, name=f"segment {si}")
        segs.append(seg)
        starts.append(t0)
        t0 += seg.duration
    return PlanTiming(tuple(segs), np.array(starts), vj, limits)
