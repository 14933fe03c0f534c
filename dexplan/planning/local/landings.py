"""Landing choice for regrasps: where a finger lands, and how long it can follow from there.

Whether finger gaits succeed is decided here (MEASURED.md): among sampled
contacts (surface points and, on a box, edge points whose normals lie between
the two faces': held on two opposite faces, a finger reaches a third face only
by way of an edge) that the finger reaches, that keep the fingertips apart and every
(n-1) subgrasp force closure, the planner picks the one from which the finger
can follow the rest of the object motion longest, its links checked against
the palm, the object and obstacles (a :class:`Track` of the finger, resumed
when a later query starts where it left off).

:class:`Landings` is the part of :class:`~dexplan.planning.local.transitions.Transitions`
that scores and yields landings; it uses the transfer machinery of that class
(IK, collision checks, grasp quality), which it is mixed into.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from dexplan.core.pose import quat_to_matrix
from dexplan.core.typing import FloatArray
from dexplan.model.collision import pose_to_se3
from dexplan.model.grasp.halfspace import cannot_be_force_closure
from dexplan.model.hand.ik import nearest_branch, planar_branches

if TYPE_CHECKING:
    from dexplan.planning.local.transitions import GraspContacts


#: Poses whose closed-form IK branches a track solves at once.
_TRACK_BATCH = 16
#: Landing candidates whose reachability is solved at a time.
_REACH_CHUNK = 192
#: Poses (after the follow stride) scored at a time by ``follow_scores``.
_FOLLOW_CHUNK = 4
#: Ranked landing candidates whose force closure is evaluated in one batch.
_FC_CHUNK = 8


@dataclass
class Track:
    """A finger tracked along object poses (:meth:`Landings.track_score`).

    ``poses: (K, 7)`` the poses followed, ``qs: (K, m)`` the finger's joint
    values there, ``stopped``: the pose after the last one could not be
    followed (False: tracking stopped at a limit and can be resumed),
    ``stopped_at`` that pose.
    """

    poses: FloatArray
    qs: FloatArray
    stopped_at: FloatArray | None = None

    @property
    def stopped(self) -> bool:
        """True when the pose after the last one could not be followed."""
        return self.stopped_at is not None

    def resume_at(self, poses: FloatArray, q_finger: FloatArray) -> int | None:
        """Index of ``poses[0]`` in the track when it continues as ``poses`` from ``q_finger``.

        None unless the track holds ``poses[0]`` with exactly ``q_finger``
        there, the poses it holds from there are ``poses``' first ones and
        the pose it failed at (if any, and if ``poses`` goes that far) is
        ``poses``' next: a fresh track from there would then repeat this one
        step for step.
        """
        for k in np.flatnonzero(np.all(self.poses == poses[0], axis=1)):
            rest = self.poses[k:]
            m = min(len(rest), len(poses))
            if not (np.array_equal(self.qs[k], q_finger) and np.array_equal(rest[:m], poses[:m])):
                continue
            fails_next = m == len(rest) and m < len(poses) and self.stopped_at is not None
            if fails_next and not np.array_equal(self.stopped_at, poses[m]):
                continue
            return int(k)
        return None

    def extend(
        self, poses: FloatArray, qs: list[FloatArray], stopped_at: FloatArray | None
    ) -> None:
        """Append postures followed over ``poses``; ``stopped_at``: the pose that failed next."""
        if qs:
            self.poses = np.vstack([self.poses, poses])
            self.qs = np.vstack([self.qs, np.asarray(qs)])
        self.stopped_at = None if stopped_at is None else stopped_at.copy()


class Landings:
    """Scoring and choice of landing contacts (mixed into ``Transitions``)."""

    def follow_scores(
        self,
        finger: int,
        candidates_tip_obj: FloatArray,
        future_poses: FloatArray,
        normals_obj: FloatArray | None = None,
    ) -> FloatArray:
        """How many consecutive future poses the finger can follow from each candidate.

        Args:
            finger: the finger to regrasp.
            candidates_tip_obj: (C, 3) fingertip centres (contact + r * normal), object frame.
            future_poses: (P, 7) the rest of the object trajectory (first = now).
            normals_obj: (C, 3) outward normals at the candidates (object
                frame). With them, and ``landing_alignment`` set, a redundant
                finger must also be able to point its last link within
                ``acos(landing_alignment)`` of the inward normal at each pose
                (bounded by how far the normal leaves the finger's flexion plane).

        Returns:
            (C,) counts of consecutive poses, from the first, where the finger's
            IK succeeds with the joint margin.
        """
        stride = max(1, self.settings.follow_stride)
        poses = future_poses[::stride]
        C = len(candidates_tip_obj)
        follow = np.zeros(C, dtype=np.int64)
        alive = np.arange(C)
        # a few poses at a time, for the candidates still followed: most stop
        # within the first poses, and the IK of a redundant finger is costly
        for lo in range(0, len(poses), _FOLLOW_CHUNK):
            chunk = poses[lo : lo + _FOLLOW_CHUNK]
            ok = self._follow_chunk(
                finger,
                candidates_tip_obj[alive],
                chunk,
                None if normals_obj is None else normals_obj[alive],
            )
            run = np.cumprod(ok, axis=0).sum(axis=0)
            follow[alive] += run
            alive = alive[run == len(chunk)]
            if not len(alive):
                break
        return follow * stride

    def _follow_chunk(
        self,
        finger: int,
        tips_obj: FloatArray,
        poses: FloatArray,
        normals_obj: FloatArray | None,
    ) -> np.ndarray:
        """(P, C) where the finger reaches fingertip centres ``tips_obj: (C, 3)`` at ``poses``.

        Reached: IK within the joint margin and, for a redundant finger with
        ``normals_obj: (C, 3)`` given, the alignment bound of :meth:`follow_scores`.
        """
        C, P = len(tips_obj), len(poses)
        Rs = [self._frames(pose)[0] for pose in poses]
        targets = np.stack([tips_obj @ R.T + pose[:3] for R, pose in zip(Rs, poses, strict=True)])
        q, ok = self._ik_in_margin(finger, targets.reshape(-1, 3))
        split = self.hand._split_ik[finger]
        limit = self.settings.landing_alignment
        if normals_obj is not None and split is not None and limit is not None and ok.any():
            inward = np.stack([-normals_obj @ R.T for R in Rs]).reshape(-1, 3)
            rows = np.flatnonzero(ok)
            axes = split.directions(q[rows])[1]  # flexion-plane normals
            off = np.einsum("ij,ij->i", axes, inward[rows])
            ok[rows] = np.sqrt(np.maximum(0.0, 1.0 - off * off)) >= limit
        return ok.reshape(P, C)

    def track_score(
        self,
        finger: int,
        q: FloatArray,
        tip_obj: FloatArray,
        normal_obj: FloatArray,
        future_poses: FloatArray,
        limit: int,
    ) -> tuple[int, FloatArray | None]:
        """How many consecutive future poses the finger follows from a contact, links checked.

        The finger lands at ``future_poses[0]`` in its collision-free posture
        whose last link points most into the surface (or, when ``q`` already
        touches there, in ``q``'s own posture), then follows the contact as a
        transfer does (tracking IK with the inward normal, other postures one
        step away when one collides), its links checked against the palm, the
        object and the obstacles (not the other fingers, which move too).

        Args:
            finger: the finger.
            q: (nq,) current hand configuration.
            tip_obj: (3,) fingertip centre (contact + r * normal), object frame.
            normal_obj: (3,) outward normal there, object frame.
            future_poses: (P, 7) the rest of the object trajectory (first = now).
            limit: stop counting after this many poses.

        Returns:
            ``(count, q_finger)``: poses followed from the first (0: the
            finger cannot touch there collision-free) and the landing posture.
        """
        hand = self.hand
        idx = hand.finger_q_index[finger]
        n = min(limit, len(future_poses))
        if n <= 0:
            return 0, None
        key = (finger, tip_obj.tobytes(), normal_obj.tobytes(), q[self._shared_q].tobytes())
        track = self._tracks.get(key)
        start = None if track is None else track.resume_at(future_poses, q[idx])
        if start is not None and not self._touches(finger, q, tip_obj, future_poses[0]):
            start = None  # the fresh track would land in another posture
        if start is None:
            target = self._target(tip_obj, normal_obj, future_poses[0])
            q_f = self._landing_posture(finger, q, *target)
            if q_f is None:
                return 0, None
            if len(self._tracks) >= 512:
                self._tracks.clear()
            track = self._tracks[key] = Track(future_poses[:1].copy(), q_f[None].copy())
            start = 0
        assert track is not None
        # the stored track, extended while this call needs more than it holds
        have = len(track.poses) - start
        if have < n and not track.stopped:
            extra, stopped = self._track_on(
                finger, q, track.qs[-1], tip_obj, normal_obj, future_poses[have:n]
            )
            end = have + len(extra)
            track.extend(future_poses[have:end], extra, future_poses[end] if stopped else None)
            have = len(track.poses) - start
        return min(have, n), track.qs[start].copy()

    def _target(
        self, tip_obj: FloatArray, normal_obj: FloatArray, pose: FloatArray
    ) -> tuple[FloatArray, FloatArray, pin.SE3]:
        """World fingertip centre, inward normal and object SE3 of a contact at ``pose``."""
        R, M = self._frames(pose)
        return R @ tip_obj + pose[:3], -(R @ normal_obj), M

    def _frames(self, pose: FloatArray) -> tuple[FloatArray, pin.SE3]:
        """Rotation matrix and SE3 of an object pose, cached (tracks revisit the poses)."""
        key = pose.tobytes()
        out = self._pose_frames.get(key)
        if out is None:
            if len(self._pose_frames) >= 4096:
                self._pose_frames.clear()
            R = quat_to_matrix(pose[3:7] / np.linalg.norm(pose[3:7]))
            out = self._pose_frames[key] = (R, pose_to_se3(pose))
        return out

    def _touches(self, finger: int, q: FloatArray, tip_obj: FloatArray, pose: FloatArray) -> bool:
        """``q``'s fingertip centre is at ``tip_obj`` (object frame) at ``pose`` (1e-6 m)."""
        tip = self._frames(pose)[0] @ tip_obj + pose[:3]
        return bool(np.linalg.norm(self.hand.fingertip_positions(q)[finger] - tip) < 1e-6)

    def _track_on(
        self,
        finger: int,
        q: FloatArray,
        q_prev: FloatArray,
        tip_obj: FloatArray,
        normal_obj: FloatArray,
        poses: FloatArray,
    ) -> tuple[list[FloatArray], bool]:
        """Postures of ``finger`` following a contact over ``poses`` from ``q_prev``.

        Returns the postures found, one per pose from the first, and True when
        the finger could not follow the pose after the last one (False: all
        were followed).
        """
        hand = self.hand
        idx = hand.finger_q_index[finger]
        lo, hi = self._lo[idx], self._hi[idx]
        qh = q.copy()
        qh[idx] = q_prev
        out: list[FloatArray] = []
        analytic = hand._analytic_ik[finger]
        branches = None
        for j, pose in enumerate(poses):
            tip, inward, M = self._target(tip_obj, normal_obj, pose)
            if analytic is not None:
                # the closed-form solver's nearest branch, its branches solved
                # in batches of poses (same solutions, fewer Python steps)
                if j % _TRACK_BATCH == 0:
                    chunk = poses[j : j + _TRACK_BATCH]
                    tips = np.array([self._target(tip_obj, normal_obj, p)[0] for p in chunk])
                    branches = planar_branches(analytic, tips)
                assert branches is not None
                k = j % _TRACK_BATCH
                q_f = nearest_branch(branches[0][k], branches[1][k], branches[2][k], qh[idx])
            else:
                q_f = hand.finger_ik_fast(finger, tip, qh, inward)
            ok = q_f is not None and bool((q_f >= lo).all() and (q_f <= hi).all())
            if ok:
                q_prev = qh[idx]
                qh[idx] = q_f
                ok = self._finger_free(finger, qh, M)
                qh[idx] = q_prev
            if not ok:
                q_f = None
                for alt in hand.finger_ik_alternatives(finger, tip, qh, inward)[
                    : self.settings.posture_options
                ]:
                    if np.any(alt < lo) or np.any(alt > hi):
                        continue
                    q_try = qh.copy()
                    q_try[idx] = alt
                    if self._finger_free(finger, q_try, M):
                        q_f = alt
                        break
                if q_f is None:
                    return out, True
            qh[idx] = q_f
            out.append(q_f)
        return out, False

    def _landing_posture(
        self, finger: int, q: FloatArray, tip: FloatArray, inward: FloatArray, M: pin.SE3
    ) -> FloatArray | None:
        """A collision-free posture of ``finger`` with its tip centre at ``tip`` (world).

        ``q``'s own when it is there already, else the IK solution (within
        the joint margin) whose last link points most along ``inward``.
        """
        hand = self.hand
        idx = hand.finger_q_index[finger]
        if np.linalg.norm(hand.fingertip_positions(q)[finger] - tip) < 1e-6:
            return q[idx].copy() if self._finger_free(finger, q, M) else None
        cands, ok = hand.finger_ik_candidates(finger, tip[None])
        cands, ok = cands[0], ok[0]
        ok &= np.all((cands >= self._lo[idx]) & (cands <= self._hi[idx]), axis=1)
        rows = np.flatnonzero(ok)
        if not len(rows):
            return None
        split = hand._split_ik[finger]
        if split is not None:
            rows = rows[np.argsort(-split.alignment(cands[rows], inward), kind="stable")]
        else:
            rows = rows[np.argsort(np.linalg.norm(cands[rows] - q[idx], axis=1), kind="stable")]
        qh = q.copy()
        for k in rows[: self.settings.landing_solutions]:
            qh[idx] = cands[k]
            if self._finger_free(finger, qh, M):
                return cands[k].copy()
        return None

    def redundant(self, finger: int) -> bool:
        """Whether ``finger`` has more postures per contact than IK branches (4+ joints)."""
        return self.hand._split_ik[finger] is not None

    def tracked_count(self, finger: int) -> int:
        """How many landings of ``finger`` are tracked with its links checked (0: none).

        ``tracked_landings`` for redundant fingers (more postures per contact
        than IK branches), ``tracked_landings_simple`` for the others.
        """
        s = self.settings
        if self.redundant(finger):
            return s.tracked_landings
        return min(s.tracked_landings, s.tracked_landings_simple)

    def landing_candidates(
        self,
        finger: int,
        pose: FloatArray,
        q: FloatArray,
        grasp: GraspContacts,
        future_poses: FloatArray,
        hint: tuple[FloatArray, FloatArray] | None = None,
        limit: int = 8,
    ) -> Iterator[tuple[FloatArray, FloatArray, int]]:
        """Landing contacts for ``finger``, best first: ``(point, normal_out, score)``.

        Filters: reachable now (with joint margin), fingertips apart, every
        (n-1) subgrasp of the new grasp force closure. Sorted by
        :meth:`follow_scores` (random among ties); for tracked fingers
        (:meth:`tracked_count`) the best are re-scored by :meth:`track_score` and
        come first. A generator: the force-closure test, the costly filter,
        runs only on the candidates the caller asks for (the first usually
        works), at most ``limit`` are yielded.
        """
        ranked = self._ranked_landings(finger, pose, grasp, future_poses, hint)
        if ranked is None:
            return
        pts, nrm, keep, scores = ranked
        self._postures.clear()
        fc = _LandingForceClosure(self, finger, grasp, pts, nrm, keep)
        tracked: list[tuple[int, int]] = []
        pos = 0
        if self.tracked_count(finger) > 0:
            tracked, pos = self._track_best(finger, q, future_poses, ranked, fc)
        found = 0
        for count, c in tracked:
            yield pts[c], nrm[c], count
            found += 1
            if found >= limit:
                return
        for i in range(pos, len(keep)):
            c = keep[i]
            if not fc.holds(i):
                continue
            score = scores[i]
            yield pts[c], nrm[c], int(score)
            found += 1
            if found >= limit:
                return

    def _landing_samples(self) -> tuple[FloatArray, FloatArray]:
        """Landing candidates: ``(points, normals_out)`` (S, 3) each, object frame.

        ``landing_candidates`` surface points and, on shapes that sample
        their edges (boxes), ``landing_edges`` edge points (normals inside
        the edge's cone), shuffled together (the landing search takes the
        first reachable ones in this order). Other shapes draw only the
        surface points, as before.
        """
        s = self.settings
        return self.obj.sample_contacts(s.landing_candidates, self.rng, s.landing_edges)

    def landing_pool(
        self, finger: int, pose: FloatArray, future_poses: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray] | None:
        """Contacts ``finger`` reaches now and can follow from, whatever the others hold.

        The grasp-independent part of the landing search, for the look-ahead
        of :meth:`can_land` (which applies the grasp-dependent filters):
        sampled surface points reached now within the joint margin (twice
        ``landing_reachable`` of them), IK-only follow score above 0.

        Returns:
            ``(points, normals_out, scores)`` object frame, best score first;
            None when there is none.
        """
        s = self.settings
        pts, nrm = self._landing_samples()
        tip_obj = pts + self.hand.fingertip_radius * nrm
        every = np.arange(len(pts))
        keep = self._first_reachable(finger, pose, tip_obj, every, 2 * s.landing_reachable)
        if len(keep) == 0:
            return None
        scores = self.follow_scores(finger, tip_obj[keep], future_poses, nrm[keep])
        order = np.argsort(-scores, kind="stable")
        keep, scores = keep[order], scores[order]
        good = scores > 0
        if not good.any():
            return None
        return pts[keep[good]], nrm[keep[good]], scores[good]

    def can_land(
        self,
        finger: int,
        q: FloatArray,
        grasp: GraspContacts,
        pool: tuple[FloatArray, FloatArray, FloatArray],
        future_poses: FloatArray,
        tries: int = 16,
    ) -> bool:
        """Whether ``finger`` has a landing from ``pool`` (:meth:`landing_pool`) on ``grasp``.

        A landing: fingertips apart, moved, every (n-1) subgrasp force
        closure (the first ``tries`` that pass the cheap filters are tested)
        and a collision-free landing posture from which the finger follows at
        least one pose (:meth:`track_score`). For the look-ahead of a
        reduction whose blocking finger has no landing: another finger is
        moved first only where it gives the blocking one some.
        """
        s = self.settings
        pts, nrm, scores = pool
        tip_obj = pts + self.hand.fingertip_radius * nrm
        cand = self._grasp_filters(finger, grasp, pts, nrm)[:tries]
        holds = self._holds_force_closure(finger, grasp, pts[cand], nrm[cand])
        if holds is None:
            return False
        for c in cand[holds]:
            horizon = int(scores[c]) + max(1, s.follow_stride)
            count, q_land = self.track_score(finger, q, tip_obj[c], nrm[c], future_poses, horizon)
            if q_land is not None and count > 0:
                return True
        return False

    def _grasp_filters(
        self, finger: int, grasp: GraspContacts, points: FloatArray, normals_out: FloatArray
    ) -> np.ndarray:
        """Indices of the landings ``points, normals_out: (S, 3)`` (object frame) that may do.

        The cheap tests that depend on the other fingers' contacts: the
        fingertips stay apart, the landing is not next to the current contact
        (it would gain nothing), and the sound half-space test leaves force
        closure of every (n-1) subgrasp possible.
        """
        s = self.settings
        r = self.hand.fingertip_radius
        tip_obj = points + r * normals_out
        others = [i for i in range(self.hand.n_fingers) if i != finger]
        other_tips = grasp.points[others] + r * grasp.normals_out[others]
        apart = np.all(
            np.linalg.norm(tip_obj[:, None, :] - other_tips[None], axis=2)
            >= 2 * r + s.tip_clearance,
            axis=1,
        )
        moved = np.linalg.norm(points - grasp.points[finger], axis=1) > 0.25 * s.max_step_m
        keep = np.flatnonzero(apart & moved)
        normals = np.repeat(grasp.normals_out[None], len(keep), axis=0)
        normals[:, finger] = normals_out[keep]
        return keep[~cannot_be_force_closure(normals, self.validity.mu)]

    def _holds_force_closure(
        self, finger: int, grasp: GraspContacts, points: FloatArray, normals_out: FloatArray
    ) -> np.ndarray | None:
        """(C,) every (n-1) subgrasp certified force closure with ``finger`` at each landing.

        ``points, normals_out: (C, 3)`` object frame, evaluated in one batch
        and counted as landing checks; None past the deadline.
        """
        if self.deadline.expired():
            return None
        self.stats["landing_checks"] += len(points)
        if not len(points):
            return np.zeros(0, dtype=bool)
        quality = self.landing_qualities(grasp, finger, points, normals_out)
        return quality > self.validity.fc_margin

    def _ranked_landings(
        self,
        finger: int,
        pose: FloatArray,
        grasp: GraspContacts,
        future_poses: FloatArray,
        hint: tuple[FloatArray, FloatArray] | None,
    ) -> tuple[FloatArray, FloatArray, np.ndarray, np.ndarray] | None:
        """Sampled landings that pass the cheap filters, by IK-only follow score.

        Returns:
            ``(points, normals_out, keep, scores)``: ``(S, 3)`` sampled
            surface points and outward normals (object frame), the indices
            kept, best first (random among ties), and their follow scores;
            None when none is kept.
        """
        s = self.settings
        r = self.hand.fingertip_radius
        pts, nrm = self._landing_samples()
        if hint is not None:
            pts = np.vstack([hint[0][None], pts])
            nrm = np.vstack([hint[1][None], nrm])
        tip_obj = pts + r * nrm
        keep = self._grasp_filters(finger, grasp, pts, nrm)
        if len(keep) == 0:
            return None
        # the first landing_reachable of them (in sampling order) reachable now
        keep = self._first_reachable(
            finger, pose, tip_obj, keep, s.landing_reachable + (hint is not None)
        )
        if len(keep) == 0:
            return None
        scores = self.follow_scores(finger, tip_obj[keep], future_poses, nrm[keep])
        reach = scores > 0
        keep, scores = keep[reach], scores[reach]
        if s.landing_alignment is not None and len(keep):
            # the distal link must be able to point into the surface there,
            # or the finger's side touches the object (redundant fingers)
            R = self._frames(pose)[0]
            aligned = self._alignment(finger, tip_obj[keep] @ R.T + pose[:3], -nrm[keep] @ R.T)
            good = aligned >= s.landing_alignment
            keep, scores = keep[good], scores[good]
        order = np.lexsort((self.rng.random(len(keep)), -scores))
        return pts, nrm, keep[order], scores[order]

    def _first_reachable(
        self, finger: int, pose: FloatArray, tip_obj: FloatArray, keep: np.ndarray, most: int
    ) -> np.ndarray:
        """The first ``most`` of candidates ``keep`` whose fingertip centre the finger reaches.

        ``tip_obj: (S, 3)`` fingertip centres (object frame) indexed by
        ``keep``; reached: IK within the joint margin at ``pose``. Candidates
        outside the finger's reach voxels (:mod:`dexplan.model.hand.reach`) are dropped
        first; the rest are solved a chunk at a time, stopping once ``most`` are found (the same
        candidates as one batch over all of them, for less IK).
        """
        R = self._frames(pose)[0]
        # outside the finger's reach voxels: not worth an IK solve
        keep = keep[self.hand.reach_voxels(finger).contains(tip_obj[keep] @ R.T + pose[:3])]
        found: list[np.ndarray] = []
        count = 0
        for lo in range(0, len(keep), _REACH_CHUNK):
            chunk = keep[lo : lo + _REACH_CHUNK]
            ok_now = self._solve_in_margin(finger, tip_obj[chunk] @ R.T + pose[:3])[1]
            found.append(chunk[ok_now])
            count += int(ok_now.sum())
            if count >= most:
                break
        return np.concatenate(found)[:most] if found else keep[:0]

    def _ik_in_margin(self, finger: int, tips: FloatArray) -> tuple[FloatArray, np.ndarray]:
        """IK of ``finger`` to fingertip centres ``tips: (N, 3)`` (world frame), off the limits.

        Targets outside the finger's reach voxels are not solved (not reached).

        Returns ``q: (N, m)`` and ``ok: (N,)``: solved and within the joint margin.
        """
        idx = self.hand.finger_q_index[finger]
        q = np.zeros((len(tips), len(idx)))
        ok = self.hand.reach_voxels(finger).contains(tips)
        if ok.any():
            q[ok], ok[ok] = self._solve_in_margin(finger, tips[ok])
        return q, ok

    def _solve_in_margin(self, finger: int, tips: FloatArray) -> tuple[FloatArray, np.ndarray]:
        """:meth:`_ik_in_margin` for targets already inside the reach voxels."""
        q, ok = self.hand.finger_ik_batch(finger, tips)
        idx = self.hand.finger_q_index[finger]
        ok &= np.all((q >= self._lo[idx]) & (q <= self._hi[idx]), axis=1)
        return q, ok

    def _track_best(
        self,
        finger: int,
        q: FloatArray,
        future_poses: FloatArray,
        ranked: tuple[FloatArray, FloatArray, np.ndarray, np.ndarray],
        fc: _LandingForceClosure,
    ) -> tuple[list[tuple[int, int]], int]:
        """Track the best-ranked landings that keep force closure, links checked.

        Best IK-only score first, each candidate that keeps force closure is
        tracked until the next IK-only score, an upper bound, cannot beat the
        best tracked one. Landing postures go to ``self._postures``.

        Returns:
            ``(tracked, pos)``: ``(tracked count, candidate index)`` pairs,
            best tracked count first, and how many of the ranked candidates
            were used up.
        """
        s = self.settings
        pts, nrm, keep, scores = ranked
        r = self.hand.fingertip_radius
        tracked: list[tuple[int, int]] = []
        best, pos, most = 0, 0, self.tracked_count(finger)
        while pos < len(keep) and len(tracked) < most and scores[pos] > best:
            c = keep[pos]
            pos += 1
            if not fc.holds(pos - 1):
                continue
            horizon = int(scores[pos - 1]) + max(1, s.follow_stride)
            tip = pts[c] + r * nrm[c]
            count, q_land = self.track_score(finger, q, tip, nrm[c], future_poses, horizon)
            if q_land is None:
                continue
            self._postures[(finger, pts[c].tobytes())] = q_land
            tracked.append((count, int(c)))
            best = max(best, count)
        tracked.sort(key=lambda t: -t[0])
        return tracked, pos

    def _alignment(self, finger: int, tips: FloatArray, inward: FloatArray) -> FloatArray:
        """Best cosine ``(C,)`` between the last link and ``inward: (C, 3)`` over IK solutions.

        ``tips: (C, 3)`` fingertip centres, world frame. Fingers without
        several solutions per target (no redundancy) score 1.
        """
        hand = self.hand
        split = hand._split_ik[finger]
        if split is None:
            return np.ones(len(tips))
        cands, ok = hand.finger_ik_candidates(finger, tips)
        idx = hand.finger_q_index[finger]
        ok &= np.all((cands >= self._lo[idx]) & (cands <= self._hi[idx]), axis=2)
        C, A, m = cands.shape
        d = split.directions(cands.reshape(-1, m))[0].reshape(C, A, 3)
        cos = np.einsum("caj,cj->ca", d, inward)
        cos[~ok] = -np.inf
        return cos.max(axis=1)


class _LandingForceClosure:
    """Whether each ranked landing keeps every (n-1) subgrasp force closure (certified).

    Evaluated lazily, :data:`_FC_CHUNK` ranked candidates at a time in one
    batch (``Transitions.landing_qualities``): the search usually stops within
    the first few, and one batch costs about what two single checks do.
    """

    def __init__(
        self,
        landings: Landings,
        finger: int,
        grasp: GraspContacts,
        points: FloatArray,
        normals_out: FloatArray,
        keep: np.ndarray,
    ) -> None:
        self.landings = landings
        self.finger = finger
        self.grasp = grasp
        self.points = points
        self.normals_out = normals_out
        self.keep = keep
        self.known = np.zeros(len(keep), dtype=bool)
        self.ok = np.zeros(len(keep), dtype=bool)

    def holds(self, i: int) -> bool:
        """Force closure with the finger at ranked landing ``keep[i]`` (False past the deadline)."""
        if not self.known[i]:
            rows = np.arange(i, min(i + _FC_CHUNK, len(self.keep)))
            rows = rows[~self.known[rows]]
            c = self.keep[rows]
            holds = self.landings._holds_force_closure(
                self.finger, self.grasp, self.points[c], self.normals_out[c]
            )
            if holds is None:
                return False
            self.ok[rows] = holds
            self.known[rows] = True
        return bool(self.ok[i])
