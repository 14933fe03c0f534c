"""Executable trajectories: a plan timed, sampled, with its grip forces.

:func:`build_trajectory` times a plan (:mod:`dexplan.execution.timing`), samples it at a
rate plus every segment boundary, and adds at each sample the contacts, the
grip forces and the joint torques (:mod:`dexplan.execution.forces`). Its
document form is :mod:`dexplan.execution.export`.

Samples: at ``k / rate`` from each segment's start, plus the segment's end;
consecutive segments share their boundary sample (at rest). At a sample inside
a waypoint step the contacts are those of the step's first waypoint, except a
finger that is free at the step's last waypoint (it is lifting off, or not yet
landed): free. A regrasp's free finger carries no load at any of its samples
(it lifts off unloaded), except the last one when another segment follows
(it has landed and takes its share there); at a boundary sample the next
regrasp's finger carries none.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from enum import StrEnum
from pathlib import Path
from typing import Any

import numpy as np

from dexplan.core.errors import InvalidInputError
from dexplan.core.typing import FloatArray
from dexplan.execution.forces import force_settings_from_plan, solver_from_plan
from dexplan.execution.segment_timing import (
    PlanTiming,
    SegmentTiming,
    TimingLimits,
    TrajectorySample,
)
from dexplan.execution.timing import time_plan
from dexplan.model.grasp.grip_forces import (
    ForceSettings,
    GripForceError,
    GripForces,
    GripForceSolver,
)
from dexplan.model.grasp.grip_program import joint_effort_limits
from dexplan.model.hand.hand import Hand
from dexplan.planfile import hand_from_plan

__all__ = [
    "DEFAULT_RATE",
    "MAX_RATE",
    "Trajectory",
    "Unbalanced",
    "build_trajectory",
]

#: Samples per second (Hz) when none is given, and the largest accepted.
DEFAULT_RATE = 100.0
MAX_RATE = 10000.0


class Unbalanced(StrEnum):
    """What :func:`build_trajectory` does where no grip forces balance the wrench."""

    #: Raise a :class:`~dexplan.model.grasp.grip_forces.GripForceError`.
    RAISE = "raise"
    #: No grip forces there (NaN margin): the physics replay of a tampered plan.
    ZERO = "zero"


@dataclass(frozen=True)
class Trajectory:
    """A timed plan, sampled (``m`` samples, ``n`` fingers, ``nq`` joints).

    Attributes:
        t: (m,) time from start (s), non-decreasing (strictly increasing
            except where a segment does not move).
        q, qd, qdd: (m, nq) joint positions, velocities, accelerations.
        object_pose: (m, 7) ``[x, y, z, qx, qy, qz, qw]``, world frame.
        object_velocity: (m, 6) ``[v, w]``, world frame (m/s, rad/s).
        object_acceleration: (m, 6) ``[dv/dt, d2c/dt2]``
            (:class:`dexplan.execution.segment_timing.TrajectorySample`).
        contacts: (m, n, 3) contact points, object frame (m); NaN for free fingers.
        normals: (m, n, 3) inward unit normals at the contacts, object frame; NaN when free.
        forces: (m, n, 3) grip forces on the object, object frame (N); NaN when free.
        torsion: (m, n) soft-finger torsional moments (N m); NaN when free.
        joint_torques: (m, nq) ``J^T f`` (N m).
        margins: (m,) cone margin each sample's forces keep (fraction of ``mu``).
        segments: per segment ``(kind, finger, first_sample, last_sample)``.
        timing: the :class:`~dexplan.execution.segment_timing.PlanTiming`.
        settings: the :class:`~dexplan.model.grasp.grip_forces.ForceSettings`.
        joint_effort: (nq,) the URDF's joint effort (torque) limits (N m), NaN
            where a joint has none; None when unknown.
    """

    t: FloatArray
    q: FloatArray
    qd: FloatArray
    qdd: FloatArray
    object_pose: FloatArray
    object_velocity: FloatArray
    object_acceleration: FloatArray
    contacts: FloatArray
    normals: FloatArray
    forces: FloatArray
    torsion: FloatArray
    joint_torques: FloatArray
    margins: FloatArray
    segments: tuple[tuple[str, int | None, int, int], ...]
    timing: PlanTiming
    settings: ForceSettings
    joint_effort: FloatArray | None = None

    @property
    def duration(self) -> float:
        """Total execution time (s)."""
        return float(self.t[-1]) if self.t.size else 0.0


def build_trajectory(
    doc: Mapping[str, Any],
    *,
    rate: float = DEFAULT_RATE,
    limits: TimingLimits | None = None,
    settings: ForceSettings | None = None,
    base_dir: str | Path = ".",
    hand: Hand | None = None,
    unbalanced: Unbalanced = Unbalanced.RAISE,
) -> Trajectory:
    """Time, sample and add forces to a validated plan.

    Args:
        doc: the plan (:func:`dexplan.planfile.document.read_plan`).
        rate: samples per second (Hz), in (0, :data:`MAX_RATE`].
        limits: timing limits (default :class:`~dexplan.execution.segment_timing.TimingLimits`).
        settings: force settings (default: the plan's mass and gravity).
        base_dir: the plan's folder (mesh paths).
        hand: the plan's hand (rebuilt from the file when None).
        unbalanced: where no forces balance the wrench: ``"raise"`` a
            GripForceError, or ``"zero"``: no grip forces there (NaN margin;
            the physics replay of a tampered plan).

    Raises:
        InvalidInputError: a bad rate.
        TimingError: a segment cannot be timed.
        GripForceError: at some sample no forces balance the wrench.
    """
    if isinstance(rate, bool) or not (
        isinstance(rate, int | float) and math.isfinite(rate) and 0 < rate <= MAX_RATE
    ):
        raise InvalidInputError(f"rate must be in (0, {MAX_RATE:g}] Hz, got {rate!r}")
    if hand is None:
        hand = hand_from_plan(doc["hand"])
    settings = force_settings_from_plan(doc) if settings is None else settings
    timing = time_plan(doc, TimingLimits() if limits is None else limits, hand)
    solver = solver_from_plan(doc, settings, hand, base_dir)
    segs = doc["segments"]
    n = hand.n_fingers
    samples = _Samples()
    ranges = []
    for si, (seg, st) in enumerate(zip(segs, timing.segments, strict=True)):
        ts = _sample_times(st.duration, rate, shared_start=si > 0)
        first = len(samples.t) - (1 if si > 0 else 0)
        smp = st.sample(ts)
        nxt = segs[si + 1] if si + 1 < len(segs) else None
        for j in range(ts.size):
            contacts, loaded = _sample_contacts(seg, st, nxt, ts, j, int(smp.step[j]), n)
            samples.add_forces(
                _grip_forces(solver, smp, j, contacts, loaded, unbalanced, si, st), contacts
            )
        samples.add_states(float(timing.start_times[si]) + ts, smp)
        ranges.append((seg["kind"], seg["finger"], first, len(samples.t) - 1))
    traj = samples.trajectory(n, hand.nq, tuple(ranges), timing, settings)
    return replace(traj, joint_effort=joint_effort_limits(hand.model))


def _sample_times(duration: float, rate: float, *, shared_start: bool) -> FloatArray:
    """A segment's sample times (s from its start): every ``1 / rate`` plus its end.

    Args:
        duration: the segment's duration (s); 0: one sample at 0.
        rate: samples per second (Hz).
        shared_start: the first sample is the previous segment's last: dropped
            (the boundary sample is the earlier segment's, with its contacts
            and forces).
    """
    ts = np.arange(0.0, duration, 1.0 / rate) if duration > 0 else np.zeros(1)
    if duration > 0:
        ts = ts[ts < duration - 1e-9]
        ts = np.append(ts, duration)
    if shared_start:
        ts = ts[1:] if ts.size > 1 else ts[:0]  # the shared boundary sample
    return ts


def _sample_contacts(
    seg: Mapping[str, Any],
    st: SegmentTiming,
    nxt: Mapping[str, Any] | None,
    ts: FloatArray,
    j: int,
    k: int,
    n: int,
) -> tuple[list[FloatArray | None], tuple[bool, ...]]:
    """The contacts of sample ``j`` of a segment and the fingers loaded there.

    Inside a waypoint step the contacts are those of the step's first waypoint,
    except a finger free at the step's last one (lifting off, or not yet
    landed). A regrasp's free finger is unloaded until it has landed (its last
    sample, shared with the next segment); the next regrasp's finger is
    unloaded from that shared sample on.

    Args:
        seg: the plan segment.
        st: its timing.
        nxt: the next plan segment, or None.
        ts: the segment's sample times (s from its start).
        j: the sample.
        k: the waypoint that starts the step sample ``j`` lies in.
        n: number of fingers.

    Returns:
        ``(contacts, loaded)``: per finger the contact point (object frame) or
        None, and whether it carries load.
    """
    wps = seg["waypoints"]
    if k + 1 < len(wps) and abs(ts[j] - st.waypoint_times[k + 1]) <= 1e-9:
        # at the next waypoint: the path parameter there can fall a rounding
        # error short of it (a regrasp's last sample then read the free
        # finger as not yet landed, and the next one's finger unloaded too)
        k += 1
    wp = wps[k]
    at_wp = abs(ts[j] - st.waypoint_times[k]) <= 1e-12 or k == len(wps) - 1
    contacts = []
    for i in range(n):
        c = wp["contacts"][i]
        lifting = not at_wp and k + 1 < len(wps) and wps[k + 1]["contacts"][i] is None
        if lifting:
            c = None
        contacts.append(None if c is None else np.asarray(c, dtype=float))
    free_here = seg["finger"] if seg["kind"] == "regrasp" else None
    free_next = nxt["finger"] if nxt is not None and nxt["kind"] == "regrasp" else None
    end = j == ts.size - 1
    loaded = tuple(
        c is not None
        and not (i == free_here and not (end and nxt is not None))
        and not (end and i == free_next)
        for i, c in enumerate(contacts)
    )
    return contacts, loaded


def _grip_forces(
    solver: GripForceSolver,
    smp: TrajectorySample,
    j: int,
    contacts: list[FloatArray | None],
    loaded: tuple[bool, ...],
    unbalanced: Unbalanced,
    si: int,
    st: SegmentTiming,
) -> GripForces:
    """Grip forces at sample ``j``; with ``unbalanced="zero"`` none (NaN margin) where none balance.

    Args:
        solver: the plan's grip-force solver.
        smp: the segment's samples.
        j: the sample.
        contacts: per finger, the contact point or None.
        loaded: the fingers that carry load.
        unbalanced: ``"raise"`` or ``"zero"`` (:func:`build_trajectory`).
        si: the segment's index (error messages).
        st: the segment's timing (error messages).

    Raises:
        GripForceError: no forces balance the wrench and ``unbalanced`` is not ``"zero"``.
    """
    k = int(smp.step[j])
    try:
        return solver.solve(
            smp.q[j],
            smp.object_pose[j],
            contacts,
            loaded,
            where=f"segment {si}, waypoint {k} (t = {st.waypoint_times[k]:.3f} s)",
        )
    except GripForceError:
        if unbalanced != Unbalanced.ZERO:
            raise
        g = solver.solve(smp.q[j], smp.object_pose[j], contacts, (False,) * len(contacts))
        return replace(g, margin=math.nan)


class _Samples:
    """The columns of a trajectory, filled segment by segment."""

    _STATES = ("q", "qd", "qdd", "object_pose", "object_velocity", "object_acceleration")

    def __init__(self) -> None:
        self.t: list[float] = []
        self.states: dict[str, list[Any]] = {key: [] for key in self._STATES}
        self.contacts: list[FloatArray] = []
        self.normals: list[FloatArray] = []
        self.forces: list[FloatArray] = []
        self.torsion: list[FloatArray] = []
        self.joint_torques: list[FloatArray] = []
        self.margins: list[float] = []

    def add_forces(self, g: GripForces, contacts: list[FloatArray | None]) -> None:
        """Append one sample's grip forces (NaN forces and torsion for free fingers)."""
        free = np.array([c is None for c in contacts])
        f = g.forces.copy()
        tor = g.torsion.copy()
        f[free] = np.nan
        tor[free] = np.nan
        self.contacts.append(g.contacts)
        self.normals.append(g.normals)
        self.forces.append(f)
        self.torsion.append(tor)
        self.joint_torques.append(g.joint_torques)
        self.margins.append(g.margin)

    def add_states(self, t: FloatArray, smp: TrajectorySample) -> None:
        """Append a segment's times (from the plan's start) and states."""
        self.t.extend(t.tolist())
        for key in self._STATES:
            self.states[key].extend(list(getattr(smp, key)))

    def trajectory(
        self,
        n: int,
        nq: int,
        ranges: tuple[tuple[str, int | None, int, int], ...],
        timing: PlanTiming,
        settings: ForceSettings,
    ) -> Trajectory:
        """The :class:`Trajectory` of the columns (``n`` fingers, ``nq`` joints)."""
        s = self.states
        return Trajectory(
            np.asarray(self.t),
            np.asarray(s["q"]).reshape(-1, nq),
            np.asarray(s["qd"]).reshape(-1, nq),
            np.asarray(s["qdd"]).reshape(-1, nq),
            np.asarray(s["object_pose"]).reshape(-1, 7),
            np.asarray(s["object_velocity"]).reshape(-1, 6),
            np.asarray(s["object_acceleration"]).reshape(-1, 6),
            np.asarray(self.contacts).reshape(-1, n, 3),
            np.asarray(self.normals).reshape(-1, n, 3),
            np.asarray(self.forces).reshape(-1, n, 3),
            np.asarray(self.torsion).reshape(-1, n),
            np.asarray(self.joint_torques).reshape(-1, nq),
            np.asarray(self.margins),
            ranges,
            timing,
            settings,
        )
