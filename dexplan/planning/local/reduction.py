"""Reduction of a dense object trajectory to finger gaits (paper, section IV).

The reduction property says a path in valid GSn can be replaced by a finite
alternation of transfer and regrasp paths. On symmetric objects the GSn path
itself mostly slides the contacts, so the physical plan is made here, and made
to look like a finger gait:

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
works or no progress is made. The paper's own edge-by-edge reduction, the
fallback, is :mod:`dexplan.planning.local.edge_reduction`; the settings, the
result and the regrasps onto given contacts here serve both.
"""

from __future__ import annotations

import enum
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import cast

from dexplan.core.errors import InvalidInputError
from dexplan.core.segments import Segment, SegmentKind
from dexplan.core.typing import FloatArray
from dexplan.planning.local.gait_choice import (
    GaitSettings,
    RegraspOption,
    best_option,
    look_ahead,
)
from dexplan.planning.local.gait_search import search_gaits
from dexplan.planning.local.grasps import current_follow
from dexplan.planning.local.transitions import (
    GraspContacts,
    LandingPool,
    TransferResult,
    TransferStop,
    Transitions,
)

#: Landings of another finger tried by the look-ahead (:attr:`RegraspPass.ENABLE`).
_ENABLE_LANDINGS = 12
#: Landings of a finger tried by the other passes.
_LANDINGS = 8


class Reduction(enum.StrEnum):
    """How a GSn path becomes transfers and regrasps (the planner's ``reduction``).

    Attributes:
        AUTO: finger gaits, then the edge-by-edge reduction when they fail.
        GAITS: finger gaits along the object trajectory (:func:`reduce_object_path`).
        EDGES: the reduction property edge by edge with bisection
            (:func:`~dexplan.planning.local.edge_reduction.reduce_gsn_path`).
    """

    AUTO = "auto"
    GAITS = "gaits"
    EDGES = "edges"


class PathSource(enum.StrEnum):
    """Which object trajectory a reduction attempt follows.

    Attributes:
        SHORTCUT: the GSn path's object trajectory shortcut into straight pieces.
        RAW: the GSn path's object trajectory as it is.
        GSN: the GSn path itself, states and contacts (the edge-by-edge reduction).
    """

    SHORTCUT = "shortcut"
    RAW = "raw"
    GSN = "gsn"


class Midpoint(enum.StrEnum):
    """How a bisected GSn edge's midpoint places the contacts (:attr:`ReductionSettings.midpoints`).

    Attributes:
        CHORD: the world fingertip centres averaged and projected onto the
            surface (as OMPL's projected interpolation moves them).
        GEODESIC: each contact halfway along its surface geodesic (meshes
            with geodesics only; the paper's section VI).
    """

    CHORD = "chord"
    GEODESIC = "geodesic"


MIDPOINTS: tuple[Midpoint, ...] = tuple(Midpoint)
"""Contact interpolations of :attr:`ReductionSettings.midpoints`."""


