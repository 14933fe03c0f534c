"""The regrasp local planner (paper, section IV).

The object is still and the other n-1 fingers hold it (force closure is
required of every (n-1) subgrasp of a valid grasp, so they can). The free
finger lifts off along the surface normal (tilted if it must), moves in its
own joint space (straight line, then batched random via points, then OMPL's
RRTConnect in the finger's joint space, capped), and lands on the new contact
along the new normal. Lift and landing are interpolated in task space so the
fingertip leaves and meets the surface squarely.
"""

from __future__ import annotations

import math

import numpy as np

from dexplan.core.pose import quat_to_matrix
from dexplan.core.segments import Segment, SegmentKind, Waypoint
from dexplan.core.typing import FloatArray
from dexplan.model.grasp.holds import HoldChecker
from dexplan.model.hand.hand import Hand
from dexplan.planning.deadline import Deadline
from dexplan.planning.gsn.contact_curve import low_dof
from dexplan.planning.local.transitions.checks import FingerChecks
from dexplan.planning.local.transitions.contacts import GraspContacts
from dexplan.planning.local.transitions.counts import LocalCounts
from dexplan.planning.local.transitions.settings import TransitionSettings
from dexplan.planning.ompl import plan_joint_path

#: Joint-space steps beyond which a straight finger move is not tried.
_MAX_SUBSTEPS = 200
#: Release verdicts kept (:meth:`RegraspPlanner.can_release`) before the cache starts over.
_RELEASE_CACHE = 4096
#: A low-DOF finger's lift direction, within its reach, must leave the surface
#: at least this steeply (cosine with the outward normal).
_MIN_LIFT_COS = 0.2


