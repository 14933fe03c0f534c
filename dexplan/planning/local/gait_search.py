"""Finger gaits planned over the whole object trajectory: a beam search.

A plan's regrasps are set by the fingers' strokes: a finger that lands on a
contact follows the object from there until a joint limit, its reach or its
links stop it, and is then regrasped. Covering the trajectory with strokes
takes fewest regrasps when each landing makes its stroke end as late as
possible (interval covering), but a regrasp must also leave the other
fingers holding the object within the joints' effort limits, and a landing
that gives one finger a long stroke can leave another boxed in. One finger
at a time, as the paper's reduction does, those choices go wrong a few
degrees later.

The search runs over gait states ``(trajectory step, hand configuration,
grasp)``, layer by layer in the number of regrasps made, keeping the
:attr:`GaitSettings.beam_width` best states of each layer:

1. from a state, one transfer follows the trajectory until a finger blocks;
2. the children are regrasps of that finger where it blocks onto
   :attr:`GaitSettings.branching` of its landings: among those of longest
   stroke, the ones whose stroke is at least
   :attr:`GaitSettings.strength_tolerance` of the longest, strongest grasp
   first (the grasp's least (n-1)-subgrasp force-closure quality); where the
   other fingers cannot hold the object without it there, the finger is
   regrasped *before* it blocks, at the latest step of the transfer where
   they can (the transfer is cut there); where the finger has no landing
   at all, the children are regrasps of the other fingers where it blocks
   (one may clear its way or make the hold), which are regrasps without
   object progress;
3. states are ranked by the stroke the gait has secured: the sum over the
   fingers of the step where each one's current stroke ends. A regrasp
   without object progress survives only where it secures more stroke than
   the alternatives with as many regrasps, i.e. where it is what lets the
   gait go on;
4. the first layer in which a state's transfer reaches the end of the
   trajectory gives the plan: the fewest regrasps the beam found, and among
   those the one whose weakest grasp is strongest;
5. where every state of a layer is a dead end (no feasible regrasp, or
   only back to a state the search has been in), the search goes back to
   the states ranked out of earlier layers that got farthest.

The search is deterministic for a given random stream (landing samples).
When it finds no gait, :func:`~dexplan.planning.local.reduction.reduce_object_path`
falls back on the one-regrasp-at-a-time reduction.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from dexplan.core.segments import Segment, SegmentKind
from dexplan.core.typing import FloatArray
from dexplan.model.grasp.rolling import ContactMotion
from dexplan.planning.local.grasps import current_follow, grasp_from_state
from dexplan.planning.local.transitions import GraspContacts, TransferResult, Transitions

__all__ = ["GaitSearchResult", "search_gaits"]

#: Steps between the transfer's waypoints tried, backwards, for an earlier release.
_RELEASE_STRIDE = 2
#: Earlier release steps tried at most per blocked transfer.
_RELEASE_TRIES = 8
#: Steps of stroke a regrasp of a finger other than the blocked one must gain.
_MIN_GAIN = 2
#: Gait states expanded without any getting farther along the trajectory
#: before the search gives up (the one-regrasp-at-a-time reduction, with its
#: backtracking, then has the rest of the time).
_STALL_STATES = 45


@dataclass(frozen=True)
class GaitSearchResult:
    """Outcome of :func:`search_gaits`.

    Attributes:
        segments: the transfers and regrasps of the gait found (empty: none).
        reached: the farthest trajectory step any state reached.
        reason: why no gait was found, None on success.
        expanded: gait states expanded.
    """

    segments: tuple[Segment, ...]
    reached: int
    reason: str | None
    expanded: int


@dataclass(frozen=True)
class _State:
    """A gait state: where the gait stands after a regrasp (or at the start).

    Attributes:
        idx: trajectory step.
        q: (nq,) the hand's joints.
        grasp: the contacts, object frame.
        cover: per finger, the trajectory step where its current stroke ends.
        segments: the gait's segments so far.
        regrasps: regrasps among them.
        strength: least force-closure quality of the grasp's (n-1)-subgrasps.
        viable: the finger that stops the next transfer can be let go
            where it stops (the others hold the object without it): a
            state where it cannot needs regrasps without progress later.
        transfer: the transfer from here, once run (:func:`_evaluate`).
        weakest: the least ``strength`` of the gait's grasps so far.
    """

    idx: int
    q: FloatArray
    grasp: GraspContacts
    cover: tuple[int, ...]
    segments: tuple[Segment, ...]
    regrasps: int
    strength: float
    viable: bool = True
    transfer: TransferResult | None = None
    weakest: float = np.inf

    def rank(self, end: int) -> tuple[bool, int, int, float]:
        """Beam order (larger first): viable, stroke secured, progress, weakest grasp."""
        return (self.viable, sum(min(c, end) for c in self.cover), self.idx, self.weakest)


def search_gaits(
    trans: Transitions,
    poses: FloatArray,
    q_start: FloatArray,
    grasp: GraspContacts,
    *,
    beam_width: int,
    branching: int,
    max_regrasps: int,
    max_expanded: int,
    tolerance: float = 0.85,
) -> GaitSearchResult:
    """The gait with fewest regrasps the beam search finds along ``poses``.

    Args:
        trans: local planners.
        poses: (P, 7) dense object trajectory, world frame, XYZW.
        q_start: (nq,) the hand holding ``grasp`` at ``poses[0]``.
        grasp: the start contacts, object frame.
        beam_width: gait states kept per number of regrasps.
        branching: landings of longest stroke tried per regrasped finger.
        max_regrasps: give up past this many regrasps.
        max_expanded: give up after expanding this many gait states.
        tolerance: landings whose stroke is at least this share of the
            longest one's are tried strongest grasp first.
    """
    end = len(poses) - 1
    n = trans.hand.n_fingers
    cover = tuple(current_follow(trans, f, q_start, grasp, poses) for f in range(n))
    strength = trans.grasp_quality(grasp)
    first = _State(0, q_start.copy(), grasp, cover, (), 0, strength, weakest=strength)
    layer = _evaluate(trans, poses, [first])
    reached, expanded, progressed = 0, 0, 0
    seen: set[tuple[int, bytes]] = set()
    reserve: list[_State] = []  # states ranked out of their layer, for dead ends
    for _ in range(2 * max_regrasps + 1):
        if trans.deadline.expired():
            return GaitSearchResult((), reached, "time limit reached", expanded)
        farthest = max([reached, *(s.transfer.reached for s in layer if s.transfer)])
        if farthest > reached:
            reached, progressed = farthest, expanded
        layer = [s for s in layer if s.regrasps <= max_regrasps]
        gait = _finished(layer)
        if gait is not None:
            return GaitSearchResult(gait, end, None, expanded)
        if expanded >= max_expanded:
            break
        if expanded - progressed > _STALL_STATES:
            why = f"no progress past trajectory step {reached} in {_STALL_STATES} gait states"
            return GaitSearchResult((), reached, why, expanded)
        children: list[_State] = []
        for state in layer:
            expanded += 1
            tr = state.transfer
            if tr is not None and tr.blocking is not None:
                children.extend(_children(trans, poses, state, tr, branching, tolerance))
        layer, spare = _beam(trans, poses, _unseen(children, seen), beam_width, end)
        reserve.extend(s for s in spare if s.regrasps < max_regrasps)
        if not layer:
            # every kept state is a dead end: go back to the states left out
            # that got farthest
            reserve = _evaluated(trans, poses, reserve)
            reserve.sort(key=lambda s: (s.idx, s.rank(end)), reverse=True)
            layer, reserve = reserve[:beam_width], reserve[beam_width:]
        if not layer:
            return GaitSearchResult((), reached, "no gait state has a feasible regrasp", expanded)
    why = f"no gait within {max_regrasps} regrasps and {max_expanded} gait states"
    return GaitSearchResult((), reached, why, expanded)


def _finished(layer: list[_State]) -> tuple[Segment, ...] | None:
    """The gait of the state of ``layer`` whose transfer reaches the end, or None.

    They have as many regrasps each: the one whose weakest grasp is strongest.
    """
    done = [s for s in layer if s.transfer is not None and s.transfer.reason is None]
    if not done:
        return None
    best = max(done, key=lambda s: s.weakest)
    assert best.transfer is not None
    return (*best.segments, *_transfer(best.transfer, len(best.transfer.waypoints)))


def _unseen(children: list[_State], seen: set[tuple[int, bytes]]) -> list[_State]:
    """The children whose (step, grasp) no earlier state had (recorded in ``seen``).

    A grasp is keyed by its contacts to the millimetre: a gait that comes
    back to a state it left is going round in circles.
    """
    out = []
    for c in children:
        key = (c.idx, np.round(c.grasp.points, 3).tobytes())
        if key not in seen:
            seen.add(key)
            out.append(c)
    return out


def _beam(
    trans: Transitions, poses: FloatArray, states: list[_State], width: int, end: int
) -> tuple[list[_State], list[_State]]:
    """The ``width`` best of ``states`` by :meth:`_State.rank` once evaluated, and the others.

    Running a state's transfer (:func:`_evaluate`) can only lower its rank:
    the finger that blocks secures no more stroke than its landing promised,
    and it may not be let go there. So the states are evaluated best
    promise first, and those whose promise ranks below ``width`` evaluated
    states are left unevaluated (their transfers are the search's largest
    cost): the beam is the one evaluating all of them would give, in the
    same order. The others are returned too, evaluated or not
    (:func:`_evaluated` runs the rest if the search comes back to them).
    """
    promise = [s.rank(end) for s in states]
    done: dict[int, _State | None] = {}
    for i in sorted(range(len(states)), key=lambda i: promise[i], reverse=True):
        ranks = sorted((d.rank(end) for d in done.values() if d is not None), reverse=True)
        if len(ranks) >= width and ranks[width - 1] > promise[i]:
            break  # this promise and every one after it rank below the beam
        out = _evaluate(trans, poses, [states[i]])
        done[i] = out[0] if out else None
    kept: list[_State] = []
    for i, s in enumerate(states):
        d = done.get(i, s)  # evaluated, dropped by the evaluation (None), or left
        if d is not None:
            kept.append(d)
    ranked = sorted(
        (s for s in kept if s.transfer is not None), key=lambda s: s.rank(end), reverse=True
    )
    return ranked[:width], ranked[width:] + [s for s in kept if s.transfer is None]


def _evaluated(trans: Transitions, poses: FloatArray, states: list[_State]) -> list[_State]:
    """``states``, those not yet evaluated by :func:`_beam` evaluated (dropped where it drops)."""
    out = []
    for s in states:
        out.extend([s] if s.transfer is not None else _evaluate(trans, poses, [s]))
    return out


def _evaluate(trans: Transitions, poses: FloatArray, states: list[_State]) -> list[_State]:
    """``states`` with their transfers run: where each truly blocks, and whether it can let go.

    The stroke a landing promises is the finger's alone, in the posture the
    landing search tracked; the transfer moves every finger together and
    tells where the first one really stops. ``viable``: the others hold the
    object without that finger where it stops.
    """
    out = []
    for s in states:
        if trans.deadline.expired():
            break
        tr = trans.transfer(poses, s.idx, s.q, s.grasp)
        landed = s.segments[-1].finger if s.segments else None
        if landed is not None and tr.reached == s.idx and tr.blocking == landed:
            continue  # the finger just landed blocks at once: the regrasp gained nothing
        cover, viable = list(s.cover), True
        if tr.blocking is not None:
            f = tr.blocking
            cover[f] = min(cover[f], tr.reached)
            viable = trans.can_release(f, poses[tr.reached], tr.waypoints[-1].q, tr.grasp)
        out.append(dataclasses.replace(s, cover=tuple(cover), viable=viable, transfer=tr))
    return out


def _transfer(tr: TransferResult, upto: int) -> tuple[Segment, ...]:
    """The transfer segment of ``tr``'s first ``upto`` waypoints (none if it does not move)."""
    if upto <= 1:
        return ()
    return (Segment(SegmentKind.TRANSFER, None, tuple(tr.waypoints[:upto])),)