class RegraspPass(enum.StrEnum):
    """What a regrasp's landing must do (:func:`_passes`).

    Attributes:
        GAIN: the finger follows further than it does now.
        ENABLE: afterwards the blocking finger has a landing of its own.
        ANY: any landing (moving a finger out of the way may clear the
            blocking finger's path in other ways).
    """

    GAIN = "gain"
    ENABLE = "enable"
    ANY = "any"


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
            starting the trajectory again, which meets the same stalls.
        max_blind: give up after this many regrasps since the last object
            progress that moved a finger other than the blocking one without
            giving the blocking one a landing (the look-ahead found none; see
            :func:`_passes`). Each costs a look-ahead (about a second on a
            box), and a long run of them rarely ends in progress where a fresh
            attempt often does; module 2's link tests run this reduction too,
            so a small limit saves time without losing solutions.
        regrasp_retries: a regrasp search that finds no feasible regrasp is
            run again this many times (the landing candidates are random
            samples; a fresh set often holds one) before the reduction gives up.
        backtracks: when the finger gaits get stuck (no feasible regrasp,
            ``max_stall`` or ``max_blind``), go back this many times at most
            to the hand's state after an earlier transfer, at least
            ``backtrack_steps`` trajectory steps before the stuck one, and go
            on from there with fresh random landings: where the fingers
            stand when they reach a hard stretch decides whether they pass
            it (a finger blocked on most grasps that reach a stretch passes
            it on others). Gaits stuck within
            ``backtrack_steps`` of the start give up at once: the start grasp
            itself is the trouble, which the caller changes (module 2).
        backtrack_steps: see ``backtracks``.
        max_depth: resolution limit of the edge-by-edge reduction
            (:func:`~.edge_reduction.reduce_gsn_path`): a GSn edge is bisected
            at most this many times (into at most ``2**max_depth`` pieces).
        same_contact_m: contacts closer than this (m, object frame) count as
            the same; no regrasp moves a finger by less.
        resync_m: in the edge-by-edge reduction, a finger whose contact is
            farther than this (m) from the GSn path's is regrasped back onto it.
        midpoints: how the edge-by-edge reduction places the contacts of a
            bisected edge's midpoint, tried in this order per GSn edge (an
            edge that fails with one is reduced again, from the same state,
            with the next): ``chord`` (the world fingertip centres averaged
            and projected onto the surface, as OMPL's projected interpolation
            moves them) and ``geodesic`` (on a mesh, each contact halfway
            along its surface geodesic, the paper's section VI; skipped on
            primitives and on meshes without geodesics). ``chord`` first
            solves more edges than ``geodesic`` first, and the second then
            only adds solutions; strings equal to the members are accepted.
        gaits: how regrasps are compared (by the transfer each allows, then
            grasp strength) and when a finger is reset before it blocks
            (:mod:`dexplan.planning.local.gait_choice`).
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
    midpoints: tuple[Midpoint, ...] = MIDPOINTS
    gaits: GaitSettings = field(default_factory=GaitSettings)

    def __post_init__(self) -> None:
        bad = [m for m in self.midpoints if m not in MIDPOINTS]
        if bad or not self.midpoints:
            raise InvalidInputError(
                f"midpoints must be a non-empty sequence of {', '.join(MIDPOINTS)}, "
                f"got {self.midpoints!r}"
            )
        object.__setattr__(self, "midpoints", tuple(Midpoint(m) for m in self.midpoints))


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
    if settings.gaits.beam_width > 0:
        searched = _search(trans, poses, q_start, grasp, settings)
        if searched is not None:
            return searched
    gait = _GaitState(trans, settings, q_start, grasp)
    reset: int | None = None  # a finger to regrasp before the next transfer
    while True:
        if trans.deadline.expired():
            return gait.result("time limit reached")
        tr: TransferResult | None = None
        if reset is None:
            tr = gait.transfer(poses)
            if tr.reason is None:
                return gait.result(None)
            if tr.blocking is None:
                reason = f"transfer blocked: {tr.reason}"
                return gait.result(reason, final=tr.reason == TransferStop.OBJECT_COLLISION)
        blocking = tr.blocking if tr is not None else reset
        assert blocking is not None
        hint_row = None if hints is None else hints[min(gait.idx, len(hints) - 1)]
        found = _regrasp_retrying(
            trans,
            poses,
            gait.idx,
            gait.q,
            gait.grasp,
            blocking,
            hint_row,
            settings.regrasp_retries,
            settings.gaits,
        )
        reset = None
        if found is None:
            if tr is None:
                continue  # no reset there: transfer to where the finger blocks
            why = _no_regrasp(gait.idx, tr)
            if gait.backtrack():
                continue
            return gait.result(why)
        seg, new, mode, option = found
        gait.regrasped(seg, new, mode)
        if gait.regrasps > settings.max_regrasps:
            return gait.result(gait.no_progress())
        stuck = gait.stuck(blocking)
        if stuck is not None and not gait.backtrack():
            return gait.result(stuck)
        reset = _reset_finger(option, settings.gaits)


