"""Landing choice for regrasps: where a finger lands.

Whether finger gaits succeed is decided here: among sampled contacts (surface
points and, on a box, edge points whose normals lie between the two faces':
held on two opposite faces, a finger reaches a third face only by way of an
edge) that the finger reaches, that keep the fingertips apart and every (n-1)
subgrasp force closure, the planner picks the one from which the finger can
follow the rest of the object motion longest (:mod:`.following`).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from dexplan.core.typing import FloatArray, IntArray
from dexplan.model.grasp import min_subgrasp_quality_batch
from dexplan.model.grasp.halfspace import cannot_be_force_closure
from dexplan.model.hand.hand import Hand
from dexplan.model.objects import Shape
from dexplan.planning.deadline import Deadline
from dexplan.planning.gsn.contact_curve import contact_curve_samples, low_dof
from dexplan.planning.gsn.validity import ValiditySettings
from dexplan.planning.local.transitions.checks import FingerChecks
from dexplan.planning.local.transitions.contacts import GraspContacts
from dexplan.planning.local.transitions.counts import LocalCounts
from dexplan.planning.local.transitions.following import FingerFollower
from dexplan.planning.local.transitions.settings import TransitionSettings

#: Landing candidates whose reachability is solved at a time.
_REACH_CHUNK = 192
#: Ranked landing candidates whose force closure is evaluated in one batch.
_FC_CHUNK = 8

#: Contacts a finger reaches and follows from (:meth:`Landings.landing_pool`):
#: points ``(S, 3)``, outward normals ``(S, 3)`` (object frame), follow scores ``(S,)``.
LandingPool = tuple[FloatArray, FloatArray, IntArray]


class Landings:
    """Scoring and choice of landing contacts for regrasps.

    Args:
        hand: the hand.
        obj: the object shape (landing samples, torque scale).
        validity: friction settings (force closure of landings).
        settings: the local planners' settings.
        checks: the per-finger collision checks and joint bounds.
        follower: the follow scores of a landing.
        rng: random generator for landing samples and ties.
        deadline: when the force-closure checks give up.
        stats: the local planners' counters (``landing_checks`` counted here).

    Attributes:
        postures: landing postures found while tracking, keyed by (finger,
            contact point bytes), for the regrasp that lands there.
    """

    def __init__(
        self,
        hand: Hand,
        obj: Shape,
        validity: ValiditySettings,
        settings: TransitionSettings,
        checks: FingerChecks,
        follower: FingerFollower,
        rng: np.random.Generator,
        deadline: Deadline,
        stats: LocalCounts,
    ) -> None:
        self.hand = hand
        self.obj = obj
        self.validity = validity
        self.settings = settings
        self.checks = checks
        self.follower = follower
        self.rng = rng
        self.deadline = deadline
        self.stats = stats
        self.postures: dict[tuple[int, bytes], FloatArray] = {}

    def landing_qualities(
        self, grasp: GraspContacts, finger: int, points: FloatArray, normals_out: FloatArray
    ) -> FloatArray:
        """Grasp quality of ``grasp`` with ``finger`` moved, per landing.

        Args:
            grasp: the current contacts.
            finger: the finger that moves.
            points: (C, 3) landing points, object frame.
            normals_out: (C, 3) outward unit normals there, object frame.

        Returns:
            (C,) the value :meth:`.Transitions.grasp_quality` gives ``grasp.replace(finger, p, n)``
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

    def tracked_count(self, finger: int) -> int:
        """How many landings of ``finger`` are tracked with its links checked (0: none).

        ``tracked_landings`` for redundant fingers (more postures per contact
        than IK branches), ``tracked_landings_simple`` for the others.
        """
        s = self.settings
        if self.follower.redundant(finger):
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
        self.postures.clear()
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

    def _landing_samples(self, finger: int, pose: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Landing candidates: ``(points, normals_out)`` (S, 3) each, object frame.

        ``landing_candidates`` surface points and, on shapes with edges
        (boxes, meshes with sharp convex edges), ``landing_edges`` edge points
        (normals inside the edge's cone) and ``landing_vertices`` corner points, shuffled
        together (the landing search takes the first reachable ones in this
        order). Other shapes draw only the surface points, as before. A finger
        of fewer than 3 joints reaches almost no sampled point: its candidates
        are the contacts it makes at the object's ``pose`` from
        ``landing_candidates`` joint values
        (:mod:`dexplan.planning.gsn.contact_curve`).
        """
        s = self.settings
        if low_dof(self.hand, finger):
            R = self.checks.frames(pose)[0]
            c = contact_curve_samples(
                self.hand, self.obj, finger, R, pose[:3], s.landing_candidates, self.rng
            )
            return c.points, c.normals_out
        return self.obj.sample_contacts(
            s.landing_candidates, self.rng, s.landing_edges, s.landing_vertices
        )

    def landing_pool(
        self, finger: int, pose: FloatArray, future_poses: FloatArray
    ) -> LandingPool | None:
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
        pts, nrm = self._landing_samples(finger, pose)
        tip_obj = pts + self.hand.fingertip_radius * nrm
        every = np.arange(len(pts))
        keep = self._first_reachable(finger, pose, tip_obj, every, 2 * s.landing_reachable)
        if len(keep) == 0:
            return None
        scores = self.follower.follow_scores(finger, tip_obj[keep], future_poses, nrm[keep])
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
        pool: LandingPool,
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
        holds = self.holds_force_closure(finger, grasp, pts[cand], nrm[cand])
        if holds is None:
            return False
        for c in cand[holds]:
            horizon = int(scores[c]) + max(1, s.follow_stride)
            count, q_land = self.follower.track_score(
                finger, q, tip_obj[c], nrm[c], future_poses, horizon
            )
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

    def holds_force_closure(
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
        pts, nrm = self._landing_samples(finger, pose)
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
        scores = self.follower.follow_scores(finger, tip_obj[keep], future_poses, nrm[keep])
        reach = scores > 0
        keep, scores = keep[reach], scores[reach]
        if s.landing_alignment is not None and len(keep):
            # the distal link must be able to point into the surface there,
            # or the finger's side touches the object (redundant fingers)
            R = self.checks.frames(pose)[0]
            aligned = self.follower.alignment(
                finger, tip_obj[keep] @ R.T + pose[:3], -nrm[keep] @ R.T
            )
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
        R = self.checks.frames(pose)[0]
        # outside the finger's reach voxels: not worth an IK solve
        keep = keep[self.hand.reach_voxels(finger).contains(tip_obj[keep] @ R.T + pose[:3])]
        found: list[np.ndarray] = []
        count = 0
        for lo in range(0, len(keep), _REACH_CHUNK):
            chunk = keep[lo : lo + _REACH_CHUNK]
            ok_now = self.follower.solve_in_margin(finger, tip_obj[chunk] @ R.T + pose[:3])[1]
            found.append(chunk[ok_now])
            count += int(ok_now.sum())
            if count >= most:
                break
        return np.concatenate(found)[:most] if found else keep[:0]

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
        best tracked one. Landing postures go to ``self.postures``.

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
            count, q_land = self.follower.track_score(finger, q, tip, nrm[c], future_poses, horizon)
            if q_land is None:
                continue
            self.postures[(finger, pts[c].tobytes())] = q_land
            tracked.append((count, int(c)))
            best = max(best, count)
        tracked.sort(key=lambda t: -t[0])
        return tracked, pos


class _LandingForceClosure:
    """Whether each ranked landing keeps every (n-1) subgrasp force closure (certified).

    Evaluated lazily, :data:`_FC_CHUNK` ranked candidates at a time in one
    batch (:meth:`Landings.landing_qualities`): the search usually stops within
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
            holds = self.landings.holds_force_closure(
                self.finger, self.grasp, self.points[c], self.normals_out[c]
            )
            if holds is None:
                return False
            self.ok[rows] = holds
            self.known[rows] = True
        return bool(self.ok[i])
