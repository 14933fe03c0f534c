"""What a physics replay found: per loop a :class:`ReplayResult`, both in a :class:`ReplayReport`.

The errors are kept in SI units (m, rad) and reported in mm and degrees. A
replay stops where the object is dropped (more than :data:`DROP_TOL` from the
plan): what the object does once it has fallen says nothing about the plan,
so the errors are those before the drop and the drop is its own record
(:class:`Drop`: when, in which segment, which finger moved, how strong the
hold was).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from dexplan.core.typing import FloatArray

__all__ = [
    "ANGLE_TOL",
    "DROP_TOL",
    "POSITION_TOL",
    "Drop",
    "Loop",
    "ReplayReport",
    "ReplayResult",
]

#: Tracking tolerances at every waypoint (m, rad).
POSITION_TOL = 0.005
ANGLE_TOL = 0.1
#: Object farther than this from the plan: dropped (m); the replay stops there.
DROP_TOL = 0.02


class Loop(StrEnum):
    """How the fingers are driven: object-pose feedback (closed) or the planned joints (open)."""

    CLOSED = "closed"
    OPEN = "open"


@dataclass(frozen=True)
class Drop:
    """Where and how a replay dropped the object.

    Attributes:
        time: when the object first was more than :data:`DROP_TOL` from the plan
            (s from the trajectory's start).
        lost_track_time: when it first left :data:`POSITION_TOL` / :data:`ANGLE_TOL`
            before that (s).
        segment: index of the plan segment the drop happened in.
        kind: that segment's kind, ``transfer`` or ``regrasp``.
        finger: the regrasp's moving finger, None in a transfer.
        planned_hold_quality: force-closure quality of the contacts the plan holds
            the object with at the drop (0: no force closure).
        measured_hold_quality: force-closure quality of the contacts the fingertips
            had in the simulation at ``measured_hold_time`` (0: no force closure).
        measured_hold_time: the last time (s) in the drop's segment, up to the track
            loss, at which every finger the plan holds the object with at the drop
            touched it in the simulation (the segment's start when there is none).
        holding_fingers: the fingers the plan holds the object with at the drop.
    """

    time: float
    lost_track_time: float
    segment: int
    kind: str
    finger: int | None
    planned_hold_quality: float
    measured_hold_quality: float
    measured_hold_time: float
    holding_fingers: tuple[int, ...]

    def describe(self, n_segments: int) -> str:
        """One line: time, segment, finger and hold qualities."""
        what = f"regrasp of finger {self.finger}" if self.kind == "regrasp" else "transfer"
        return (
            f"DROPPED at {self.time:.2f} s in segment {self.segment + 1} of {n_segments} "
            f"({what}; held by fingers {', '.join(map(str, self.holding_fingers)) or 'none'}); "
            f"lost track at {self.lost_track_time:.2f} s; hold quality "
            f"{self.planned_hold_quality:.4f} planned, {self.measured_hold_quality:.4f} at the "
            f"simulated contacts at {self.measured_hold_time:.2f} s"
        )


@dataclass(frozen=True)
class ReplayResult:
    """What one physics replay of a plan did (``m`` recorded samples).

    The samples end at the drop when the object was dropped (the replay stops
    there), else at the trajectory's end.

    Attributes:
        loop: closed (object-pose feedback) or open (the planned joints).
        gravity: whether gravity was on.
        duration: the plan's execution time (s).
        n_segments: the plan's segment count.
        t: (m,) times of the recorded samples (s from the trajectory's start).
        planned_pose: (m, 7) the plan's object pose at those times, world frame.
        sim_pose: (m, 7) the simulated object pose, world frame.
        planned_q: (m, nq) the planned (timed) joints at those times.
        sim_q: (m, nq) the simulated joints.
        position_error: (m,) |p_sim - p_plan| (m).
        angle_error: (m,) rotation angle between the two orientations (rad).
        max_position_error: max over the samples before the drop (m).
        max_angle_error: max over the samples before the drop (rad).
        waypoint_position_error: max over the waypoints reached before the drop (m).
        waypoint_angle_error: max over the waypoints reached before the drop (rad).
        waypoints_reached: how many of the plan's waypoints were reached (all
            unless dropped).
        waypoints: the plan's waypoint count.
        goal_position_error: final distance to the goal position (m); None when dropped.
        goal_angle_error: final angle to the goal orientation (rad); None when dropped.
        goal_tolerances: the plan's ``(position_tol, angle_tol)``.
        contact_losses: (finger, time) of each contact loss.
        slips: (finger, time, distance) of each slip event.
        max_contact_drift: the farthest a loaded fingertip's contact was from the
            plan's contact, on the object (m): how far the contacts migrated.
        drop: where and how the object was dropped, or None.
        max_penetration: deepest hand-object penetration (m).
        unbalanced_samples: trajectory samples where no grip forces balance
            the wrench (not force closure: no feed-forward there).
        effort_limits: (nq,) the actuators' torque limits (N m), NaN where the
            plan's URDF has none (that joint's actuator is unlimited).
        max_effort_ratio: the largest ``|actuator torque| / limit`` of any limited joint.
        saturated_time: time (s) any limited joint's actuator spent at its limit.
        handovers: hand-overs inserted where the holding fingers change
            (:mod:`dexplan.execution.replay.handover`).
        handover_time: the time they add to the plan's execution (s), in ``duration``.
    """

    loop: Loop
    gravity: bool
    duration: float
    n_segments: int
    t: FloatArray
    planned_pose: FloatArray
    sim_pose: FloatArray
    planned_q: FloatArray
    sim_q: FloatArray
    position_error: FloatArray
    angle_error: FloatArray
    max_position_error: float
    max_angle_error: float
    waypoint_position_error: float
    waypoint_angle_error: float
    waypoints_reached: int
    waypoints: int
    goal_position_error: float | None
    goal_angle_error: float | None
    goal_tolerances: tuple[float, float]
    contact_losses: tuple[tuple[int, float], ...]
    slips: tuple[tuple[int, float, float], ...]
    max_contact_drift: float
    drop: Drop | None
    max_penetration: float
    unbalanced_samples: int
    effort_limits: tuple[float, ...]
    max_effort_ratio: float
    saturated_time: float
    handovers: int = 0
    handover_time: float = 0.0

    @property
    def dropped(self) -> bool:
        """The object strayed more than :data:`DROP_TOL` from the plan."""
        return self.drop is not None

    @property
    def drop_time(self) -> float | None:
        """When it was dropped (s), or None."""
        return None if self.drop is None else self.drop.time

    @property
    def tracked(self) -> bool:
        """Every waypoint within the tolerances and no drop."""
        return (
            self.drop is None
            and self.waypoint_position_error <= POSITION_TOL
            and self.waypoint_angle_error <= ANGLE_TOL
        )

    @property
    def at_goal(self) -> bool:
        """The final pose is within the plan's goal tolerances."""
        if self.goal_position_error is None or self.goal_angle_error is None:
            return False
        return (
            self.goal_position_error <= self.goal_tolerances[0]
            and self.goal_angle_error <= self.goal_tolerances[1]
        )

    @property
    def verdict(self) -> str:
        """``TRACKED``, ``LOST TRACK`` or ``DROPPED``."""
        if self.tracked:
            return "TRACKED"
        return "DROPPED" if self.dropped else "LOST TRACK"

    def summary(self) -> str:
        """Lines for the CLI: errors (mm, degrees), events, actuators and the verdict."""
        loop = "closed loop (object-pose feedback)" if self.loop == Loop.CLOSED else "open loop"
        lines = [
            f"replay, {loop}, {'gravity' if self.gravity else 'no gravity'}: "
            f"{self.duration:.2f} s, {self.n_segments} segments"
            + (
                f" ({self.handovers} hand-overs, {self.handover_time:.1f} s of them)"
                if self.handovers
                else ""
            ),
            f"  object error{' before the drop' if self.dropped else ''}: max "
            f"{_mm(self.max_position_error)}, {_deg(self.max_angle_error)}; at waypoints "
            f"({self.waypoints_reached} of {self.waypoints} reached) max "
            f"{_mm(self.waypoint_position_error)}, {_deg(self.waypoint_angle_error)}",
        ]
        if self.goal_position_error is not None and self.goal_angle_error is not None:
            lines.append(
                f"  goal: {_mm(self.goal_position_error)}, {_deg(self.goal_angle_error)} "
                f"({'within' if self.at_goal else 'outside'} the goal tolerance)"
            )
        else:
            lines.append("  goal: not reached")
        lines.append(
            f"  contacts: {len(self.contact_losses)} losses, {len(self.slips)} slips over "
            f"3 mm, at most {_mm(self.max_contact_drift)} from the planned contacts; "
            f"max penetration {_mm(self.max_penetration)}; samples without balancing "
            f"grip forces: {self.unbalanced_samples}"
        )
        lines.append("  actuators: " + self._effort_line())
        if self.drop is not None:
            lines.append("  " + self.drop.describe(self.n_segments))
        elif self.tracked:
            lines.append(
                f"  TRACKED within {_mm(POSITION_TOL)} and {_deg(ANGLE_TOL)} at every waypoint"
            )
        else:
            lines.append(f"  LOST TRACK: beyond {_mm(POSITION_TOL)} or {_deg(ANGLE_TOL)}")
        return "\n".join(lines)

    def _effort_line(self) -> str:
        e = np.asarray(self.effort_limits, dtype=float)
        limited = np.isfinite(e)
        if not limited.any():
            return "no effort limits in the plan's URDF: unlimited torque"
        lo, hi = float(e[limited].min()), float(e[limited].max())
        span = f"{lo:.3g} N m" if math.isclose(lo, hi) else f"{lo:.3g}-{hi:.3g} N m"
        free = int((~limited).sum())
        return (
            f"torque limited to the URDF's effort limits ({span}"
            + (f"; {free} joints unlimited" if free else "")
            + f"); peak {self.max_effort_ratio:.0%} of a limit, "
            f"{self.saturated_time:.2f} s at a limit"
        )


@dataclass(frozen=True)
class ReplayReport:
    """The replays of one plan: closed loop, open loop or both, in that order.

    Attributes:
        results: one :class:`ReplayResult` per loop replayed.
    """

    results: tuple[ReplayResult, ...]

    def result(self, loop: Loop) -> ReplayResult | None:
        """The result of ``loop``, or None when it was not replayed."""
        return next((r for r in self.results if r.loop == loop), None)

    @property
    def tracked(self) -> bool:
        """The first result's verdict: closed loop when replayed (what a robot would run)."""
        return self.results[0].tracked

    def summary(self) -> str:
        """Every result's lines, then one verdict line per loop."""
        verdicts = ", ".join(f"{r.loop} loop {r.verdict}" for r in self.results)
        return "\n".join([*(r.summary() for r in self.results), f"verdict: {verdicts}"])


def _mm(x: float) -> str:
    return f"{x * 1e3:.2f} mm"


def _deg(x: float) -> str:
    return f"{math.degrees(x):.2f} deg"