def _children(
    trans: Transitions,
    poses: FloatArray,
    state: _State,
    tr: TransferResult,
    branching: int,
    tolerance: float,
) -> list[_State]:
    """The regrasps after transfer ``tr`` from ``state`` (see the module, step 2)."""
    f = tr.blocking
    assert f is not None
    # state.cover already ends f's stroke where it blocked, and state.viable
    # says whether it can be let go there (:func:`_evaluate`)
    cover = state.cover
    at = _release_step(trans, poses, state, tr, f)
    if at is not None:
        kids = _regrasps_of(trans, poses, state, tr, at, f, cover, branching, None, tolerance)
        if kids:
            return kids
    # the finger cannot be regrasped: move another where it blocks, one that
    # gains stroke or makes the hold that lets the blocked finger go
    at_block = (len(tr.waypoints) - 1, tr.reached)
    out: list[_State] = []
    # a finger regrasped twice where the object has not moved in between is
    # one regrasp onto the second landing done twice: never a child
    last = state.segments[-1].finger if state.segments and tr.reached == state.idx else None
    others = sorted(
        (g for g in range(trans.hand.n_fingers) if g not in (f, last)), key=lambda g: cover[g]
    )
    for g in others:
        out.extend(
            _regrasps_of(
                trans, poses, state, tr, at_block, g, cover, 1, (f, state.viable), tolerance
            )
        )
    return out


