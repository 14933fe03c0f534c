"""How long a finger can follow the object's motion from a contact.

Two scores: the IK-only bound (:meth:`FingerFollower.follow_scores`, the
fingertip reached within the joint margin at each pose, cheap and batched)
and the tracked count (:meth:`FingerFollower.track_score`, the finger followed
as a transfer moves it, its links checked against the palm, the object and
obstacles), kept as a :class:`Track` that a later query starting where it
left off resumes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from dexplan.core.typing import FloatArray, IntArray
from dexplan.model.hand.hand import Hand
from dexplan.model.hand.ik import nearest_branch, planar_branches
from dexplan.planning.local.transitions.checks import FingerChecks
from dexplan.planning.local.transitions.settings import TransitionSettings

#: Poses whose closed-form IK branches a track solves at once.
_TRACK_BATCH = 16
#: Poses (after the follow stride) scored at a time by ``follow_scores``.
_FOLLOW_CHUNK = 4
#: Tracks kept before the store is emptied.
_TRACK_CACHE = 512


@dataclass
class Track:
    """A finger tracked along object poses (:meth:`FingerFollower.track_score`).

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
            stop = self.stopped_at
            fails_next = m == len(rest) and m < len(poses) and stop is not None
            if fails_next and stop is not None and not np.array_equal(stop, poses[m]):
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


class FingerFollower:
    """Scores of how long each finger follows the object's motion from a contact.

    Args:
        hand: the hand.
        settings: the local planners' settings.
        checks: the per-finger collision checks and joint bounds.

    Attributes:
        tracks: finger tracks by (finger, fingertip centre, normal, joints of
            no finger): poses followed, postures there, and whether the pose
            after the last one failed.
    """

    def __init__(self, hand: Hand, settings: TransitionSettings, checks: FingerChecks) -> None:
        self.hand = hand
        self.settings = settings
        self.checks = checks
        self.tracks: dict[tuple[int, bytes, bytes, bytes], Track] = {}
        fingers = np.concatenate([np.asarray(i, dtype=np.int64) for i in hand.finger_q_index])
        self._shared_q = np.setdiff1d(np.arange(hand.nq), fingers)

    def follow_scores(
        self,
        finger: int,
        candidates_tip_obj: FloatArray,
        future_poses: FloatArray,
        normals_obj: FloatArray | None = None,
    ) -> IntArray:
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
        Rs = [self.checks.frames(pose)[0] for pose in poses]
        targets = np.stack([tips_obj @ R.T + pose[:3] for R, pose in zip(Rs, poses, strict=True)])
        q, ok = self.ik_in_margin(finger, targets.reshape(-1, 3))
        split = self.hand.split_ik(finger)
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
        track = self.tracks.get(key)
        start = None if track is None else track.resume_at(future_poses, q[idx])
        if start is not None and not self._touches(finger, q, tip_obj, future_poses[0]):
            start = None  # the fresh track would land in another posture
        if start is None:
            target = self._target(tip_obj, normal_obj, future_poses[0])
            q_f = self._landing_posture(finger, q, *target)
            if q_f is None:
                return 0, None
            if len(self.tracks) >= _TRACK_CACHE:
                self.tracks.clear()
            track = self.tracks[key] = Track(future_poses[:1].copy(), q_f[None].copy())
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
        R, M = self.checks.frames(pose)
        return R @ tip_obj + pose[:3], -(R @ normal_obj), M

    def _touches(self, finger: int, q: FloatArray, tip_obj: FloatArray, pose: FloatArray) -> bool:
        """``q``'s fingertip centre is at ``tip_obj`` (object frame) at ``pose`` (1e-6 m)."""
        tip = self.checks.frames(pose)[0] @ tip_obj + pose[:3]
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
        lo, hi = self.checks.lo[idx], self.checks.hi[idx]
        qh = q.copy()
        qh[idx] = q_prev
        out: list[FloatArray] = []
        analytic = hand.planar_ik(finger)
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
                ok = self.checks.finger_free(finger, qh, M)
                qh[idx] = q_prev
            if not ok or q_f is None:
                q_f = None
                for alt in hand.finger_ik_alternatives(finger, tip, qh, inward)[
                    : self.settings.posture_options
                ]:
                    if np.any(alt < lo) or np.any(alt > hi):
                        continue
                    q_try = qh.copy()
                    q_try[idx] = alt
                    if self.checks.finger_free(finger, q_try, M):
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
            return q[idx].copy() if self.checks.finger_free(finger, q, M) else None
        cands, ok = hand.finger_ik_candidates(finger, tip[None])
        cands, ok = cands[0], ok[0]
        ok &= np.all((cands >= self.checks.lo[idx]) & (cands <= self.checks.hi[idx]), axis=1)
        rows = np.flatnonzero(ok)
        if not len(rows):
            return None
        split = hand.split_ik(finger)
        if split is not None:
            rows = rows[np.argsort(-split.alignment(cands[rows], inward), kind="stable")]
        else:
            rows = rows[np.argsort(np.linalg.norm(cands[rows] - q[idx], axis=1), kind="stable")]
        qh = q.copy()
        for k in rows[: self.settings.landing_solutions]:
            qh[idx] = cands[k]
            if self.checks.finger_free(finger, qh, M):
                return cands[k].copy()
        return None

    def redundant(self, finger: int) -> bool:
        """Whether ``finger`` has more postures per contact than IK branches (4+ joints)."""
        return self.hand.split_ik(finger) is not None

    def ik_in_margin(self, finger: int, tips: FloatArray) -> tuple[FloatArray, np.ndarray]:
        """IK of ``finger`` to fingertip centres ``tips: (N, 3)`` (world frame), off the limits.

        Targets outside the finger's reach voxels are not solved (not reached).

        Returns ``q: (N, m)`` and ``ok: (N,)``: solved and within the joint margin.
        """
        idx = self.hand.finger_q_index[finger]
        q = np.zeros((len(tips), len(idx)))
        ok = self.hand.reach_voxels(finger).contains(tips)
        if ok.any():
            q[ok], ok[ok] = self.solve_in_margin(finger, tips[ok])
        return q, ok

    def solve_in_margin(self, finger: int, tips: FloatArray) -> tuple[FloatArray, np.ndarray]:
        """:meth:`ik_in_margin` for targets already inside the reach voxels."""
        q, ok = self.hand.finger_ik_batch(finger, tips)
        idx = self.hand.finger_q_index[finger]
        ok &= np.all((q >= self.checks.lo[idx]) & (q <= self.checks.hi[idx]), axis=1)
        return q, ok

    def alignment(self, finger: int, tips: FloatArray, inward: FloatArray) -> FloatArray:
        """Best cosine ``(C,)`` between the last link and ``inward: (C, 3)`` over IK solutions.

        ``tips: (C, 3)`` fingertip centres, world frame. Fingers without
        several solutions per target (no redundancy) score 1.
        """
        hand = self.hand
        split = hand.split_ik(finger)
        if split is None:
            return np.ones(len(tips))
        cands, ok = hand.finger_ik_candidates(finger, tips)
        idx = hand.finger_q_index[finger]
        ok &= np.all((cands >= self.checks.lo[idx]) & (cands <= self.checks.hi[idx]), axis=2)
        C, A, m = cands.shape
        d = split.directions(cands.reshape(-1, m))[0].reshape(C, A, 3)
        cos = np.einsum("caj,cj->ca", d, inward)
        cos[~ok] = -np.inf
        return cos.max(axis=1)