def _search(
    trans: Transitions,
    poses: FloatArray,
    q_start: FloatArray,
    grasp: GraspContacts,
    settings: ReductionSettings,
) -> ReductionResult | None:
    """The gait search's plan (:mod:`dexplan.planning.local.gait_search`), or None."""
    g = settings.gaits
    found = search_gaits(
        trans,
        poses,
        q_start,
        grasp,
        beam_width=g.beam_width,
        branching=g.branching,
        max_regrasps=settings.max_regrasps,
        max_expanded=g.search_states,
        tolerance=g.strength_tolerance,
    )
    if found.reason is not None:
        return None
    regrasps = sum(s.kind == SegmentKind.REGRASP for s in found.segments)
    return ReductionResult(
        True, found.segments, len(poses) - 1, None, reduction_stats(trans, regrasps)
    )


def _reset_finger(option: RegraspOption | None, settings: GaitSettings) -> int | None:
    """The finger to regrasp before transferring: one that would block within ``reset_steps``."""
    if option is None or option.blocking in (None, option.seg.finger):
        return None
    return option.blocking if 0 < option.reach < settings.reset_steps else None


def _no_regrasp(idx: int, tr: TransferResult) -> str:
    """The failure reason when no regrasp lets the transfer blocked at step ``idx`` go on."""
    return (
        f"no feasible regrasp at trajectory step {idx} (blocked by finger "
        f"{tr.blocking}: {tr.reason})"
    )


class _GaitState:
    """State of :func:`reduce_object_path`: segments so far, the hand's state, counters.

    Attributes:
        segments: the transfer and regrasp segments kept.
        idx: index of the current pose in the dense trajectory.
        q: (nq,) the hand's joints there.
        grasp: the contacts held there, object frame.
        regrasps: regrasps among ``segments``.
        stall: regrasps since the object last moved.
        blind: regrasps since the object last moved that moved another
            finger than the blocking one without giving it a landing.
        checkpoints: ``(segments kept, idx, q, grasp)`` after each transfer
            that moved the object (and the start), for backtracking.
        backtracks: backtracks made.
    """

    def __init__(
        self,
        trans: Transitions,
        settings: ReductionSettings,
        q_start: FloatArray,
        grasp: GraspContacts,
    ) -> None:
        self.trans = trans
        self.settings = settings
        self.segments: list[Segment] = []
        self.idx = 0
        self.q = q_start.copy()
        self.grasp = grasp
        self.regrasps = self.stall = self.blind = 0
        self.checkpoints: list[tuple[int, int, FloatArray, GraspContacts]] = [
            (0, 0, self.q.copy(), grasp)
        ]
        self.backtracks = 0

    def result(self, reason: str | None, *, final: bool = False) -> ReductionResult:
        """The outcome so far: success when ``reason`` is None."""
        stats = reduction_stats(self.trans, self.regrasps)
        return ReductionResult(
            reason is None, tuple(self.segments), self.idx, reason, stats, final=final
        )

    def transfer(self, poses: FloatArray) -> TransferResult:
        """Transfer along ``poses`` from the current step for as long as it stays valid."""
        tr = self.trans.transfer(poses, self.idx, self.q, self.grasp)
        moved = len(tr.waypoints) > 1
        if moved:
            self.segments.append(Segment(SegmentKind.TRANSFER, None, tr.waypoints))
            self.stall = self.blind = 0
        self.idx, self.q, self.grasp = tr.reached, tr.waypoints[-1].q, tr.grasp
        if moved:
            self.checkpoints.append((len(self.segments), self.idx, self.q.copy(), self.grasp))
        return tr

    def regrasped(self, seg: Segment, grasp: GraspContacts, mode: RegraspPass) -> None:
        """Keep a regrasp found by :func:`_regrasp_retrying` in pass ``mode``."""
        self.segments.append(seg)
        self.grasp = grasp
        self.q = seg.end.q
        self.regrasps += 1
        self.stall += 1
        self.blind += mode == RegraspPass.ANY

    def no_progress(self) -> str:
        """The failure reason of too many regrasps."""
        return f"no progress after {self.regrasps} regrasps at trajectory step {self.idx}"

    def stuck(self, blocking: int) -> str | None:
        """Why the gaits are stuck (``max_stall`` or ``max_blind`` passed), or None."""
        if self.stall > self.settings.max_stall:
            return self.no_progress()
        if self.blind > self.settings.max_blind:
            return (
                f"no landing for finger {blocking} at trajectory step {self.idx} after "
                f"{self.blind} moves of other fingers"
            )
        return None

    def backtrack(self) -> bool:
        """Go back to an earlier checkpoint (True), or not (False: give up).

        Not near the start (the start grasp itself is the trouble, another
        grasp's turn), nor past the deadline or the settings' backtracks.
        """
        s = self.settings
        if (
            self.backtracks >= s.backtracks
            or self.idx < s.backtrack_steps
            or self.trans.deadline.expired()
        ):
            return False
        self.backtracks += 1
        self.trans.stats["backtracks"] += 1
        # the latest checkpoint far enough back (checkpoints go forward in idx)
        limit = self.idx - s.backtrack_steps
        k = max((i for i, c in enumerate(self.checkpoints) if c[1] <= limit), default=0)
        kept, self.idx, q, self.grasp = self.checkpoints[k]
        del self.checkpoints[k + 1 :]
        self.segments = self.segments[:kept]
        self.q = q.copy()
        self.regrasps = sum(seg.kind == "regrasp" for seg in self.segments)
        self.stall = self.blind = 0
        return True