def _release_step(
    trans: Transitions, poses: FloatArray, state: _State, tr: TransferResult, finger: int
) -> tuple[int, int] | None:
    """Where ``finger`` is regrasped, as ``(waypoint of tr, trajectory step)``, or None.

    Where it blocks when the others hold the object there without it
    (``state.viable``); otherwise the latest earlier trajectory pose of the
    transfer (every :data:`_RELEASE_STRIDE`-th, at most :data:`_RELEASE_TRIES`)
    where they do.
    """
    steps = _pose_waypoints(poses, state.idx, tr)
    if state.viable:
        return steps[-1]
    for k, j in steps[-1 - _RELEASE_STRIDE :: -_RELEASE_STRIDE][: _RELEASE_TRIES - 1]:
        g = _grasp_at(trans, poses, tr, k, j)
        if trans.can_release(finger, poses[j], tr.waypoints[k].q, g):
            return k, j
    return None


def _pose_waypoints(poses: FloatArray, start: int, tr: TransferResult) -> list[tuple[int, int]]:
    """``(waypoint, trajectory step)`` of ``tr``'s waypoints that are trajectory poses.

    A transfer subdivides a step whose joints move too far: the waypoints
    in between are not poses of the trajectory.
    """
    out = [(0, start)]
    j = start + 1
    for k in range(1, len(tr.waypoints)):
        if j < len(poses) and np.array_equal(tr.waypoints[k].object_pose_xyzquat, poses[j]):
            out.append((k, j))
            j += 1
    return out


