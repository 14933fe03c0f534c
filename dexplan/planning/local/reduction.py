"""Reduction of a GSn path to transfer and regrasp segments (paper, section IV).

The reduction property says a path in valid GSn can be replaced by a finite
alternation of transfer and regrasp paths. On symmetric objects the GSn path
itself mostly slides the contacts, so the physical plan is made here, and made
to look like a finger gait (see MEASURED.md):

1. follow the object trajectory with one transfer on the current grasp for as
   long as it stays valid;
2. regrasp the finger that blocks it (IK, joint limit, collision) onto the
   landing from which it can follow the rest of the motion longest (surface
   points and, on a box, edge points); when that finger has no landing, move
   another finger first (fewest remaining steps first): where that gains it
   follow, else where the blocking finger then has a landing (the look-ahead),
   else anywhere, which may clear its way;
3. repeat until the object reaches the end of the trajectory.

Only the object trajectory of the GSn path is followed; its contacts are
offered as landing hints. A clear failure status is returned when no regrasp
works or no progress is made.

When that fails, :func:`reduce_gsn_path` applies the reduction property edge
by edge: each GSn edge ``(pose_a, contacts_a) -> (pose_b, contacts_b)`` becomes
a transfer on the current grasp, or regrasps onto ``contacts_b`` then a
transfer, or regrasps onto ``contacts_a`` then a transfer; when none is valid
the edge is bisected on GSn until every piece is, or a resolution limit is
hit. The bisection's midpoint is the object pose slerp and contacts halfway:
first the world fingertip centres averaged and projected onto the surface;
on a mesh, an edge that fails so is reduced again with each contact halfway
along its surface geodesic (the paper's section VI,
:mod:`dexplan.planning.local.contact_paths`; :attr:`ReductionSettings.midpoints`).
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np

from dexplan.core.errors import InvalidInputError
from dexplan.core.pose import interpolate_pose, inverse_transform_points
from dexplan.core.segments import Segment
from dexplan.core.typing import FloatArray
from dexplan.planning.local.contact_paths import ContactPaths
from dexplan.planning.local.transitions import GraspContacts, Transitions, densify_poses

#: Landings of another finger tried by the look-ahead (:func:`_passes`, ``"enable"``).
_ENABLE_LANDINGS = 12

MIDPOINTS = ("chord", "geodesic")
"""Contact interpolations of :attr:`ReductionSettings.midpoints`."""


@dataclass(frozen=True)
class ReductionSettings:
    """Limits of the reduction.

    Attributes:
        max_regrasps: give up after this many regrasps.
        max_stall: give up after this many regrasps in a row without object
            progress. Finger gaits on a hand whose fingers block each other
            (the Allegro: the ring finger's distal link meets a ball after a
            few degrees) need long runs of regrasps without progress; on a
            sphere every pose is like the others, so carrying on beats
            starting the trajectory again (allegro_sphere seeds 1, 4: 8 stalls
            at 146 degrees on every attempt, 30 solves in 12 s).
        max_blind: give up after this many regrasps since the last object
            progress that moved a finger other than the blocking one without
            giving the blocking one a landing (the look-ahead found none; see
            :func:`_passes`). Each costs a look-ahead (about 1 s on a box), and
            a run of them rarely ends in progress: box_tilt90 seed 4 spent 30 s
            on 35 at one step, then a fresh attempt solved in 2 s; module 2's
            link tests run this reduction too. The four box scenarios, seeds
            1-20: 80/80 with 4 (slowest 9.5 s), 80/80 with no limit (40 s).
        regrasp_retries: a regrasp search that finds no feasible regrasp is
            run again this many times (the landing candidates are random
            samples; a fresh set often holds one) before the reduction gives up.
        backtracks: when the finger gaits get stuck (no feasible regrasp,
            ``max_stall`` or ``max_blind``), go back this many times at most
            to the hand's state after an earlier transfer, at least
            ``backtrack_steps`` trajectory steps before the stuck one, and go
            on from there with fresh random landings: where the fingers
            stand when they reach a hard stretch decides whether they pass
            it (allegro_cube: the ring finger blocked at 65 degrees on most
            grasps that reach it, passed on others). Gaits stuck within
            ``backtrack_steps`` of the start give up at once: the start grasp
            itself is the trouble, which the caller changes (module 2).
        backtrack_steps: see ``backtracks``.
        max_depth: resolution limit of :func:`reduce_gsn_path`: a GSn edge is
            bisected at most this many times (into at most ``2**max_depth`` pieces).
        same_contact_m: contacts closer than this (m, object frame) count as
            the same; no regrasp moves a finger by less.
        resync_m: in :func:`reduce_gsn_path`, a finger whose contact is farther
            than this (m) from the GSn path's is regrasped back onto it.
        midpoints: how :func:`reduce_gsn_path` places the contacts of a
            bisected edge's midpoint, tried in this order per GSn edge (an
            edge that fails with one is reduced again, from the same state,
            with the next): ``chord`` (the world fingertip centres averaged
            and projected onto the surface, as OMPL's projected interpolation
            moves them) and ``geodesic`` (on a mesh, each contact halfway
            along its surface geodesic, the paper's section VI; skipped on
            primitives and on meshes without geodesics). Measured on
            egg_tilt90 (docs/meshes.md): ``chord`` first solves more edges
            than ``geodesic`` first; the second only adds.
    """

    max_regrasps: int = 200
    max_stall: int = 30
    max_blind: int = 4
    regrasp_retries: int = 2
    backtracks: int = 3
    backtrack_steps: int = 8
    max_depth: int = 5
    same_contact_m: float = 1e-3
    resync_m: float = 0.01
    midpoints: tuple[str, ...] = MIDPOINTS

    def __post_init__(self) -> None:
        bad = [m for m in self.midpoints if m not in MIDPOINTS]
        if bad or not self.midpoints:
            raise InvalidInputError(
                f"midpoints must be a non-empty sequence of {', '.join(MIDPOINTS)}, "
                f"got {self.midpoints!r}"
            )


@dataclass(frozen=True)
class ReductionResult:
    """Outcome of :func:`reduce_object_path`.

    Attributes:
        success: the object reached the end of the trajectory.
        segments: transfer and regrasp segments, in order.
        reached: index of the last pose reached in the dense trajectory.
        reason: failure reason, None on success.
        stats: counters (transfers, regrasps, attempts).
        final: the failure does not depend on random choices (the object
            trajectory itself is blocked): retrying the same trajectory is useless.
    """

    success: bool
    segments: tuple[Segment, ...]
    reached: int
    reason: str | None
    stats: dict[str, int] = field(default_factory=dict)
    final: bool = False


def reduce_object_path(
    trans: Transitions,
    poses: FloatArray,
    q_start: FloatArray,
    grasp: GraspContacts,
    settings: ReductionSettings | None = None,
    hints: FloatArray | None = None,
) -> ReductionResult:
    """Turn a dense object trajectory into transfer and regrasp segments.

    Args:
        trans: local planners.
        poses: (P, 7) dense object trajectory (consecutive poses within the
            transfer resolution), starting at the current pose.
        q_start: (nq,) hand configuration holding ``grasp`` at ``poses[0]``.
        grasp: initial contacts (all n fingers).
        settings: limits.
        hints: optional (P, n, 6) per-pose contact point and outward normal
            (object frame) of each finger along the GSn path, offered as
            landing candidates.

    Returns:
        A :class:`ReductionResult`.
    """
    settings = settings or ReductionSettings()
    segments: list[Segment] = []
    idx, q = 0, q_start.copy()
    regrasps = stall = blind = 0
    # (segments kept, trajectory index, q, grasp) after each transfer that moved the object
    checkpoints: list[tuple[int, int, FloatArray, GraspContacts]] = [(0, 0, q.copy(), grasp)]
    backtracks = 0

    def backtracked() -> bool:
        """Go back to an earlier checkpoint (True), or not (False: give up)."""
        nonlocal segments, idx, q, grasp, regrasps, stall, blind, backtracks
        if (
            backtracks >= settings.backtracks
            or idx < settings.backtrack_steps  # stuck near the start: another grasp's turn
            or trans.deadline.expired()
        ):
            return False
        backtracks += 1
        trans.stats["backtracks"] += 1
        # the latest checkpoint far enough back (checkpoints go forward in idx)
        limit = idx - settings.backtrack_steps
        k = max((i for i, c in enumerate(checkpoints) if c[1] <= limit), default=0)
        kept, idx, q, grasp = checkpoints[k]
        del checkpoints[k + 1 :]
        segments = segments[:kept]
        q = q.copy()
        regrasps = sum(seg.kind == "regrasp" for seg in segments)
        stall = blind = 0
        return True

    while True:
        if trans.deadline.expired():
            return ReductionResult(
                False, tuple(segments), idx, "time limit reached", _stats(trans, regrasps)
            )
        tr = trans.transfer(poses, idx, q, grasp)
        if len(tr.waypoints) > 1:
            segments.append(Segment("transfer", None, tr.waypoints))
            stall = blind = 0
        idx, q = tr.reached, tr.waypoints[-1].q
        if len(tr.waypoints) > 1:
            checkpoints.append((len(segments), idx, q.copy(), grasp))
        if tr.reason is None:
            return ReductionResult(True, tuple(segments), idx, None, _stats(trans, regrasps))
        if tr.blocking is None:
            return ReductionResult(
                False,
                tuple(segments),
                idx,
                f"transfer blocked: {tr.reason}",
                _stats(trans, regrasps),
                final=tr.reason == "object_collision",
            )
        hint_row = None if hints is None else hints[min(idx, len(hints) - 1)]
        found = _regrasp_retrying(
            trans, poses, idx, q, grasp, tr.blocking, hint_row, settings.regrasp_retries
        )
        if found is None:
            why = (
                f"no feasible regrasp at trajectory step {idx} (blocked by finger "
                f"{tr.blocking}: {tr.reason})"
            )
            if backtracked():
                continue
            return ReductionResult(False, tuple(segments), idx, why, _stats(trans, regrasps))
        seg, grasp, mode = found
        segments.append(seg)
        q = seg.end.q
        regrasps += 1
        stall += 1
        blind += mode == "any"
        if regrasps > settings.max_regrasps:
            return ReductionResult(
                False,
                tuple(segments),
                idx,
                f"no progress after {regrasps} regrasps at trajectory step {idx}",
                _stats(trans, regrasps),
            )
        why = None
        if stall > settings.max_stall:
            why = f"no progress after {regrasps} regrasps at trajectory step {idx}"
        elif blind > settings.max_blind:
            why = (
                f"no landing for finger {tr.blocking} at trajectory step {idx} after "
                f"{blind} moves of other fingers"
            )
        if why is not None and not backtracked():
            return ReductionResult(False, tuple(segments), idx, why, _stats(trans, regrasps))


def _regrasp_retrying(
    trans: Transitions,
    poses: FloatArray,
    idx: int,
    q: FloatArray,
    grasp: GraspContacts,
    blocking: int,
    hint_row: FloatArray | None,
    retries: int,
) -> tuple[Segment, GraspContacts, str] | None:
    """:func:`_regrasp_one`, run again up to ``retries`` times while it finds nothing.

    The landing candidates are random samples: a fresh set often holds a
    feasible regrasp. Stops at the deadline.
    """
    for _ in range(1 + retries):
        found = _regrasp_one(trans, poses, idx, q, grasp, blocking, hint_row)
        if found is not None or trans.deadline.expired():
            return found
    return None


def _regrasp_one(
    trans: Transitions,
    poses: FloatArray,
    idx: int,
    q: FloatArray,
    grasp: GraspContacts,
    blocking: int,
    hint_row: FloatArray | None,
) -> tuple[Segment, GraspContacts, str] | None:
    """One regrasp that lets the transfer blocked at ``poses[idx]`` go on, or None.

    The blocking finger first, then the others, least remaining follow first
    (the others' follows only when the blocking finger cannot move: it
    usually can, and tracking them costs more than the rest); see
    :func:`_passes`. ``hint_row: (n, 6)`` the GSn path's contact point and
    outward normal per finger there (object frame), offered as landings.

    Returns:
        ``(regrasp segment, new grasp, pass)``, the pass as :func:`_passes` names it.
    """
    future = poses[idx:]
    others = [i for i in range(trans.hand.n_fingers) if i != blocking]
    follow: dict[int, int] = {}
    pool: tuple[FloatArray, FloatArray, FloatArray] | None = None
    for f, mode in _passes(blocking, others, follow, trans, q, grasp, future):
        if not trans.can_release(f, poses[idx], q, grasp):
            continue  # the other fingers cannot hold the object within the effort limits
        hint = None if hint_row is None else (hint_row[f, :3], hint_row[f, 3:])
        limit = _ENABLE_LANDINGS if mode == "enable" else 8
        for point, normal, score in trans.landing_candidates(
            f, poses[idx], q, grasp, future, hint, limit
        ):
            if f != blocking and mode == "gain" and score <= follow[f]:
                break  # moving this finger would not help it follow further
            new = grasp.replace(f, point, normal)
            if mode == "enable":
                if pool is None:
                    pool = trans.landing_pool(blocking, poses[idx], future)
                if pool is None:
                    break  # the blocking finger reaches nothing it could follow from
                if not trans.can_land(blocking, q, new, pool, future):
                    continue
            seg = trans.regrasp(poses[idx], q, grasp, f, point, normal)
            if seg is not None:
                return seg, new, mode
    return None


def _passes(
    blocking: int,
    others: list[int],
    follow: dict[int, int],
    trans: Transitions,
    q: FloatArray,
    grasp: GraspContacts,
    future: FloatArray,
) -> Iterator[tuple[int, bool]]:
    """Fingers to regrasp, in order, with what their landing must do.

    ``"gain"``: follow further than the finger does now. The blocking finger;
    then the others, least remaining follow first (the follows are computed
    only here, into ``follow``). When nothing works, the others again even
    onto a landing they follow less far from: first ``"enable"``, a landing
    after which the blocking finger has one of its own
    (:meth:`Transitions.can_land`: on a box held by two fingers on each of
    two faces, most landings of the blocking finger break some subgrasp's
    force closure, and moving a neighbour where it does not help led to
    runs of 30 regrasps without progress); then ``"any"`` landing (moving
    one out of the way may clear the blocker's path in other ways).
    """
    yield blocking, "gain"
    follow.update({i: current_follow(trans, i, q, grasp, future) for i in others})
    order = sorted(others, key=lambda i: follow[i])
    for f in order:
        yield f, "gain"
    for mode in ("enable", "any"):
        for f in order:
            yield f, mode


def grasp_follow(
    trans: Transitions, pose: FloatArray, q: FloatArray, future: FloatArray
) -> tuple[int, ...]:
    """How far each finger of the grasp held at ``(pose, q)`` follows ``future``, ascending.

    The IK-only bound of :meth:`Transitions.follow_scores` per finger (joint
    limits, no link collisions: tracking the links too cost 0.28 s for 8
    paper-hand grasps on a 90-degree turn, ranked them nearly alike, and the
    reduction tracks the grasp it keeps), sorted: compared as tuples, a grasp
    whose first blocked finger goes further, then whose second does, ranks
    higher (a transfer stops at the first blocked finger).
    """
    grasp = grasp_from_state(trans, pose, q)
    tips = grasp.points + trans.hand.fingertip_radius * grasp.normals_out
    n = trans.hand.n_fingers
    return tuple(sorted(int(trans.follow_scores(i, tips[i][None], future)[0]) for i in range(n)))


def current_follow(
    trans: Transitions, finger: int, q: FloatArray, grasp: GraspContacts, future: FloatArray
) -> int:
    """How many of the ``future`` poses ``finger`` can follow on its current contact.

    The IK-only bound (:meth:`Transitions.follow_scores`), tightened by
    tracking the finger with its links collision-checked
    (:meth:`Transitions.track_score`) for tracked fingers (:meth:`Transitions.tracked_count`).
    """
    r = trans.hand.fingertip_radius
    tip = grasp.points[finger] + r * grasp.normals_out[finger]
    bound = int(trans.follow_scores(finger, tip[None], future)[0])
    if trans.tracked_count(finger) <= 0 or bound <= 0:
        return bound
    limit = bound + max(1, trans.settings.follow_stride)
    return trans.track_score(finger, q, tip, grasp.normals_out[finger], future, limit)[0]


def regrasps_onto(
    trans: Transitions,
    pose: FloatArray,
    q: FloatArray,
    grasp: GraspContacts,
    target: GraspContacts,
    same_contact_m: float = 1e-3,
) -> tuple[list[Segment], FloatArray, GraspContacts] | None:
    """Regrasps (one finger at a time, the object fixed at ``pose``) from ``grasp`` onto ``target``.

    Every intermediate grasp keeps all its (n-1) subgrasps force closure; the
    finger order is chosen greedily, farthest contact first. Fingers already
    within ``same_contact_m`` of their target stay.

    Args:
        trans: local planners.
        pose: (7,) object pose, world frame.
        q: (nq,) hand joints holding ``grasp``.
        grasp: the current contacts, object frame.
        target: the contacts to end on, object frame.
        same_contact_m: contacts closer than this (m) count as the same.

    Returns:
        ``(regrasp segments, q, grasp)`` at the end (no segments when nothing
        had to move), or None when no order works.
    """
    gap = np.linalg.norm(grasp.points - target.points, axis=1)
    todo = [int(f) for f in np.argsort(-gap) if gap[f] > same_contact_m]
    segs: list[Segment] = []
    while todo:
        for f in todo:
            new = grasp.replace(f, target.points[f], target.normals_out[f])
            if trans.grasp_quality(new, exact=True) <= trans.validity.fc_margin:
                continue
            seg = trans.regrasp(pose, q, grasp, f, target.points[f], target.normals_out[f])
            if seg is not None:
                segs.append(seg)
                q, grasp = seg.end.q, new
                todo.remove(f)
                break
        else:
            return None
    return segs, q, grasp


def _stats(trans: Transitions, regrasps: int) -> dict[str, int]:
    out = dict(trans.stats)
    out["reduction_regrasps"] = regrasps
    return out


def grasp_from_state(trans: Transitions, pose: FloatArray, q: FloatArray) -> GraspContacts:
    """Contacts (object frame) of the fingertips of ``q`` at an object pose."""
    from dexplan.core.pose import inverse_transform_points

    tips = inverse_transform_points(pose, trans.hand.fingertip_positions(q))
    pts, n_out = trans.obj.closest_point(tips)
    return GraspContacts(np.asarray(pts), np.asarray(n_out))


def reduce_gsn_path(
    trans: Transitions,
    poses: FloatArray,
    grasps: Sequence[GraspContacts],
    q_start: FloatArray,
    settings: ReductionSettings | None = None,
    deadline: float | None = None,
) -> ReductionResult:
    """The reduction property, edge by edge: transfers and regrasps along a GSn path.

    Every edge of the path is replaced by (first that is valid)

    1. a transfer on the current grasp;
    2. regrasps onto the edge's end contacts, then a transfer;
    3. regrasps onto the edge's start contacts, then a transfer;

    or else it is bisected and both halves are reduced in turn, at most
    ``settings.max_depth`` times. The grasp is changed only where a transfer
    needs it, so a path that one grasp can follow gives a single transfer.

    Args:
        trans: local planners.
        poses: (K, 7) object poses of the GSn path, XYZW, unit quaternions.
        grasps: K contact sets (object frame), one per GSn state.
        q_start: (nq,) hand configuration holding ``grasps[0]`` at ``poses[0]``.
        settings: limits (``max_depth`` is the resolution limit).
        deadline: ``time.perf_counter()`` value after which it gives up.

    Returns:
        A :class:`ReductionResult`; ``reached`` is the index of the last GSn
        state reached. The failure reason names the edge and the limit hit.
    """
    if len(poses) != len(grasps):
        raise InvalidInputError(f"{len(poses)} poses but {len(grasps)} contact sets")
    # quaternion signs continuous along the path: a transfer ends on the sign
    # its slerp arrives with, and the next edge's regrasps must start there
    poses = np.array(poses, dtype=float)
    for k in range(1, len(poses)):
        if float(np.dot(poses[k - 1, 3:], poses[k, 3:])) < 0.0:
            poses[k, 3:] *= -1.0
    reducer = _EdgeReducer(trans, settings or ReductionSettings(), deadline, q_start, grasps[0])
    for k in range(len(poses) - 1):
        if not reducer.whole_edge(poses[k], grasps[k], poses[k + 1], grasps[k + 1]):
            return ReductionResult(
                False,
                tuple(reducer.segments),
                k,
                f"GSn edge {k} -> {k + 1} of {len(poses) - 1}: {reducer.failure}",
                reducer.stats(),
            )
    return ReductionResult(True, tuple(reducer.segments), len(poses) - 1, None, reducer.stats())


class _EdgeReducer:
    """State of :func:`reduce_gsn_path`: the hand's current configuration and grasp."""

    def __init__(
        self,
        trans: Transitions,
        settings: ReductionSettings,
        deadline: float | None,
        q: FloatArray,
        grasp: GraspContacts,
    ) -> None:
        self.trans = trans
        self.settings = settings
        self.deadline = deadline
        self.q = q.copy()
        self.grasp = grasp
        self.segments: list[Segment] = []
        self.regrasps = 0
        self.bisections = 0
        self.failure = ""
        self.contact_paths = ContactPaths(trans.obj)
        self.midpoint = settings.midpoints[0]
        self.geodesic_midpoints = 0
        self.retries = 0

    def stats(self) -> dict[str, int]:
        out = _stats(self.trans, self.regrasps)
        out["reduction_bisections"] = self.bisections
        out["reduction_geodesic_midpoints"] = self.geodesic_midpoints
        out["reduction_midpoint_retries"] = self.retries
        return out

    def whole_edge(
        self, pa: FloatArray, ca: GraspContacts, pb: FloatArray, cb: GraspContacts
    ) -> bool:
        """Reduce one GSn edge, with each of the settings' midpoint interpolations in turn.

        A failed attempt leaves nothing behind: segments, joints, grasp and
        regrasp count are restored before the next.
        """
        kept = (len(self.segments), self.q, self.grasp, self.regrasps)
        modes = [m for m in self.settings.midpoints if m != "geodesic" or self.contact_paths.active]
        for k, mode in enumerate(modes):
            if k:
                self.retries += 1
                del self.segments[kept[0] :]
                self.q, self.grasp, self.regrasps = kept[1], kept[2], kept[3]
            self.midpoint = mode
            if self.edge(pa, ca, pb, cb, 0):
                return True
            if self.failure == "time limit reached":
                break
        return False

    def edge(
        self, pa: FloatArray, ca: GraspContacts, pb: FloatArray, cb: GraspContacts, depth: int
    ) -> bool:
        """Reduce the edge ``(pa, ca) -> (pb, cb)``; the hand is at ``pa`` on ``self.grasp``."""
        if self.deadline is not None and time.perf_counter() > self.deadline:
            self.failure = "time limit reached"
            return False
        s = self.trans.settings
        dense = densify_poses(np.stack([pa, pb]), s.max_step_m, s.max_step_rad)
        if self._transfer(dense, [], self.q, self.grasp):
            self._resync(pb, cb)
            return True
        for target in (cb, ca):
            moved = self._regrasps_to(pa, target)
            if moved is not None and self._transfer(dense, *moved):
                return True
        if depth >= self.settings.max_depth:
            self.failure = (
                f"resolution limit: no transfer or regrasp sequence is valid after "
                f"{depth} bisections (max_depth={self.settings.max_depth})"
            )
            return False
        self.bisections += 1
        pm, cm = self._midpoint(pa, ca, pb, cb)
        return self.edge(pa, ca, pm, cm, depth + 1) and self.edge(pm, cm, pb, cb, depth + 1)

    def _transfer(
        self, dense: FloatArray, regrasps: list[Segment], q: FloatArray, grasp: GraspContacts
    ) -> bool:
        """Transfer along ``dense`` after ``regrasps``; commit all of it when it is valid."""
        tr = self.trans.transfer(dense, 0, q, grasp)
        if tr.reason is not None:
            return False
        self.segments.extend(regrasps)
        self.regrasps += len(regrasps)
        last = self.segments[-1] if self.segments else None
        if last is not None and last.kind == "transfer":
            # consecutive edges on one grasp make a single transfer
            self.segments[-1] = Segment("transfer", None, last.waypoints + tr.waypoints[1:])
        elif len(tr.waypoints) > 1:
            self.segments.append(Segment("transfer", None, tr.waypoints))
        self.q, self.grasp = tr.waypoints[-1].q, grasp
        return True

    def _resync(self, pose: FloatArray, target: GraspContacts) -> None:
        """Regrasp fingers that drifted far from the GSn path's contacts, where possible.

        Transfers keep the grasp while the path's contacts slide on; a grasp
        far from the path's can no longer be regrasped onto it finger by
        finger, so fingers more than ``settings.resync_m`` away are moved back
        (each only when its landing keeps every (n-1) subgrasp force closure).
        """
        trans = self.trans
        gap = np.linalg.norm(self.grasp.points - target.points, axis=1)
        for f in np.argsort(-gap):
            if gap[f] <= self.settings.resync_m:
                break
            f = int(f)
            new = self.grasp.replace(f, target.points[f], target.normals_out[f])
            if trans.grasp_quality(new, exact=True) <= trans.validity.fc_margin:
                continue
            point, normal = target.points[f], target.normals_out[f]
            seg = trans.regrasp(pose, self.q, self.grasp, f, point, normal)
            if seg is not None:
                self.segments.append(seg)
                self.regrasps += 1
                self.q, self.grasp = seg.end.q, new

    def _regrasps_to(
        self, pose: FloatArray, target: GraspContacts
    ) -> tuple[list[Segment], FloatArray, GraspContacts] | None:
        """:func:`regrasps_onto` from the current grasp; None also when it is ``target``.

        (The same grasp: the transfer on it already failed.)
        """
        out = regrasps_onto(
            self.trans, pose, self.q, self.grasp, target, self.settings.same_contact_m
        )
        return None if out is None or not out[0] else out

    def _midpoint(
        self, pa: FloatArray, ca: GraspContacts, pb: FloatArray, cb: GraspContacts
    ) -> tuple[FloatArray, GraspContacts]:
        """GSn midpoint of an edge: the object pose slerp and the contacts halfway.

        The contacts per the current midpoint interpolation
        (:attr:`ReductionSettings.midpoints`): halfway along each contact's
        surface geodesic (object frame, :class:`ContactPaths`), or as OMPL's
        projected interpolation moves them (interpolating the hand joints
        moves the fingertips roughly along the chord between their world
        positions: the world fingertip centres are averaged and projected
        onto the surface).
        """
        trans = self.trans
        pm = interpolate_pose(pa, pb, 0.5)
        if self.midpoint == "geodesic":
            halfway = self.contact_paths.between(ca, cb, 0.5)
            if halfway is not None:
                self.geodesic_midpoints += 1
                return pm, halfway
        tips_world = 0.5 * (trans.tip_targets(pa, ca) + trans.tip_targets(pb, cb))
        pts, n_out = trans.obj.closest_point(inverse_transform_points(pm, tips_world))
        return pm, GraspContacts(np.asarray(pts).reshape(-1, 3), np.asarray(n_out).reshape(-1, 3))