def _regrasp_retrying(
    trans: Transitions,
    poses: FloatArray,
    idx: int,
    q: FloatArray,
    grasp: GraspContacts,
    blocking: int,
    hint_row: FloatArray | None,
    retries: int,
    gaits: GaitSettings,
) -> _Found | None:
    """:func:`_regrasp_one`, run again up to ``retries`` times while it finds nothing.

    The landing candidates are random samples: a fresh set often holds a
    feasible regrasp. Stops at the deadline.
    """
    for _ in range(1 + retries):
        found = _regrasp_one(trans, poses, idx, q, grasp, blocking, hint_row, gaits)
        if found is not None or trans.deadline.expired():
            return found
    return None


#: A regrasp found: the segment, the grasp after it, its pass, and its look-ahead
#: (None where the first feasible landing was taken).
_Found = tuple[Segment, GraspContacts, "RegraspPass", RegraspOption | None]


def _regrasp_one(
    trans: Transitions,
    poses: FloatArray,
    idx: int,
    q: FloatArray,
    grasp: GraspContacts,
    blocking: int,
    hint_row: FloatArray | None,
    gaits: GaitSettings,
) -> _Found | None:
    """One regrasp that lets the transfer blocked at ``poses[idx]`` go on, or None.

    The blocking finger first, then the others, least remaining follow first
    (the others' follows only when the blocking finger cannot move: it
    usually can, and tracking them costs more than the rest); see
    :func:`_passes`. ``hint_row: (n, 6)`` the GSn path's contact point and
    outward normal per finger there (object frame), offered as landings.
    A regrasp of another finger must leave a grasp from which the blocking
    finger can be let go (:meth:`Transitions.can_release`): under real
    effort limits, moving a neighbour is often what makes the hold strong
    enough. In the :attr:`RegraspPass.GAIN` passes the first
    ``gaits.lookahead_landings`` feasible regrasps of a finger are compared
    by the transfer each allows (:func:`~.gait_choice.best_option`).

    Returns:
        ``(regrasp segment, new grasp, pass, look-ahead)``, the pass as
        :func:`_passes` names it.
    """
    future = poses[idx:]
    others = [i for i in range(trans.hand.n_fingers) if i != blocking]
    # where the blocking finger can be let go now, moving another keeps that
    # (checked in full when it is let go); else a move must make it so
    held = trans.can_release(blocking, poses[idx], q, grasp)
    follow: dict[int, int] = {}
    pool: LandingPool | None = None
    for f, mode in _passes(blocking, others, follow, trans, q, grasp, future):
        if not trans.can_release(f, poses[idx], q, grasp):
            continue  # the other fingers cannot hold the object within the effort limits
        hint = None if hint_row is None else (hint_row[f, :3], hint_row[f, 3:])
        limit = _ENABLE_LANDINGS if mode == RegraspPass.ENABLE else _LANDINGS
        options: list[RegraspOption] = []
        for point, normal, score in trans.landing_candidates(
            f, poses[idx], q, grasp, future, hint, limit
        ):
            if f != blocking and mode == RegraspPass.GAIN and score <= follow[f]:
                break  # moving this finger would not help it follow further
            new = grasp.replace(f, point, normal)
            if mode == RegraspPass.ENABLE:
                if pool is None:
                    pool = trans.landing_pool(blocking, poses[idx], future)
                if pool is None:
                    break  # the blocking finger reaches nothing it could follow from
                if not trans.can_land(blocking, q, new, pool, future):
                    continue
            seg = trans.regrasp(poses[idx], q, grasp, f, point, normal)
            if seg is None:
                continue
            if (
                f != blocking
                and not held
                and not trans.can_release(blocking, poses[idx], seg.end.q, new)
            ):
                continue  # the blocking finger still could not be let go
            if mode != RegraspPass.GAIN or gaits.lookahead_landings <= 1:
                return seg, new, mode, None
            options.append(look_ahead(trans, poses, idx, seg, new, gaits))
            if len(options) >= gaits.lookahead_landings or options[-1].blocking is None:
                break
        best = best_option(options, gaits, blocking)
        if best is not None:
            return best.seg, best.grasp, mode, best
    return None