def _grasp_at(
    trans: Transitions, poses: FloatArray, tr: TransferResult, k: int, j: int
) -> GraspContacts:
    """The contacts at ``tr``'s waypoint ``k`` (step ``j``): the transfer's, or the rolled ones."""
    if k == len(tr.waypoints) - 1 or trans.settings.contact_motion == ContactMotion.FIXED:
        return tr.grasp
    return grasp_from_state(trans, poses[j], tr.waypoints[k].q)


def _regrasps_of(
    trans: Transitions,
    poses: FloatArray,
    state: _State,
    tr: TransferResult,
    at: tuple[int, int],
    finger: int,
    cover: tuple[int, ...],
    most: int,
    blocked: tuple[int, bool] | None,
    tolerance: float,
) -> list[_State]:
    """Children regrasping ``finger`` at ``at = (waypoint of tr, step)``.

    Of the finger's landings of longest stroke, those whose stroke is at
    least ``tolerance`` of the longest come first, strongest grasp first
    (the least force-closure quality of its (n-1)-subgrasps: where a real
    hand drops the object), then the others by stroke.

    ``blocked = (finger, held)``: the regrasp is made for a blocked finger
    that cannot be regrasped itself (``held``: the others could let it go
    there); it must then let that finger go where it could not, or lengthen
    the regrasped finger's stroke by :data:`_MIN_GAIN` steps.
    """
    k, idx = at
    w = tr.waypoints[k]
    grasp = _grasp_at(trans, poses, tr, k, idx)
    future = poses[idx:]
    head = (*state.segments, *_transfer(tr, k + 1))
    landings = [
        (point, normal, int(score), trans.grasp_quality(grasp.replace(finger, point, normal)))
        for point, normal, score in trans.landing_candidates(
            finger, poses[idx], w.q, grasp, future, None, 2 * most + 2
        )
        if score > 0
    ]
    if not landings:
        return []
    far = tolerance * max(t[2] for t in landings)
    landings.sort(key=lambda t: (t[2] >= far, t[3] if t[2] >= far else t[2]), reverse=True)
    out: list[_State] = []
    for point, normal, score, quality in landings:
        seg = trans.regrasp(poses[idx], w.q, grasp, finger, point, normal)
        if seg is None:
            continue
        new = grasp.replace(finger, point, normal)
        if blocked is not None and idx + score < cover[finger] + _MIN_GAIN:
            b, held = blocked
            if held or not trans.can_release(b, poses[idx], seg.end.q, new):
                continue
        c = list(cover)
        c[finger] = idx + score
        out.append(
            _State(
                idx,
                seg.end.q,
                new,
                tuple(c),
                (*head, seg),
                state.regrasps + 1,
                quality,
                weakest=min(state.weakest, quality),
            )
        )
        if len(out) >= most or trans.deadline.expired():
            break
    return out
