"""Object-pose feedback for the physics replay: the fingertip targets.

The replay itself is :mod:`dexplan.execution.replay.simulation`.

The plan keeps every contact fixed on the object during a transfer while the
rigid fingertip sphere (radius ``r``) turns with its link, so the tip's
material point at the contact would have to slide on the object by
``r (w_object - w_link) x n``. Friction resists that: in physics the tips
roll, the contacts move on the object and, driven open loop by the planned
joints, the object turns less than planned (a fraction of each transfer's
rotation), and the error grows until it drops. A robot executing such a plan
tracks the object and corrects its fingers; :class:`ObjectFeedback` does the
same, every :data:`CONTROL_PERIOD`:

- a *holding* finger (in contact in the plan at this sample) aims its tip
  centre at ``T p_tip``, where ``p_tip`` is its measured tip centre and ``T``
  the transform from the measured to the planned object pose: the finger keeps
  the contact where it actually is on the object (wherever rolling moved it)
  and carries it to where the plan wants the object now;
- in a plan with rolling contacts (``contact_motion = "rolling"``) the
  planned joints already roll each tip over the object as MuJoCo's rigid tips
  roll (the plan's contact kinematics), so a holding finger follows its
  planned joints plus the same correction, ``T p_tip - p_tip`` mapped to the
  joints at the planned configuration: the correction moves the object, the
  planned joints keep the contacts on the plan's rolled contacts. Carrying
  the measured tip, as for fixed contacts, would hold each tip centre still
  on the object, which a rolling plan's tips are not: they lag the planned
  rolling, the contacts migrate and the hold weakens (paper_sphere seed 4
  lost track that way, by more than 20 degrees, and tracks within 0.5
  degrees this way);
- a *free* finger (a regrasp's moving finger) aims at its planned tip moved
  by the inverse transform (it lands on the planned contact of the object
  where the object actually is), plus the offset it had when it let go (the
  contact had rolled away from the planned one), fading out as the plan lifts
  the tip :data:`LIFT_BLEND` away.

A tip displacement goes to the finger's joints through one damped least
squares step on its position Jacobian, from the measured joints (the loop
closes every period; at most :data:`MAX_JOINT_STEP`), or, for a free finger
once its offset has faded, from the planned joints (no tracking lag: a
lagging tip cuts the corner of a regrasp's path and lands early). The
grip-force feed-forward ``J^T f`` is kept; the errors reported stay those of
the measured object against the plan.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from dexplan.core.typing import FloatArray
from dexplan.execution.replay.handover import HandOvers, loaded_fingers_of
from dexplan.execution.replay.squeeze import SqueezeSolver
from dexplan.execution.trajectory import Trajectory
from dexplan.model.grasp.grip_forces import GripForceError, GripForceSolver
from dexplan.model.hand.hand import Hand
from dexplan.planfile import shape_of

__all__ = [
    "CONTROL_PERIOD",
    "FORCE_EVERY",
    "LIFT_BLEND",
    "ObjectFeedback",
    "planned_tip_slip",
    "pose_se3",
]

#: Feedback update period (s); the grip forces are recomputed every FORCE_EVERY updates.
CONTROL_PERIOD = 0.005
FORCE_EVERY = 10
#: A released finger's offset from the plan fades out as the plan lifts its tip this far (m).
LIFT_BLEND = 0.01
#: A free finger's tip kept this far off the object (m) until LAND_TIME (s) before it lands
#: (planned regrasp paths may graze the object, a fraction of a millimetre from it).
CLEARANCE = 0.002
LAND_TIME = 0.4
#: Pull of a redundant finger's null space toward the planned joints (per update).
NULL_GAIN = 0.1
#: Largest tip correction (m) and joint step (rad) per update; the damping of the
#: least squares step (m): near full extension a finger's joint steps blow up.
MAX_CORRECTION = 0.02
MAX_JOINT_STEP = 0.05
_DAMPING = 5e-3


def pose_se3(p: FloatArray) -> pin.SE3:
    """SE3 of a pose ``[x, y, z, qx, qy, qz, qw]``."""
    q = pin.Quaternion(float(p[6]), float(p[3]), float(p[4]), float(p[5])).normalized()
    return pin.SE3(q.toRotationMatrix(), np.asarray(p[:3], dtype=float))


def _dls(J: FloatArray, dx: FloatArray) -> FloatArray:
    """Damped least squares joint step (at most MAX_JOINT_STEP) for a tip displacement ``dx``."""
    dq = J.T @ np.linalg.solve(J @ J.T + _DAMPING**2 * np.eye(3), dx)
    big = float(np.abs(dq).max(initial=0.0))
    return dq if big <= MAX_JOINT_STEP else dq * (MAX_JOINT_STEP / big)


def _clip(dx: FloatArray) -> FloatArray:
    n = float(np.linalg.norm(dx))
    return dx if n <= MAX_CORRECTION else dx * (MAX_CORRECTION / n)


class ObjectFeedback:
    """Joint targets that carry the measured object onto the plan (``n`` fingers).

    Args:
        hand: the plan's :class:`~dexplan.model.hand.hand.Hand`.
        traj: the sampled trajectory (:class:`dexplan.execution.trajectory.Trajectory`).
        solver: the replay's grip forces
            (:class:`~dexplan.execution.replay.squeeze.SqueezeSolver`, or the
            plan's :class:`~dexplan.model.grasp.grip_forces.GripForceSolver`): the
            feed-forward forces are recomputed at the measured contacts; None
            keeps the planned ones.
        rolling: the plan's contacts roll during transfers (``contact_motion``
            ``"rolling"``): the holding tips follow the plan's rolling.
        handovers: the trajectory's hand-overs
            (:func:`dexplan.execution.replay.handover.insert_handovers`), or None.
    """

    def __init__(
        self,
        hand: Hand,
        traj: Trajectory,
        solver: GripForceSolver | SqueezeSolver | None = None,
        *,
        rolling: bool = False,
        handovers: HandOvers | None = None,
    ) -> None:
        self.hand = hand
        self.traj, self.solver, self.rolling = traj, solver, rolling
        self.handovers = handovers
        self.holding = ~np.isnan(traj.forces[:, :, 0])
        self.loaded = loaded_fingers_of(traj)
        #: the loaded fingers the feed-forward was last solved for (None: never)
        self.solved_for: np.ndarray | None = None
        self.solved_at = -1
        holding = self.holding
        self.idx = [np.asarray(ix, dtype=int) for ix in hand.finger_q_index]
        self.lower, self.upper = np.asarray(hand.lower), np.asarray(hand.upper)
        n = hand.n_fingers
        #: per finger: its tip's offset from the plan when it let go (object frame),
        #: the planned tip then (object frame) and how far the plan has lifted it since.
        self.offset = np.zeros((n, 3))
        self.release_tip = np.zeros((n, 3))
        self.lifted = np.zeros(n)
        self.was_holding = holding[0].copy()
        self.landing = _next_hold_times(traj.t, holding)
        #: (m,) samples where the plan rolls the holding tips: transfers (a
        #: regrasp and a hand-over hold the object still)
        self.rolls = np.zeros(traj.t.size, dtype=bool)
        if rolling:
            for kind, _, first, last in traj.segments:
                self.rolls[first : last + 1] |= kind == "transfer"
            if handovers is not None:
                self.rolls &= np.isnan(handovers.blend)

    def targets(
        self,
        i: int,
        q_plan: FloatArray,
        q_sim: FloatArray,
        planned_pose: FloatArray,
        sim_pose: FloatArray,
    ) -> FloatArray:
        """Joint targets (nq,) now.

        Args:
            i: the trajectory sample now lies after.
            q_plan: (nq,) the planned joints now.
            q_sim: (nq,) the measured joints.
            planned_pose: (7,) the planned object pose now, world frame.
            sim_pose: (7,) the measured object pose, world frame.
        """
        Xp, Xm = pose_se3(planned_pose), pose_se3(sim_pose)
        p_sim, J_sim = self.hand.fingertip_jacobians(q_sim)
        p_plan, J_plan = self.hand.fingertip_jacobians(q_plan)
        out = np.array(q_plan, dtype=float)
        for f, ix in enumerate(self.idx):
            hold = bool(self.holding[i, f])
            plan_tip = Xp.actInv(p_plan[f])  # object frame
            if self.was_holding[f] and not hold:  # lets go where rolling took the contact
                self.offset[f] = Xm.actInv(p_sim[f]) - plan_tip
                self.release_tip[f] = plan_tip
                self.lifted[f] = 0.0
            self.was_holding[f] = hold
            keep = 1.0
            rolls = hold and bool(self.rolls[i])
            if hold:  # carry the measured contact to where the plan wants the object
                move = Xp.act(Xm.actInv(p_sim[f])) - p_sim[f]
                move = self._press(p_plan[f] if rolls else p_sim[f], move, p_sim[f], Xm)
            if rolls:  # the planned joints roll the tips; correct the object
                out[ix] = q_plan[ix] + _dls(J_plan[f], _clip(move))
                continue
            if hold:
                goal = p_sim[f] + move
            else:
                lift = float(np.linalg.norm(plan_tip - self.release_tip[f]))
                self.lifted[f] = max(self.lifted[f], lift)
                keep = max(0.0, 1.0 - self.lifted[f] / LIFT_BLEND)
                goal = Xm.act(plan_tip + keep * self.offset[f])
            if keep == 0.0:  # lifted off: the planned joints corrected to first order (no lag)
                goal = Xm.act(self._clear(plan_tip, float(self.landing[i, f] - self.traj.t[i])))
                out[ix] = q_plan[ix] + _dls(J_plan[f], _clip(goal - p_plan[f]))
                continue
            J = J_sim[f]
            out[ix] = q_sim[ix] + _dls(J, _clip(goal - p_sim[f]))
            if len(ix) > 3:  # a redundant finger: its null space toward the plan
                null = np.eye(len(ix)) - np.linalg.pinv(J) @ J
                out[ix] += NULL_GAIN * null @ (q_plan[ix] - q_sim[ix])
        return np.clip(out, self.lower, self.upper)

    def _press(
        self, start: FloatArray, move: FloatArray, p_tip: FloatArray, Xm: pin.SE3
    ) -> FloatArray:
        """A holding finger's tip correction (world frame) that never pulls and keeps it pressing.

        A finger can push an object, not pull it: a correction that carries
        the object toward the plan by moving a tip out along the contact's
        outward normal only lifts that tip off (and a just-landed finger,
        which holds little yet, lets go). So the outward part of ``move`` is
        dropped, and where the tip would still aim outside the measured
        object's surface (it has not reached the object, or the object moved
        away from it) it aims onto the surface: the grip-force feed-forward
        then presses it on the object, as a guarded approach closes a finger
        until contact.

        Args:
            start: (3,) the tip centre the correction is added to, world frame.
            move: (3,) the correction, world frame (m).
            p_tip: (3,) the measured tip centre, world frame.
            Xm: the measured object pose.
        """
        if self.solver is None:
            return move
        obj, r = self.solver.obj, self.hand.fingertip_radius
        _, n_obj = obj.closest_point(Xm.actInv(p_tip))
        n_out = Xm.rotation @ np.reshape(n_obj, 3)
        move = move - max(0.0, float(np.dot(move, n_out))) * n_out
        goal = Xm.actInv(start + move)
        c, n_obj = (np.reshape(v, 3) for v in obj.closest_point(goal))
        gap = float(np.dot(goal - c, n_obj)) - r
        if gap > 0.0:
            move = move - gap * (Xm.rotation @ n_obj)
        return move

    def _clear(self, tip: FloatArray, to_landing: float) -> FloatArray:
        """A free tip centre (object frame) kept :data:`CLEARANCE` off the object until it lands.

        The push along the outward normal fades out between :data:`LAND_TIME`
        and a quarter of it before the landing.
        """
        if self.solver is None:
            return tip
        fade = min(1.0, max(0.0, (to_landing - LAND_TIME / 4) / (0.75 * LAND_TIME)))
        if fade == 0.0:
            return tip
        c, n_out = (np.reshape(v, 3) for v in self.solver.obj.closest_point(tip))
        gap = float(np.dot(tip - c, n_out)) - self.hand.fingertip_radius
        if gap >= CLEARANCE:
            return tip
        return tip + fade * (CLEARANCE - gap) * n_out

    def forces_due(self, i: int) -> bool:
        """Whether the feed-forward must be solved again at sample ``i``, not only periodically.

        The loaded fingers changed since the last solve (a finger landed or let
        go: the old forces would load a lifting finger or leave a landed one
        idle), or a hand-over is under way and ``i`` is a sample not solved
        for yet (the blend moves every sample).
        """
        if self.handovers is not None and np.isfinite(self.handovers.blend[i]):
            return i != self.solved_at
        return self.solved_for is None or not np.array_equal(self.solved_for, self.loaded[i])

    def feed_forward(
        self, i: int, q_sim: FloatArray, sim_pose: FloatArray, planned: FloatArray
    ) -> FloatArray:
        """Joint torques (nq,) of grip forces at the measured contacts.

        The contacts are the object's surface points closest to the measured
        tip centres, the forces those of the plan's solver there (least norm,
        in the margin-shrunk cones, balancing the replay's wrench) for the
        fingers the plan loads at sample ``i``; during a hand-over the blend
        of those of the fingers loaded before and after it (as the planned
        forces blend). The planned torques where the solver has none, the
        plan has none at ``i`` (a tampered plan) or no forces balance at the
        measured contacts.

        Args:
            i: the trajectory sample now lies after.
            q_sim: (nq,) the measured joints.
            sim_pose: (7,) the measured object pose, world frame.
            planned: (nq,) the planned feed-forward torques now.
        """
        self.solved_for, self.solved_at = self.loaded[i].copy(), i
        if self.solver is None or np.isnan(self.traj.margins[i]):
            return planned
        Xm = pose_se3(sim_pose)
        p_sim = self.hand.fingertip_positions(q_sim)
        contacts: list[FloatArray | None] = []
        for f in range(self.hand.n_fingers):
            if not self.holding[i, f]:
                contacts.append(None)
                continue
            c, _ = self.solver.obj.closest_point(Xm.actInv(p_sim[f]))
            contacts.append(np.asarray(c, dtype=float).reshape(3))
        ho = self.handovers
        lam = math.nan if ho is None else float(ho.blend[i])
        try:
            if math.isnan(lam):
                g = self.solver.solve(q_sim, sim_pose, contacts, tuple(self.loaded[i]))
                return np.asarray(g.joint_torques, dtype=float)
            assert ho is not None
            old = self.solver.solve(q_sim, sim_pose, contacts, tuple(ho.loaded_from[i]))
            new = self.solver.solve(q_sim, sim_pose, contacts, tuple(ho.loaded_to[i]))
        except GripForceError:
            return planned
        return (1.0 - lam) * np.asarray(old.joint_torques) + lam * np.asarray(new.joint_torques)


def planned_tip_slip(doc: Mapping[str, Any], hand: Hand) -> FloatArray:
    """The sliding each transfer of a plan asks of the rigid fingertips (the open-loop gap).

    Along a transfer the plan keeps each contact fixed on the object while the
    fingertip sphere turns with its link; the tip's material point at the
    contact then slides on the object by ``r (w_object - w_link) x n``. This
    sums its length over each transfer's waypoint steps, with the relative
    rotation of each step taken in the object frame and ``n`` the outward
    normal of the plan's object at the contact.

    Args:
        doc: a validated plan.
        hand: its :class:`~dexplan.model.hand.hand.Hand`.

    Returns:
        (transfers, n) slip length (m) per transfer segment and finger (0 for a
        finger not in contact).
    """
    obj = shape_of(doc["object"], Path("."), "object")
    r = float(hand.fingertip_radius)
    rows = []
    for seg in doc["segments"]:
        if seg["kind"] != "transfer":
            continue
        slip = np.zeros(hand.n_fingers)
        wps = seg["waypoints"]
        for a, b in itertools.pairwise(wps):
            Ta, Tb = _tip_rotations(hand, a["q"]), _tip_rotations(hand, b["q"])
            Ra = pose_se3(np.asarray(a["object_pose_xyzquat"], dtype=float)).rotation
            Rb = pose_se3(np.asarray(b["object_pose_xyzquat"], dtype=float)).rotation
            for f in range(hand.n_fingers):
                c = a["contacts"][f]
                if c is None or b["contacts"][f] is None:
                    continue
                rel = pin.log3((Rb.T @ Tb[f]) @ (Ra.T @ Ta[f]).T)
                _, n_out = obj.closest_point(np.asarray(c, dtype=float))
                slip[f] += r * float(np.linalg.norm(np.cross(rel, np.reshape(n_out, 3))))
        rows.append(slip)
    return np.array(rows).reshape(-1, hand.n_fingers)


def _tip_rotations(hand: Hand, q: Any) -> list[FloatArray]:
    """World rotation of each fingertip frame (it turns with its link) at ``q``."""
    pin.framesForwardKinematics(hand.model, hand.data, np.asarray(q, dtype=float))
    return [hand.data.oMf[fid].rotation.copy() for fid in hand.tip_frame_ids]


def _next_hold_times(t: FloatArray, holding: np.ndarray) -> FloatArray:
    """(m, n) the time each finger is next in contact in the plan (inf: never again)."""
    out = np.full(holding.shape, np.inf)
    nxt = np.full(holding.shape[1], np.inf)
    for k in range(t.size - 1, -1, -1):
        nxt = np.where(holding[k], t[k], nxt)
        out[k] = nxt
    return out