def _passes(
    blocking: int,
    others: list[int],
    follow: dict[int, int],
    trans: Transitions,
    q: FloatArray,
    grasp: GraspContacts,
    future: FloatArray,
) -> Iterator[tuple[int, RegraspPass]]:
    """Fingers to regrasp, in order, with what their landing must do.

    :attr:`RegraspPass.GAIN`: the blocking finger; then the others, least
    remaining follow first (the follows are computed only here, into
    ``follow``). When nothing works, the others again even onto a landing
    they follow less far from: first :attr:`RegraspPass.ENABLE`, a landing
    after which the blocking finger has one of its own
    (:meth:`Transitions.can_land`: on a box held by two fingers on each of
    two faces, most landings of the blocking finger break some subgrasp's
    force closure, and moving a neighbour where it does not help gives long
    runs of regrasps without progress); then :attr:`RegraspPass.ANY`.
    """
    yield blocking, RegraspPass.GAIN
    follow.update({i: current_follow(trans, i, q, grasp, future) for i in others})
    order = sorted(others, key=lambda i: follow[i])
    for f in order:
        yield f, RegraspPass.GAIN
    for mode in (RegraspPass.ENABLE, RegraspPass.ANY):
        for f in order:
            yield f, mode


def reduction_stats(trans: Transitions, regrasps: int) -> dict[str, int]:
    """The local planners' counters with the reduction's regrasps (``reduction_regrasps``)."""
    # every counter of LocalCounts is an int; a TypedDict is not a dict[str, int] to mypy
    out = dict(cast("Mapping[str, int]", trans.stats))
    out["reduction_regrasps"] = regrasps
    return out