class RegraspPlanner:
    """Regrasps: one finger lifted, moved and landed while the others hold the object.

    Args:
        hand: the hand.
        settings: the local planners' settings.
        checks: the per-finger collision checks and joint bounds.
        landing_postures: landing postures found by the landing search,
            keyed by (finger, contact point bytes), tried first.
        rng: random generator for via points and the OMPL seed.
        deadline: when regrasps give up.
        holds: the hold check (the object's weight, the joints' effort
            limits, the contact shift): a finger is let go only where the
            others hold the object (:meth:`can_release`); None: force closure
            alone decides.
        stats: the local planners' counters.
    """

    def __init__(
        self,
        hand: Hand,
        settings: TransitionSettings,
        checks: FingerChecks,
        landing_postures: dict[tuple[int, bytes], FloatArray],
        rng: np.random.Generator,
        deadline: Deadline,
        holds: HoldChecker | None,
        stats: LocalCounts,
    ) -> None:
        self.hand = hand
        self.settings = settings
        self.checks = checks
        self.landing_postures = landing_postures
        self.rng = rng
        self.deadline = deadline
        self.holds = holds
        self.stats = stats
        self._released: dict[tuple[int, bytes, bytes, bytes], bool] = {}

    def can_release(
        self, finger: int, pose: FloatArray, q: FloatArray, grasp: GraspContacts
    ) -> bool:
        """Whether the other fingers hold the object while ``finger`` is lifted.

        Every (n-1)-subgrasp is force closure, so some forces always balance
        the object's weight; the joints must also produce them within their
        effort limits, with each contact moved the hold shift along the
        surface (:mod:`dexplan.model.grasp.holds`): an (n-1) hold can need
        several times a joint's effort limit, and a plan with it would drop
        the object. Counted in ``stats["weak_holds"]``.

        Args:
            finger: the finger to let go.
            pose: (7,) object pose, world frame.
            q: (nq,) the configuration the regrasp starts from.
            grasp: the current contacts, object frame.
        """
        if self.holds is None:
            return True
        # the gait search asks the same question where a transfer stops, where
        # it regrasps there and where it plans that regrasp: each hold is a
        # handful of linear programmes
        others = np.delete(grasp.points, finger, axis=0)
        key = (finger, pose.tobytes(), q.tobytes(), others.tobytes())
        known = self._released.get(key)
        if known is None:
            contacts = [
                None if i == finger else grasp.points[i] for i in range(self.hand.n_fingers)
            ]
            known = self.holds.holds(q, pose, contacts)
            if len(self._released) >= _RELEASE_CACHE:
                self._released.clear()
            self._released[key] = known
        if not known:
            self.stats["weak_holds"] += 1
        return known

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

        tip_now = grasp.tip_centres(pose, self.hand.fingertip_radius)[finger]
        n_now = R @ grasp.normals_out[finger]
        tip_new = new_grasp.tip_centres(pose, self.hand.fingertip_radius)[finger]
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
        if not self.checks.world.check(q_land, pose, self.checks.all_contact).free:
            return None
        transit = self.joint_move(finger, lift[-1], land[0], pose, free_mask)
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
        return Segment(SegmentKind.REGRASP, finger, tuple(wps))

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
        cached = None if point is None else self.landing_postures.get((finger, point.tobytes()))
        if cached is not None:
            q1 = q.copy()
            q1[idx] = cached
            if self.checks.world.is_free(q1, pose, self.checks.all_contact):
                return q1
            tried.append(cached)
        q_f = hand.finger_ik_fast(finger, tip, q)
        if q_f is not None:
            q1 = q.copy()
            q1[idx] = q_f
            if self.checks.world.is_free(q1, pose, self.checks.all_contact):
                return q1
            tried.append(q_f)
        cands, ok = hand.finger_ik_candidates(finger, tip[None])
        cands, ok = cands[0], ok[0]
        ok &= np.all((cands >= self.checks.lo[idx]) & (cands <= self.checks.hi[idx]), axis=1)
        opts = np.flatnonzero(ok)
        opts = opts[np.argsort(np.linalg.norm(cands[opts] - q[idx], axis=1), kind="stable")]
        untried = (
            cands[k]
            for k in opts[: self.settings.landing_solutions]
            if not any(np.array_equal(cands[k], t) for t in tried)
        )
        return self.checks.first_free(q, idx, untried, pose)

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
        degrees when the finger cannot move straight out; for a finger of
        fewer than 3 joints, those directions within its reach
        (:meth:`_reachable_directions`). The first entry is the configuration
        at ``tip`` (on the surface).
        """
        hand, s = self.hand, self.settings
        idx = hand.finger_q_index[finger]
        q_f = hand.finger_ik_fast(finger, tip, q)
        if q_f is None:
            return None
        q0 = q.copy()
        q0[idx] = q_f
        n_steps = max(2, math.ceil(s.lift_height / s.max_step_m))
        directions = self._lift_directions(normal)
        if low_dof(hand, finger):
            directions = self._reachable_directions(finger, q0, normal, directions)
        for direction in directions:
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
                    self.checks.world.is_free(qi, pose, free_mask) for qi in sub[1:]
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

    def _reachable_directions(
        self, finger: int, q: FloatArray, normal: FloatArray, directions: list[FloatArray]
    ) -> list[FloatArray]:
        """``directions`` projected onto where a finger of fewer than 3 joints can move its tip.

        Such a fingertip moves on a surface (a plane for parallel joints): a
        straight move along the normal, which leaves it, is not reachable.
        Each direction is projected onto the span of the finger's Jacobian at
        ``q: (nq,)`` and kept, normalised, when it still leaves the surface
        (cosine with ``normal`` at least :data:`_MIN_LIFT_COS`); duplicates dropped.
        """
        J = self.hand.fingertip_jacobians(q)[1][finger]
        P = J @ np.linalg.pinv(J)
        out: list[FloatArray] = []
        n = normal / np.linalg.norm(normal)
        for d in directions:
            v = P @ d
            norm = float(np.linalg.norm(v))
            if norm < 1e-6 or float(v @ n) < _MIN_LIFT_COS * norm:
                continue
            v = v / norm
            if all(float(v @ w) < 1.0 - 1e-9 for w in out):
                out.append(v)
        return out

    def _subdivide(self, qa: FloatArray, qb: FloatArray) -> list[FloatArray] | None:
        """Joint-space straight line from qa to qb in steps <= max_step_rad (incl. ends)."""
        d = float(np.max(np.abs(qb - qa)))
        k = max(1, math.ceil(d / self.settings.max_step_rad))
        if k > _MAX_SUBSTEPS:
            return None
        return [qa + (qb - qa) * (j / k) for j in range(k + 1)]

    def segment_free(self, finger, qa, qb, pose, free_mask) -> list[FloatArray] | None:
        """Joint-space line qa -> qb of ``finger`` (qa collision-free), checked; None if blocked."""
        sub = self._subdivide(qa, qb)
        if sub is None:
            return None
        for qi in sub[1:]:
            if not self.checks.moved_free(finger, qi, qa, pose, free_mask):
                return None
        return sub

    def joint_move(
        self,
        finger: int,
        qa: FloatArray,
        qb: FloatArray,
        pose: FloatArray,
        free_mask: tuple[bool, ...],
    ) -> list[FloatArray] | None:
        """Collision-free joint-space move of one finger: straight, via points, else OMPL."""
        direct = self.segment_free(finger, qa, qb, pose, free_mask)
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
            if not self.checks.moved_free(finger, qv, qa, pose, free_mask):
                continue
            first = self.segment_free(finger, qa, qv, pose, free_mask)
            if first is None:
                continue
            second = self.segment_free(finger, qv, qb, pose, free_mask)
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
            return self.checks.moved_free(finger, q, qa, pose, free_mask)

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
            leg = self.segment_free(finger, qs[-1], q, pose, free_mask)  # at our resolution
            if leg is None:
                return None
            qs.extend(leg[1:])
        qs[-1] = qb.copy()
        self.stats["transit_planned_found"] = self.stats.get("transit_planned_found", 0) + 1
        return qs
