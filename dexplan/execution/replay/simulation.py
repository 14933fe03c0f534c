"""Physics replay of a plan in MuJoCo (extra ``sim``): does the object follow the plan?

The model is the plan's MJCF (:func:`dexplan.execution.replay.mjcf.build_mjcf`):
its actuators are limited to the hand's effort limits. :func:`replay_plan`
times the plan and computes its grip forces
(:func:`dexplan.execution.replay.driven_trajectory.replay_trajectory`: every
loaded contact pressed with at least 2 N where the effort limits allow; with
``gravity=False`` the forces balance no weight and only squeeze), then drives the
fingers along the timed trajectory (targets interpolated linearly between
samples) with the grip-force feed-forward ``J^T f``: closed loop through the
object-pose feedback (:class:`dexplan.execution.replay.control.ObjectFeedback`),
open loop on the planned joints. It measures the object's position and
orientation error against the plan (max over the samples and the waypoints,
and at the goal), contact losses (a loaded finger without a MuJoCo contact for
longer than :data:`LOSS_TIME`), slips (the contact point moving more than
:data:`SLIP_TOL` on the object from the planned one), the deepest penetration,
the actuator torques against their limits, and a drop (the object more than
:data:`~dexplan.execution.replay.result.DROP_TOL` from the plan), where the
replay stops (:class:`~dexplan.execution.replay.result.Drop`).
:func:`replay_loops` replays both loops (:class:`~dexplan.execution.replay.result.ReplayReport`).

Determinism: a replay depends only on the plan and its arguments. Each one
builds its own MuJoCo model and data (MuJoCo keeps no state between them,
and runs single-threaded here), its own grip-force solver (a fresh QP per
solve) and its own force-closure solver for the drop's hold quality; the
same plan gives the same report twice in one process and in a fresh one
(tests/test_replay_determinism.py).

mujoco is imported only in this module, on use (it is the optional extra ``sim``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from dexplan.core.errors import DependencyError, PlanFileError
from dexplan.core.pose import quat_angle
from dexplan.core.typing import FloatArray
from dexplan.execution.replay.control import CONTROL_PERIOD, FORCE_EVERY, ObjectFeedback
from dexplan.execution.replay.driven_trajectory import replay_trajectory
from dexplan.execution.replay.drops import DropScene, describe_drop, segment_of
from dexplan.execution.replay.handover import HANDOVER_TIME, HandOvers, insert_handovers
from dexplan.execution.replay.mjcf import KP, TIMESTEP, build_mjcf
from dexplan.execution.replay.result import (
    ANGLE_TOL,
    DROP_TOL,
    POSITION_TOL,
    Loop,
    ReplayReport,
    ReplayResult,
)
from dexplan.execution.replay.squeeze import SqueezeSolver
from dexplan.execution.trajectory import Trajectory
from dexplan.model.hand.hand import Hand
from dexplan.planfile import hand_from_plan, models_from_document

__all__ = [
    "replay_loops",
    "replay_plan",
    "require_mujoco",
]

#: A loaded finger without contact for longer than this: a contact loss (s).
LOSS_TIME = 0.02
#: Contact point farther than this from the planned one on the object: a slip (m).
SLIP_TOL = 0.003
#: Still time before the trajectory starts (s), with the start targets and forces.
SETTLE_TIME = 0.2
#: An actuator within this fraction of its limit counts as saturated.
_SATURATED = 0.999
_PIP = "pip install 'dexplan[sim]' (or: pip install mujoco)"


def require_mujoco() -> Any:
    """Import mujoco or raise DependencyError naming the pip command."""
    try:
        import mujoco
    except ImportError as exc:
        raise DependencyError(f"dexplan replay needs MuJoCo: {_PIP}") from exc
    return mujoco


# ------------------------------------------------------------------ replay
def replay_loops(
    doc: Mapping[str, Any],
    loops: Sequence[Loop | str] = (Loop.CLOSED, Loop.OPEN),
    *,
    gravity: bool = True,
    base_dir: str | Path = ".",
    rate: float = 100.0,
    mass: float | None = None,
    gravity_vector: FloatArray | None = None,
    hand: Hand | None = None,
    handover: float = HANDOVER_TIME,
) -> ReplayReport:
    """Replay the plan once per loop (closed: object-pose feedback; open: the planned joints).

    Args:
        doc: a validated plan (:func:`dexplan.planfile.document.read_plan`).
        loops: the loops to replay, in order.
        gravity: gravity on or off (as :func:`replay_plan`).
        base_dir: the plan's folder (mesh paths).
        rate: trajectory samples per second.
        mass: object mass (kg), default the plan's ``object.mass`` or 0.1.
        gravity_vector: (3,) overrides the plan's gravity (world frame).
        hand: the plan's hand (rebuilt from the file when None).
        handover: each hand-over's time (s), as :func:`replay_plan`.

    Raises:
        As :func:`replay_plan`.
    """
    if hand is None:
        hand = hand_from_plan(doc["hand"])
    results = tuple(
        replay_plan(
            doc,
            gravity=gravity,
            base_dir=base_dir,
            rate=rate,
            mass=mass,
            gravity_vector=gravity_vector,
            hand=hand,
            feedback=Loop(loop) == Loop.CLOSED,
            handover=handover,
        )
        for loop in loops
    )
    return ReplayReport(results)


def replay_plan(
    doc: Mapping[str, Any],
    *,
    gravity: bool = True,
    base_dir: str | Path = ".",
    rate: float = 100.0,
    mass: float | None = None,
    gravity_vector: FloatArray | None = None,
    hand: Hand | None = None,
    feedback: bool = True,
    handover: float = HANDOVER_TIME,
) -> ReplayResult:
    """Simulate the plan in MuJoCo and measure how far the object strays from it.

    Args:
        doc: a validated plan (:func:`dexplan.planfile.document.read_plan`).
        gravity: gravity on (the plan's ``world.gravity`` or ``(0, 0, -9.81)``) or off.
        base_dir: the plan's folder (mesh paths).
        rate: trajectory samples per second (targets in between are interpolated).
        mass: object mass (kg), default the plan's ``object.mass`` or 0.1.
        gravity_vector: (3,) overrides the plan's gravity (world frame).
        hand: the plan's hand (rebuilt from the file when None).
        feedback: correct the fingertip targets from the measured object pose
            (:class:`dexplan.execution.replay.control.ObjectFeedback`); False: the
            planned joints open loop.
        handover: the time (s) of each hand-over
            (:func:`dexplan.execution.replay.handover.insert_handovers`): where
            the fingers holding the object change, the hand waits this long
            while the load passes from the old fingers to the new ones; 0: the
            plan's timing, the load switched within one sample.

    Where no grip forces balance the wrench (a tampered plan) the fingers get
    no feed-forward there and only follow their targets; the result counts
    those samples (:attr:`ReplayResult.unbalanced_samples`).

    Raises:
        DependencyError: mujoco is not installed.
        PlanFileError: MuJoCo rejects the model built from the plan.
        TimingError: the plan cannot be timed.
    """
    mujoco = require_mujoco()
    if hand is None:
        hand = hand_from_plan(doc["hand"])
    traj = replay_trajectory(
        doc,
        gravity=gravity,
        base_dir=base_dir,
        rate=rate,
        mass=mass,
        gravity_vector=gravity_vector,
        hand=hand,
    )
    settings = traj.settings
    # replay_settings gave the trajectory its gravity, already zero with gravity off
    g = np.asarray(settings.gravity, dtype=float)
    solver = SqueezeSolver(doc, settings, hand, base_dir)
    traj, handovers = insert_handovers(traj, solver, handover, rate)
    xml, tips = build_mjcf(doc, hand, mass=settings.mass, gravity=g, base_dir=base_dir)
    try:
        m = mujoco.MjModel.from_xml_string(xml)
    except Exception as exc:  # mujoco's ValueError
        raise PlanFileError(f"MuJoCo rejects the model built from the plan: {exc}") from exc
    feedback_ctl = None
    if feedback:
        rolling = doc.get("contact_motion", "fixed") == "rolling"
        feedback_ctl = ObjectFeedback(hand, traj, solver, rolling=rolling, handovers=handovers)
    run = _Replay(mujoco, m, hand, tips, traj, feedback_ctl)
    run.simulate()
    loop = Loop.CLOSED if feedback else Loop.OPEN
    return _replay_result(doc, gravity, loop, traj, run, base_dir, handovers)


def _replay_result(
    doc: Mapping[str, Any],
    gravity: bool,
    loop: Loop,
    traj: Trajectory,
    run: _Replay,
    base_dir: str | Path,
    handovers: HandOvers,
) -> ReplayResult:
    """The errors of a finished simulation against the plan's trajectory and goal.

    Args:
        doc: the plan.
        gravity: whether gravity was on.
        loop: the loop replayed.
        traj: the sampled trajectory (:class:`dexplan.execution.trajectory.Trajectory`).
        run: the finished simulation (its samples end at the drop, if any).
        base_dir: the plan's folder (mesh paths).
        handovers: the hand-overs inserted into ``traj``.
    """
    k = run.rec_idx
    sim_pose, planned = run.sim_pose[:k], traj.object_pose[:k]
    pos_err = np.linalg.norm(sim_pose[:, :3] - planned[:, :3], axis=1)
    ang_err = np.array([quat_angle(a[3:], b[3:]) for a, b in zip(sim_pose, planned, strict=True)])
    before = k - 1 if run.drop_sample is not None else k  # the drop sample is the drop
    wp_pos, wp_ang, reached, total = _waypoint_errors(doc, traj, sim_pose[:before])
    drop = None
    if run.drop_sample is not None:
        models = models_from_document(doc, base_dir, hand=run.hand)
        drop = describe_drop(traj, models, run.drop_scene())
    gp = np.asarray(doc["goal"]["object_pose_xyzquat"], dtype=float)
    fin = sim_pose[-1]
    return ReplayResult(
        loop=loop,
        gravity=gravity,
        duration=traj.duration,
        n_segments=len(doc["segments"]),
        t=traj.t[:k],
        planned_pose=planned,
        sim_pose=sim_pose,
        planned_q=traj.q[:k],
        sim_q=run.sim_q[:k],
        position_error=pos_err,
        angle_error=ang_err,
        max_position_error=float(pos_err[:before].max(initial=0.0)),
        max_angle_error=float(ang_err[:before].max(initial=0.0)),
        waypoint_position_error=wp_pos,
        waypoint_angle_error=wp_ang,
        waypoints_reached=reached,
        waypoints=total,
        goal_position_error=None if drop else float(np.linalg.norm(fin[:3] - gp[:3])),
        goal_angle_error=None if drop else float(quat_angle(fin[3:], gp[3:])),
        goal_tolerances=(
            float(doc["goal"].get("position_tol", 0.005)),
            float(doc["goal"].get("angle_tol", 0.05)),
        ),
        contact_losses=tuple(run.losses),
        slips=tuple(run.slips),
        max_contact_drift=run.max_drift,
        drop=drop,
        max_penetration=run.max_pen,
        unbalanced_samples=int(np.sum(np.isnan(traj.margins))),
        effort_limits=tuple(float(e) for e in run.effort),
        max_effort_ratio=run.max_effort_ratio,
        saturated_time=run.saturated_steps * TIMESTEP,
        handovers=handovers.count,
        handover_time=handovers.added_time,
    )


class _Replay:
    """One MuJoCo run of a timed trajectory and what it records (``m`` samples, ``n`` fingers).

    Attributes:
        sim_pose: (m, 7) the simulated object pose at each sample, world frame, XYZW.
        sim_q: (m, nq) the simulated joints at each sample.
        touching: (m, n) which fingertips touch the object in MuJoCo at each sample.
        rec_idx: samples recorded (all of them unless the object was dropped).
        losses: (finger, time) of each contact loss.
        slips: (finger, time, distance) of each slip event.
        max_pen: deepest hand-object penetration (m).
        max_drift: farthest a loaded tip's contact was from the planned one (m).
        drop_sample: the first sample farther than DROP_TOL from the plan, or None.
        lost_sample: the first sample outside the tracking tolerances, or None.
        effort: (nq,) the joints' effort limits (N m), NaN where none.
        max_effort_ratio: the largest ``|actuator torque| / limit`` seen.
        saturated_steps: steps with a limited actuator at its limit.
    """

    def __init__(
        self,
        mujoco: Any,
        m: Any,
        hand: Hand,
        tips: list[int],
        traj: Trajectory,
        feedback: ObjectFeedback | None = None,
    ) -> None:
        self.mujoco, self.m, self.traj, self.hand = mujoco, m, traj, hand
        self.d = mujoco.MjData(m)
        self.nq = hand.nq
        self.jq = np.array([m.jnt_qposadr[m.joint(n).id] for n in hand.joint_names])
        self.jv = np.array([m.jnt_dofadr[m.joint(n).id] for n in hand.joint_names])
        self.oq = m.jnt_qposadr[m.joint("object").id]
        # every geom of the object's body: a concave mesh is several convex parts
        self.obj_geoms = {
            int(g) for g in np.flatnonzero(np.asarray(m.geom_bodyid) == m.body("object").id)
        }
        tip_ids = [m.geom(f"hand{k}").id for k in tips]
        self.tip_of = {gid: i for i, gid in enumerate(tip_ids)}
        self.hand_geoms = {
            m.geom(f"hand{k}").id for k in range(hand.geom_model.ngeoms) if _has(m, k)
        }
        n = hand.n_fingers
        self.n = n
        self.loaded = ~np.isnan(traj.forces[:, :, 0])  # (m, n): fingers planned in contact
        self.feedback = feedback
        self.sim_pose = np.empty((traj.t.size, 7))
        self.sim_q = np.empty((traj.t.size, self.nq))
        self.touching = np.zeros((traj.t.size, n), dtype=bool)
        self.rec_idx = 0
        self.missing = np.zeros(n)
        self.losses: list[tuple[int, float]] = []
        self.slips: list[tuple[int, float, float]] = []
        self.slipping = np.zeros(n, dtype=bool)
        self.max_pen = 0.0
        self.max_drift = 0.0
        self.drop_sample: int | None = None
        self.lost_sample: int | None = None
        # the limits the compiled model clamps to (NaN: an unlimited actuator)
        jid = [m.joint(name).id for name in hand.joint_names]
        self.effort = np.where(
            np.asarray(m.jnt_actfrclimited)[jid].astype(bool),
            np.asarray(m.jnt_actfrcrange)[jid, 1],
            np.nan,
        )
        self.max_effort_ratio = 0.0
        self.saturated_steps = 0

    def simulate(self) -> None:
        """Settle at the start, then follow the trajectory to its end or the drop."""
        mujoco, m, d, traj, oq = self.mujoco, self.m, self.d, self.traj, self.oq
        d.qpos[self.jq] = traj.q[0]
        for name, mim in self.hand.mimic_joints.items():  # coupled joints start coupled
            q_primary = traj.q[0][self.hand.joint_names.index(mim.primary)]
            d.qpos[m.jnt_qposadr[m.joint(name).id]] = mim.multiplier * q_primary + mim.offset
        d.qpos[oq : oq + 3] = traj.object_pose[0, :3]
        d.qpos[oq + 3 : oq + 7] = traj.object_pose[0, [6, 3, 4, 5]]
        mujoco.mj_forward(m, d)
        steps_total = math.ceil((SETTLE_TIME + traj.t[-1]) / TIMESTEP) + 1
        every = max(1, round(CONTROL_PERIOD / TIMESTEP))
        target, ff_now = traj.q[0], traj.joint_torques[0]
        pose_now = traj.object_pose[0]
        for step in range(steps_total):
            i, planned, ff, planned_pose = self._targets(step * TIMESTEP - SETTLE_TIME)
            if self.feedback is None:
                target = planned
            elif step % every == 0:
                q_sim = d.qpos[self.jq]
                target = self.feedback.targets(i, planned, q_sim, planned_pose, pose_now)
                if step % (every * FORCE_EVERY) == 0 or self.feedback.forces_due(i):
                    ff_now = self.feedback.feed_forward(i, q_sim, pose_now, ff)
            if self.feedback is not None:
                ff = ff_now
            # the feed-forward rides on the position actuator (ctrl offset ff / KP)
            # so that the actuator's force limit bounds the total joint torque
            d.ctrl[: self.nq] = target + np.asarray(ff) / KP
            mujoco.mj_step(m, d)
            self._count_effort()
            now = (step + 1) * TIMESTEP - SETTLE_TIME
            pose_now = np.concatenate(
                [d.qpos[oq : oq + 3], d.qpos[oq + 4 : oq + 7], d.qpos[oq + 3 : oq + 4]]
            )
            touching = self._scan_contacts(i, now, pose_now)
            if now >= 0.0:
                self._count_losses(i, now, touching)
            self._record(now, pose_now, touching)
            if self.drop_sample is not None:  # what a fallen object does is no test of the plan
                return
        while self.rec_idx < traj.t.size:  # numerical end: the last state
            self.sim_pose[self.rec_idx] = self.sim_pose[self.rec_idx - 1]
            self.sim_q[self.rec_idx] = self.sim_q[self.rec_idx - 1]
            self.touching[self.rec_idx] = self.touching[self.rec_idx - 1]
            self.rec_idx += 1

    def drop_scene(self) -> DropScene:
        """What the simulation saw before the drop (call only after a drop).

        The hold is that of the fingers the plan holds the object with at the
        drop, read at the last sample of the drop's segment, up to the track
        loss, at which all of them touched the object in MuJoCo (by the loss
        itself the object is often already falling free); the segment's first
        sample when there is none.
        """
        assert self.drop_sample is not None
        lost = self.drop_sample if self.lost_sample is None else self.lost_sample
        holders = ~np.isnan(self.traj.contacts[self.drop_sample, :, 0])
        first = self.traj.segments[segment_of(self.traj, self.drop_sample)][2]
        lo = min(first, lost)
        held = np.flatnonzero(np.all(self.touching[lo : lost + 1] | ~holders, axis=1))
        k = lo + int(held[-1]) if held.size else lo
        return DropScene(
            drop_sample=self.drop_sample,
            lost_sample=lost,
            hold_sample=k,
            sim_pose=self.sim_pose[k].copy(),
            sim_q=self.sim_q[k].copy(),
            touching=self.touching[k] & holders,
        )

    def _count_effort(self) -> None:
        """The joints' total actuator torque against their effort limits, after a step."""
        tau = np.abs(np.asarray(self.d.qfrc_actuator)[self.jv])
        limited = np.isfinite(self.effort)
        if not limited.any():
            return
        ratio = tau[limited] / self.effort[limited]
        self.max_effort_ratio = max(self.max_effort_ratio, float(ratio.max()))
        self.saturated_steps += int(bool((ratio >= _SATURATED).any()))

    def _targets(self, now: float) -> tuple[int, FloatArray, FloatArray, FloatArray]:
        """The sample before ``now``, the planned joints, feed-forward torques and object pose.

        All are interpolated linearly between samples (the quaternion
        normalised); ``now`` is clipped to the trajectory (before its start:
        the start; after its end: the end).
        """
        t, traj = self.traj.t, self.traj
        tt = min(max(now, 0.0), t[-1])
        i = int(np.clip(np.searchsorted(t, tt, side="right") - 1, 0, t.size - 1))
        if i + 1 < t.size and t[i + 1] > t[i]:
            w = (tt - t[i]) / (t[i + 1] - t[i])
            target = (1 - w) * traj.q[i] + w * traj.q[i + 1]
            ff = (1 - w) * traj.joint_torques[i] + w * traj.joint_torques[i + 1]
            a, b = traj.object_pose[i], traj.object_pose[i + 1]
            if float(np.dot(a[3:], b[3:])) < 0.0:
                b = np.concatenate([b[:3], -b[3:]])
            pose = (1 - w) * a + w * b
            pose[3:] /= np.linalg.norm(pose[3:])
        else:
            target, ff, pose = traj.q[i], traj.joint_torques[i], traj.object_pose[i]
        return i, target, ff, pose

    def _scan_contacts(self, i: int, now: float, pose_now: FloatArray) -> np.ndarray:
        """The fingertips touching the object; records penetration depth and slips.

        Args:
            i: the trajectory sample the step started from.
            now: the time after the step (s from the trajectory's start).
            pose_now: (7,) the object pose after the step.

        Returns:
            (n,) whether each fingertip has a MuJoCo contact with the object.
        """
        d, obj_geoms = self.d, self.obj_geoms
        touching = np.zeros(self.n, dtype=bool)
        R = pin.Quaternion(pose_now[6], pose_now[3], pose_now[4], pose_now[5]).normalized()
        Rm = R.toRotationMatrix()
        for c in range(d.ncon):
            con = d.contact[c]
            g1, g2 = int(con.geom1), int(con.geom2)
            if (g1 in obj_geoms) == (g2 in obj_geoms):
                continue
            other = g2 if g1 in obj_geoms else g1
            if other in self.hand_geoms:
                self.max_pen = max(self.max_pen, -float(con.dist))
            f = self.tip_of.get(other)
            if f is None:
                continue
            touching[f] = True
            if now >= 0.0 and self.loaded[i, f]:
                p_obj = Rm.T @ (np.asarray(con.pos) - pose_now[:3])
                dist = float(np.linalg.norm(p_obj - self.traj.contacts[i, f]))
                self.max_drift = max(self.max_drift, dist)
                if dist > SLIP_TOL and not self.slipping[f]:
                    self.slips.append((f, now, dist))
                self.slipping[f] = dist > SLIP_TOL
        return touching

    def _count_losses(self, i: int, now: float, touching: np.ndarray) -> None:
        """A contact loss where a loaded finger has gone without contact for :data:`LOSS_TIME`."""
        for f in range(self.n):
            if self.loaded[i, f] and not touching[f]:
                self.missing[f] += TIMESTEP
                if self.missing[f] > LOSS_TIME and self.missing[f] - TIMESTEP <= LOSS_TIME:
                    self.losses.append((f, now))
            else:
                self.missing[f] = 0.0

    def _record(self, now: float, pose_now: FloatArray, touching: np.ndarray) -> None:
        """Record the state at every sample reached by ``now``, the track loss and the drop."""
        t, traj = self.traj.t, self.traj
        while self.rec_idx < t.size and now >= t[self.rec_idx] - 1e-9:
            k = self.rec_idx
            self.sim_pose[k] = pose_now
            self.sim_q[k] = self.d.qpos[self.jq]
            self.touching[k] = touching
            self.rec_idx += 1
            err = float(np.linalg.norm(pose_now[:3] - traj.object_pose[k, :3]))
            ang = quat_angle(pose_now[3:], traj.object_pose[k, 3:])
            if self.lost_sample is None and (err > POSITION_TOL or ang > ANGLE_TOL):
                self.lost_sample = k
            if err > DROP_TOL:
                self.drop_sample = k
                return


def _waypoint_errors(
    doc: Mapping[str, Any], traj: Trajectory, sim_pose: FloatArray
) -> tuple[float, float, int, int]:
    """Largest position (m) and angle (rad) error at the plan's waypoints reached.

    Each waypoint is compared with the first simulated sample at or after its
    time in the trajectory; waypoints after the last sample given are not reached.

    Args:
        doc: the plan (its waypoints' object poses).
        traj: its :class:`~dexplan.execution.trajectory.Trajectory`.
        sim_pose: (k, 7) the simulated object pose at the first ``k`` samples.

    Returns:
        ``(position, angle, reached, total)``: the errors (0 when none is
        reached) and the count of waypoints reached and in the plan.
    """
    t = traj.t
    wp_t = np.concatenate(
        [
            traj.timing.start_times[s] + seg.waypoint_times
            for s, seg in enumerate(traj.timing.segments)
        ]
    )
    wp_pose = np.array(
        [w["object_pose_xyzquat"] for s in doc["segments"] for w in s["waypoints"]], dtype=float
    )
    idx = np.clip(np.searchsorted(t, wp_t - 1e-9), 0, t.size - 1)
    reached = idx < len(sim_pose)
    if not reached.any():
        return 0.0, 0.0, 0, len(wp_pose)
    idx, wp_pose = idx[reached], wp_pose[reached]
    wp_pos = float(np.max(np.linalg.norm(sim_pose[idx, :3] - wp_pose[:, :3], axis=1)))
    wp_ang = float(max(quat_angle(sim_pose[k, 3:], wp_pose[j, 3:]) for j, k in enumerate(idx)))
    return wp_pos, wp_ang, int(reached.sum()), len(reached)


def _has(m: Any, k: int) -> bool:
    try:
        m.geom(f"hand{k}")
    except KeyError:
        return False
    return True
