"""Transfer and regrasp local planners (paper, section IV).

**Transfer**: contacts fixed in the object frame; the object follows a given
pose sequence (straight line in position, slerp in orientation between
samples); every finger follows by IK. A transfer moves the grasp rigidly, so
force closure and fingertip spacing are constant along it and are checked
where the grasp is made; joint limits (kept :attr:`TransitionSettings.joint_margin`
away: joint steps blow up near full extension) and link collisions are checked
at every waypoint. Waypoints are at most ``max_step_m`` / ``max_step_rad``
apart in object position, object rotation and every joint.

**Regrasp**: the object is still and the other n-1 fingers hold it (force
closure is required of every (n-1) subgrasp of a valid grasp, so they can). The
free finger lifts off along the surface normal (tilted if it must), moves in its
own joint space (straight line, then batched random via points, then OMPL's
RRTConnect in the finger's joint space, capped), and lands on
the new contact along the new normal. Lift and landing are interpolated in
task space so the fingertip leaves and meets the surface squarely.

**Landing choice** (:mod:`dexplan.planning.local.landings`, mixed into
:class:`Transitions`) decides whether finger gaits succeed (see MEASURED.md).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from dexplan.core.pose import interpolate_pose, quat_angle, quat_to_matrix
from dexplan.core.segments import Segment, Waypoint
from dexplan.core.typing import FloatArray, IntArray
from dexplan.model.collision import CollisionWorld
from dexplan.model.grasp import min_subgrasp_quality, min_subgrasp_quality_batch
from dexplan.model.grasp.grip import GripForceSolver
from dexplan.model.hand.hand import Hand
from dexplan.model.objects import Shape
from dexplan.planning.deadline import Deadline
from dexplan.planning.gsn.validity import ValiditySettings
from dexplan.planning.local.landings import Landings, Track
from dexplan.planning.ompl import plan_joint_path


@dataclass(frozen=True)
class TransitionSettings:
    """Resolution and search settings of the local planners.

    Attributes:
        max_step_m: largest object translation or fingertip move between
            waypoints (m); the plan verifier allows 1 cm.
        max_step_rad: largest object rotation or joint change between
            waypoints (rad); the verifier allows 0.05.
        joint_margin: transfers stop this far (rad) from joint limits.
        lift_height: fingertip clearance above the surface before moving (m).
        landing_candidates: surface points sampled when choosing a landing.
        landing_edges: edge points (normals inside the edge's cone) added to
            them on shapes with edges (boxes): held on two opposite faces, a
            finger gets onto a third face only by way of an edge.
        landing_reachable: of those, the ones the finger reaches now that
            are scored (the first ``landing_reachable``, in sampling order).
        via_points: random via points tried for a free-finger move.
        tip_clearance: minimum gap between fingertip spheres (m).
        follow_stride: pose stride when scoring how long a landing can be followed.
        transit_planner: OMPL planner for a free-finger move that neither the
            straight line nor a via point clears (None: no such fallback).
        transit_time: its time cap (s).
        transit_iterations: its iteration cap (the answer depends on the seed only
            when this cap, not the time, stops it).
        landing_solutions: IK solutions (nearest first) tried for a
            collision-free landing configuration when the nearest collides
            (redundant fingers have many: branches times the free-joint grid).
        posture_options: other postures of a redundant finger tried, one
            tracking step away, when a transfer step collides.
        landing_alignment: landings of a redundant finger need an IK solution
            whose last link is within ``acos(landing_alignment)`` of the
            inward normal (its side would touch the surface otherwise);
            None: no such filter. Non-redundant fingers are not filtered.
        tracked_landings: landing candidates (best IK-only follow scores
            first) whose follow is re-scored by tracking the finger along the
            rest of the motion with its links collision-checked against the
            palm, the object and the obstacles (:meth:`Transitions.track_score`);
            0: IK-only scores.
        tracked_landings_simple: ``tracked_landings`` for non-redundant
            fingers (one posture per IK branch): their IK-only score already
            follows the finger's own motion and misses only link collisions,
            so fewer are tracked (each costs a force-closure check and a track).
    """

    max_step_m: float = 0.008
    max_step_rad: float = 0.04
    joint_margin: float = 0.02
    lift_height: float = 0.008
    landing_candidates: int = 600
    landing_edges: int = 300
    via_points: int = 96
    tip_clearance: float = 0.004
    follow_stride: int = 2
    transit_planner: str | None = "RRTConnect"
    transit_time: float = 1.0
    transit_iterations: int = 200
    landing_solutions: int = 8
    posture_options: int = 6
    landing_alignment: float | None = 0.4
    tracked_landings: int = 16
    landing_reachable: int = 96
    tracked_landings_simple: int = 8


@dataclass(frozen=True)
class GraspContacts:
    """Contacts of all n fingers, object frame.

    Attributes:
        points: (n, 3) contact points on the object surface.
        normals_out: (n, 3) outward unit surface normals there.
    """

    points: FloatArray
    normals_out: FloatArray

    def replace(self, finger: int, point: FloatArray, normal_out: FloatArray) -> GraspContacts:
        """Copy with finger ``finger`` moved to a new contact."""
        p, n = self.points.copy(), self.normals_out.copy()
        p[finger], n[finger] = point, normal_out
        return GraspContacts(p, n)

    def as_tuple(self) -> tuple[FloatArray, ...]:
        """Contacts as a per-finger tuple (for waypoints)."""
        return tuple(self.points[i].copy() for i in range(len(self.points)))


@dataclass(frozen=True)
class TransferResult:
    """Outcome of :meth:`Transitions.transfer`.

    Attributes:
        waypoints: waypoints from the start pose to the last valid one.
        reached: index in the pose sequence of the last pose reached.
        blocking: finger that stopped the transfer (IK, joint limit or link
            collision), or None when the end was reached or the object collided.
        reason: why it stopped, or None when it reached the end.
    """

    waypoints: tuple[Waypoint, ...]
    reached: int
    blocking: int | None
    reason: str | None


def densify_poses(poses: FloatArray, max_step_m: float, max_step_rad: float) -> FloatArray:
    """Insert poses so consecutive ones differ by at most the given steps.

    Args:
        poses: (P, 7) object poses, XYZW.
        max_step_m: largest translation between consecutive poses (m).
        max_step_rad: largest rotation between consecutive poses (rad).

    Returns:
        (P', 7) poses, straight line in position and slerp in orientation
        between the given ones, the quaternions' signs continuous (each
        interpolation starts from the previous output, so a given pose whose
        quaternion has the other sign comes out negated, the same rotation).
    """
    out = [poses[0]]
    for b in poses[1:]:
        a = out[-1]
        d = float(np.linalg.norm(b[:3] - a[:3]))
        ang = quat_angle(a[3:], b[3:])
        k = max(1, math.ceil(max(d / max_step_m, ang / max_step_rad)))
        out.extend(interpolate_pose(a, b, j / k) for j in range(1, k + 1))
    return np.array(out)


class Transitions(Landings):
    """Transfer and regrasp local planners for one hand, object and world.

    Args:
        hand: the hand.
        obj: the object shape.
        world: collision world of hand, object and obstacles.
        validity: friction settings (force closure of landings).
        settings: resolution and search settings.
        rng: random generator for landing candidates and via points.
        deadline: when regrasps and landings give up (None: never); the
            planner shares its query deadline here.
        grip: the grip forces of the plan's export (the scenario's object
            mass and gravity): a finger is let go only where the others hold
            the object within the joints' effort limits (:meth:`can_release`);
            None: force closure alone decides.
    """

    def __init__(
        self,
        hand: Hand,
        obj: Shape,
        world: CollisionWorld,
        validity: ValiditySettings,
        settings: TransitionSettings,
        rng: np.random.Generator,
        deadline: Deadline | None = None,
        grip: GripForceSolver | None = None,
    ) -> None:
        self.hand = hand
        self.grip = grip
        self.deadline = deadline or Deadline()
        self.obj = obj
        self.world = world
        self.validity = validity
        self.settings = settings
        self.rng = rng
        self.all_contact = (True,) * hand.n_fingers
        self._lo = hand.lower + settings.joint_margin
        self._hi = hand.upper - settings.joint_margin
        self._finger_of_joint = np.zeros(hand.nq, dtype=np.int64)
        for i, idx in enumerate(hand.finger_q_index):
            self._finger_of_joint[idx] = i
        self.stats = {
            "transfers": 0,
            "regrasp_attempts": 0,
            "regrasps": 0,
            "landing_checks": 0,
            "weak_holds": 0,
            "backtracks": 0,
        }
        # per finger, its pairs as one geometry data each (checked in one C++ call):
        # the links alone (tracks, landings), and a free finger's moves
        n_f = range(hand.n_fingers)
        self._own_data = [world.pairs_data(world.finger_pairs(i)) for i in n_f]
        self._move_data = [world.pairs_data(world.free_finger_pairs(i)) for i in n_f]
        # landing postures found by track_score, keyed by (finger, fingertip centre)
        self._postures: dict[tuple[int, bytes], FloatArray] = {}
        # finger tracks by (finger, contact, joints of no finger): poses followed,
        # postures there, and whether the pose after the last one failed
        self._tracks: dict[tuple[int, bytes, bytes, bytes], Track] = {}
        fingers = np.concatenate([np.asarray(i, dtype=np.int64) for i in hand.finger_q_index])
        self._shared_q = np.setdiff1d(np.arange(hand.nq), fingers)
        self._pose_frames: dict[bytes, tuple[FloatArray, pin.SE3]] = {}
        n = hand.n_fingers
        self._free_masks = [tuple(j != i for j in range(n)) for i in range(n)]
        self._rest_q = [np.setdiff1d(np.arange(hand.nq), idx) for idx in hand.finger_q_index]

    def _moved_free(
        self, finger: int, q: FloatArray, ref: FloatArray, pose: FloatArray, mask: tuple[bool, ...]
    ) -> bool:
        """``world.is_free(q, pose, mask)`` when ``ref`` is a configuration it accepted.

        ``q`` must differ from ``ref`` in ``finger``'s joints only, with only
        ``finger`` free in ``mask``: every other pair, and the contact fingers'
        penetration, are then as they were at ``ref`` (free), so only the
        finger's own pairs (:meth:`CollisionWorld.free_finger_pairs`) are
        checked. The answer is the full check's; anything else gets the full
        check.
        """
        rest = self._rest_q[finger]
        if mask != self._free_masks[finger] or not np.array_equal(q[rest], ref[rest]):
            return self.world.is_free(q, pose, mask)
        return not self.world.pairs_collide(self._move_data[finger], q, self._frames(pose)[1])

    def _finger_free(self, finger: int, q: FloatArray, M_obj: pin.SE3) -> bool:
        """``finger``'s links at ``q: (nq,)`` clear of palm, object (pose ``M_obj``), obstacles."""
        return not self.world.pairs_collide(self._own_data[finger], q, M_obj)

    # ------------------------------------------------------------------ helpers
    def tip_targets(self, pose: FloatArray, grasp: GraspContacts) -> FloatArray:
        """World fingertip centres ``(n, 3)`` of a grasp at an object pose."""
        R = quat_to_matrix(pose[3:7] / np.linalg.norm(pose[3:7]))
        r = self.hand.fingertip_radius
        return (grasp.points + r * grasp.normals_out) @ R.T + pose[:3]

    def grasp_quality(self, grasp: GraspContacts, *, exact: bool = False) -> float:
        """Minimum force-closure quality over the grasp and its (n-1) subgrasps.

        With ``exact=False`` only certified bounds decide the margin (cheap,
        conservative: sampled landings are plentiful); ``exact=True`` solves
        the undecided cases (for given contacts, such as a GSn path's).
        """
        v = self.validity
        return float(
            min_subgrasp_quality(
                grasp.points,
                -grasp.normals_out,
                v.mu,
                torque_scale=self.obj.characteristic_length,
                solve=exact,
                **v.quality_args(),
            )
        )

    def landing_qualities(
        self, grasp: GraspContacts, finger: int, points: FloatArray, normals_out: FloatArray
    ) -> FloatArray:
        """:meth:`grasp_quality` (``exact=False``) of ``grasp`` with ``finger`` moved, per landing.

        Args:
            grasp: the current contacts.
            finger: the finger that moves.
            points: (C, 3) landing points, object frame.
            normals_out: (C, 3) outward unit normals there, object frame.

        Returns:
            (C,) the value :meth:`grasp_quality` gives ``grasp.replace(finger, p, n)``
            for each landing, all evaluated in one batch.
        """
        v = self.validity
        C = len(points)
        p = np.repeat(grasp.points[None], C, axis=0)
        n = np.repeat(-grasp.normals_out[None], C, axis=0)
        p[:, finger], n[:, finger] = points, -normals_out
        return min_subgrasp_quality_batch(
            p, n, v.mu, torque_scale=self.obj.characteristic_length, solve=False, **v.quality_args()
        )

    def _solve_all(self, pose: FloatArray, grasp: GraspContacts, q_prev: FloatArray):
        """IK of every finger at ``pose``: ``(q, blocking finger or None, reason)``."""
        targets = self.tip_targets(pose, grasp)
        R = quat_to_matrix(pose[3:7] / np.linalg.norm(pose[3:7]))
        inward = -grasp.normals_out @ R.T  # (n, 3) world frame
        q = q_prev.copy()
        for i in range(self.hand.n_fingers):
            idx = self.hand.finger_q_index[i]
            q_f = self.hand.finger_ik_fast(i, targets[i], q, inward[i])
            if q_f is None:
                return q, i, "ik"
            if np.any(q_f < self._lo[idx]) or np.any(q_f > self._hi[idx]):
                return q, i, "joint_limit"
            q[idx] = q_f
        return q, None, None

    def _collision_finger(self, q: FloatArray, pose: FloatArray, mask) -> tuple[bool, int | None]:
        """(collision-free, finger involved in the first collision or None)."""
        rep = self.world.check(q, pose, mask)
        if rep.free:
            return True, None
        if rep.pair is None:  # contact penetration: blame nobody in particular
            return False, None
        fingers = [self.world.finger_of(n) for n in rep.pair]
        fingers = [f for f in fingers if f is not None]
        return False, (fingers[0] if fingers else None)

    # ----------------------------------------------------------------- transfer
    def transfer(
        self, poses: FloatArray, start: int, q_start: FloatArray, grasp: GraspContacts
    ) -> TransferResult:
        """Follow ``poses[start:]`` with a fixed grasp for as long as it stays valid.

        Args:
            poses: (P, 7) dense object trajectory (see :func:`densify_poses`).
            start: index of the current pose in ``poses``.
            q_start: (nq,) hand configuration at ``poses[start]``.
            grasp: contacts held during the transfer.

        Returns:
            A :class:`TransferResult`; its waypoints start at ``poses[start]``.
        """
        self.stats["transfers"] += 1
        contacts = grasp.as_tuple()
        wps = [Waypoint(poses[start].copy(), q_start.copy(), contacts)]
        q = q_start
        for j in range(start + 1, len(poses)):
            if self.world.object_collides(poses[j]):
                return TransferResult(tuple(wps), j - 1, None, "object_collision")
            steps = self._advance(poses[j - 1], poses[j], q, grasp, depth=0)
            if isinstance(steps, tuple):
                return TransferResult(tuple(wps), j - 1, steps[0], steps[1])
            for pose_k, q_k in steps:
                wps.append(Waypoint(pose_k, q_k, contacts))
            q = steps[-1][1]
        return TransferResult(tuple(wps), len(poses) - 1, None, None)

    def _advance(self, pa, pb, q_a, grasp, depth):
        """Waypoints from pose ``pa`` (at ``q_a``) to ``pb``, subdividing big joint steps.

        Returns a list of (pose, q) ending at ``pb``, or (blocking finger, reason).
        """
        q_b, blocking, reason = self._solve_all(pb, grasp, q_a)
        if blocking is not None:
            return (blocking, reason)
        if np.max(np.abs(q_b - q_a)) > self.settings.max_step_rad:
            if depth >= 4:
                return (int(self._finger_of_joint[np.argmax(np.abs(q_b - q_a))]), "joint_jump")
            mid = interpolate_pose(pa, pb, 0.5)
            first = self._advance(pa, mid, q_a, grasp, depth + 1)
            if isinstance(first, tuple):
                return first
            second = self._advance(mid, pb, first[-1][1], grasp, depth + 1)
            if isinstance(second, tuple):
                return second
            return first + second
        free, finger = self._collision_finger(q_b, pb, self.all_contact)
        if not free and finger is not None:
            q_alt = self._other_posture(finger, pb, q_a, q_b, grasp)
            if q_alt is not None:
                q_b, free = q_alt, True
        if not free:
            return (finger, "collision")
        return [(pb.copy(), q_b)]

    def _other_posture(
        self, finger: int, pose: FloatArray, q_a: FloatArray, q_b: FloatArray, grasp: GraspContacts
    ) -> FloatArray | None:
        """``q_b`` with ``finger`` in another collision-free posture one step from ``q_a``.

        Redundant fingers reach a contact in many postures; when the one
        chosen collides, the others within a tracking step are tried (best
        aligned with the surface normal first). None when none is free.
        """
        hand = self.hand
        idx = hand.finger_q_index[finger]
        R = quat_to_matrix(pose[3:7] / np.linalg.norm(pose[3:7]))
        tip = self.tip_targets(pose, grasp)[finger]
        inward = -(R @ grasp.normals_out[finger])
        options = hand.finger_ik_alternatives(finger, tip, q_a, inward)
        lo, hi = self._lo[idx], self._hi[idx]
        others = (
            q_f
            for q_f in options[: self.settings.posture_options]
            if not (np.any(q_f < lo) or np.any(q_f > hi) or np.array_equal(q_f, q_b[idx]))
        )
        return self._first_free(q_b, idx, others, pose)

    def _first_free(
        self, q: FloatArray, idx: IntArray, postures: Iterable[FloatArray], pose: FloatArray
    ) -> FloatArray | None:
        """``q`` with the finger joints ``idx`` set to the first collision-free posture, or None.

        Args:
            q: (nq,) the hand's joints.
            idx: the finger's joint indexes.
            postures: candidate finger joint values (len(idx),), tried in order.
            pose: (7,) the object pose, world frame.
        """
        for q_f in postures:
            q1 = q.copy()
            q1[idx] = q_f
            if self.world.is_free(q1, pose, self.all_contact):
                return q1
        return None

    # ------------------------------------------------------------------ regrasp
    def can_release(
        self, finger: int, pose: FloatArray, q: FloatArray, grasp: GraspContacts
    ) -> bool:
        """Whether the other fingers hold the object while ``finger`` is lifted.

        Every (n-1)-subgrasp is force closure, so some forces always balance
        the object's weight; the joints must also produce them. On
        paper_sphere seed 6 a 3-finger hold needed 3.6 N m on a joint limited
        to 1 N m, and the plan could not be exported. Counted in
        ``stats["weak_holds"]``.

        Args:
            finger: the finger to let go.
            pose: (7,) object pose, world frame.
            q: (nq,) the configuration the regrasp starts from.
            grasp: the current contacts, object frame.
        """
        if self.grip is None:
            return True
        contacts = [None if i == finger else grasp.points[i] for i in range(self.hand.n_fingers)]
        if self.grip.holds(q, pose, contacts):
            return True
        self.stats["weak_holds"] += 1
        return False

    def regrasp(
        self,
        pose: FloatArray,
        q: FloatArray,
        grasp: GraspContacts,
        finger: int,
        new_point: FloatArray,
        new_normal_out: FloatArray,
    ) -> Segment | None:
        """Plan a regrasp of ``finger`` to a new contact; None when no motion is found.

        The waypoints: lift along the (possibly tilted) normal, a free move in
        the finger's joint space, landing along the new normal. None at once
        when the other fingers cannot hold the object (:meth:`can_release`).
        """
        if self.deadline.expired() or not self.can_release(finger, pose, q, grasp):
            return None
        self.stats["regrasp_attempts"] += 1
        hand = self.hand
        new_grasp = grasp.replace(finger, new_point, new_normal_out)
        R = quat_to_matrix(pose[3:7] / np.linalg.norm(pose[3:7]))
        free_mask = tuple(i != finger for i in range(hand.n_fingers))

        tip_now = self.tip_targets(pose, grasp)[finger]
        n_now = R @ grasp.normals_out[finger]
        tip_new = self.tip_targets(pose, new_grasp)[finger]
        n_new = R @ new_normal_out

        lift = self._straight_tip_move(finger, q, tip_now, n_now, pose, free_mask)
        if lift is None:
            return None
        q_touch = self._landing_configuration(finger, q, tip_new, pose, new_point)
        if q_touch is None:
            return None
        land = self._straight_tip_move(finger, q_touch, tip_new, n_new, pose, free_mask)
        if land is None:
            return None
        land = land[::-1]  # approach: from above the new contact down onto it
        # the landing configuration must be a valid full grasp
        q_land = land[-1]
        if not self.world.check(q_land, pose, self.all_contact).free:
            return None
        transit = self._joint_move(finger, lift[-1], land[0], pose, free_mask)
        if transit is None:
            return None
        qs = lift + transit[1:] + land[1:]
        qs[0] = q.copy()  # exactly where the previous segment ended
        old_c, new_c = grasp.as_tuple(), new_grasp.as_tuple()
        free_c = tuple(None if i == finger else old_c[i] for i in range(hand.n_fingers))
        wps = [Waypoint(pose.copy(), qs[0], old_c)]
        wps += [Waypoint(pose.copy(), qk, free_c) for qk in qs[1:-1]]
        wps.append(Waypoint(pose.copy(), qs[-1], new_c))
        self.stats["regrasps"] += 1
        return Segment("regrasp", finger, tuple(wps))

    def _landing_configuration(
        self,
        finger: int,
        q: FloatArray,
        tip: FloatArray,
        pose: FloatArray,
        point: FloatArray | None = None,
    ) -> FloatArray | None:
        """Hand configuration with ``finger`` touching at fingertip centre ``tip: (3,)``.

        The IK solution nearest ``q: (nq,)`` when the grasp it makes is
        collision-free; otherwise (a redundant finger, or another branch) the
        nearest of the other IK solutions that is, within the joint margin.
        """
        hand = self.hand
        idx = hand.finger_q_index[finger]
        tried: list[FloatArray] = []
        cached = None if point is None else self._postures.get((finger, point.tobytes()))
        if cached is not None:
            q1 = q.copy()
            q1[idx] = cached
            if self.world.is_free(q1, pose, self.all_contact):
                return q1
            tried.append(cached)
        q_f = hand.finger_ik_fast(finger, tip, q)
        if q_f is not None:
            q1 = q.copy()
            q1[idx] = q_f
            if self.world.is_free(q1, pose, self.all_contact):
                return q1
            tried.append(q_f)
        cands, ok = hand.finger_ik_candidates(finger, tip[None])
        cands, ok = cands[0], ok[0]
        ok &= np.all((cands >= self._lo[idx]) & (cands <= self._hi[idx]), axis=1)
        opts = np.flatnonzero(ok)
        opts = opts[np.argsort(np.linalg.norm(cands[opts] - q[idx], axis=1), kind="stable")]
        untried = (
            cands[k]
            for k in opts[: self.settings.landing_solutions]
            if not any(np.array_equal(cands[k], t) for t in tried)
        )
        return self._first_free(q, idx, untried, pose)

    def _straight_tip_move(
        self,
        finger: int,
        q: FloatArray,
        tip: FloatArray,
        normal: FloatArray,
        pose: FloatArray,
        free_mask: tuple[bool, ...],
    ) -> list[FloatArray] | None:
        """Configurations moving the tip from ``tip`` off the surface by ``lift_height``.

        The direction is the outward normal, or that normal tilted up to 60
        degrees when the finger cannot move straight out. The first entry is
        the configuration at ``tip`` (on the surface).
        """
        hand, s = self.hand, self.settings
        idx = hand.finger_q_index[finger]
        q_f = hand.finger_ik_fast(finger, tip, q)
        if q_f is None:
            return None
        q0 = q.copy()
        q0[idx] = q_f
        n_steps = max(2, math.ceil(s.lift_height / s.max_step_m))
        for direction in self._lift_directions(normal):
            qs = [q0]
            ok = True
            for k in range(1, n_steps + 1):
                target = tip + direction * (s.lift_height * k / n_steps)
                q_f = hand.finger_ik_fast(finger, target, qs[-1])
                if q_f is None:
                    ok = False
                    break
                qk = qs[-1].copy()
                qk[idx] = q_f
                sub = self._subdivide(qs[-1], qk)
                if sub is None or not all(
                    self.world.is_free(qi, pose, free_mask) for qi in sub[1:]
                ):
                    ok = False
                    break
                qs.extend(sub[1:])
            if ok:
                return qs
        return None

    def _lift_directions(self, normal: FloatArray) -> list[FloatArray]:
        """The normal, then normals tilted by 30 and 60 degrees in 6 azimuths."""
        n = normal / np.linalg.norm(normal)
        a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        t1 = np.cross(n, a)
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(n, t1)
        dirs = [n]
        for tilt in (math.radians(30), math.radians(60)):
            for k in range(6):
                phi = 2 * math.pi * k / 6
                d = math.cos(tilt) * n + math.sin(tilt) * (math.cos(phi) * t1 + math.sin(phi) * t2)
                dirs.append(d)
        return dirs

    def _subdivide(self, qa: FloatArray, qb: FloatArray) -> list[FloatArray] | None:
        """Joint-space straight line from qa to qb in steps <= max_step_rad (incl. ends)."""
        d = float(np.max(np.abs(qb - qa)))
        k = max(1, math.ceil(d / self.settings.max_step_rad))
        if k > 200:
            return None
        return [qa + (qb - qa) * (j / k) for j in range(k + 1)]

    def _segment_free(self, finger, qa, qb, pose, free_mask) -> list[FloatArray] | None:
        """Joint-space line qa -> qb of ``finger`` (qa collision-free), checked; None if blocked."""
        sub = self._subdivide(qa, qb)
        if sub is None:
            return None
        for qi in sub[1:]:
            if not self._moved_free(finger, qi, qa, pose, free_mask):
                return None
        return sub

    def _joint_move(
        self,
        finger: int,
        qa: FloatArray,
        qb: FloatArray,
        pose: FloatArray,
        free_mask: tuple[bool, ...],
    ) -> list[FloatArray] | None:
        """Collision-free joint-space move of one finger: straight, via points, else OMPL."""
        direct = self._segment_free(finger, qa, qb, pose, free_mask)
        if direct is not None:
            return direct
        hand = self.hand
        idx = hand.finger_q_index[finger]
        vias = self.rng.uniform(
            hand.lower[idx], hand.upper[idx], size=(self.settings.via_points, len(idx))
        )
        # shortest detours first
        cost = np.linalg.norm(vias - qa[idx], axis=1) + np.linalg.norm(vias - qb[idx], axis=1)
        for k in np.argsort(cost):
            qv = qa.copy()
            qv[idx] = vias[k]
            if not self._moved_free(finger, qv, qa, pose, free_mask):
                continue
            first = self._segment_free(finger, qa, qv, pose, free_mask)
            if first is None:
                continue
            second = self._segment_free(finger, qv, qb, pose, free_mask)
            if second is None:
                continue
            return first + second[1:]
        return self._planned_move(finger, qa, qb, pose, free_mask)

    def _planned_move(
        self,
        finger: int,
        qa: FloatArray,
        qb: FloatArray,
        pose: FloatArray,
        free_mask: tuple[bool, ...],
    ) -> list[FloatArray] | None:
        """The capped fallback: an OMPL planner in the finger's joint space."""
        s = self.settings
        if s.transit_planner is None:
            return None
        self.stats["transit_planned"] = self.stats.get("transit_planned", 0) + 1
        idx = self.hand.finger_q_index[finger]

        def free(q_f: FloatArray) -> bool:
            q = qa.copy()
            q[idx] = q_f
            return self._moved_free(finger, q, qa, pose, free_mask)

        via = plan_joint_path(
            qa[idx],
            qb[idx],
            self.hand.lower[idx],
            self.hand.upper[idx],
            free,
            resolution=s.max_step_rad,
            time_limit=max(1e-3, min(s.transit_time, self.deadline.remaining())),
            max_iterations=s.transit_iterations,
            seed=int(self.rng.integers(2**31 - 1)),
            planner=s.transit_planner,
        )
        if via is None:
            return None
        qs = [qa.copy()]
        for q_f in via[1:]:
            q = qa.copy()
            q[idx] = q_f
            leg = self._segment_free(finger, qs[-1], q, pose, free_mask)  # at our resolution
            if leg is None:
                return None
            qs.extend(leg[1:])
        qs[-1] = qb.copy()
        self.stats["transit_planned_found"] = self.stats.get("transit_planned_found", 0) + 1
        return qs
