"""Regrasps chosen by what the whole grasp does next.

A regrasp is judged by the transfer it makes possible: a transfer stops at the
first finger that blocks, so a landing from which the regrasped finger alone
could follow the object a long way is worth little when another finger then
blocks at once. For each of a few feasible regrasps (the landing search's best
by the finger's own follow, :meth:`Transitions.landing_candidates`), the
transfer that would follow is run (links collision-checked, as the plan will
run it) up to a horizon. Among the regrasps whose transfer goes at least
:attr:`GaitSettings.strength_tolerance` of the farthest one's way, the
reduction prefers, in this order:

1. one after which the finger that stops that transfer can be let go: the
   others must hold the object's weight within the joints' effort limits
   there (:meth:`Transitions.can_release`), or the gait must first move
   another finger at that stop;
2. one whose new grasp can let go the most fingers where it is made (the
   holds of the regrasps to come; checked at the stated contacts, a cheap
   screen);
3. one whose grasp reaches :attr:`GaitSettings.strong_quality`;
4. the strongest: the largest least force-closure quality of the grasp's
   (n-1)-finger subgrasps.

A regrasp after which the regrasped finger, or the finger that blocked, stops
the transfer at once gains nothing and is never chosen.

The reduction (:mod:`dexplan.planning.local.reduction`) also uses the
look-ahead to reset a finger *before* it blocks: when the transfer after a
regrasp would stop within :attr:`GaitSettings.reset_steps` steps, the finger
that would stop it is regrasped at once, where the object stands, rather
than after a transfer of a few degrees (the same regrasps, one transfer
fewer, and its landing is chosen for the whole rest of the trajectory).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from dexplan.core.errors import InvalidInputError
from dexplan.core.segments import Segment
from dexplan.core.typing import FloatArray
from dexplan.planning.local.transitions import GraspContacts, Transitions

__all__ = ["GaitSettings", "RegraspOption", "best_option", "look_ahead"]


@dataclass(frozen=True)
class GaitSettings:
    """How regrasps are compared (:func:`best_option`).

    Attributes:
        lookahead_landings: feasible regrasps of the finger to move compared
            by the transfer each allows (1: the first feasible one, the
            finger's own longest follow).
        horizon_steps: trajectory steps a look-ahead transfer runs at most;
            a regrasp that lets the grasp follow this far is as good as any.
        strength_tolerance: regrasps whose transfer reaches at least this
            share of the farthest one's are ranked by grasp strength.
        reset_steps: a finger that would stop the next transfer within this
            many trajectory steps is regrasped first (0: never).
        strong_quality: regrasps whose grasp's least (n-1)-subgrasp
            force-closure quality reaches this are preferred to weaker ones
            however far those go (0: strength only breaks ties of reach).
        beam_width: gait states the gait search keeps per number of
            regrasps (:mod:`dexplan.planning.local.gait_search`; 0: no
            search, the one-regrasp-at-a-time reduction only).
        branching: landings of longest stroke the gait search tries per
            regrasped finger.
        search_states: gait states the search expands at most before the
            reduction falls back on one regrasp at a time.
    """

    lookahead_landings: int = 4
    horizon_steps: int = 160
    strength_tolerance: float = 0.85
    reset_steps: int = 6
    strong_quality: float = 0.0
    beam_width: int = 2
    branching: int = 2
    search_states: int = 150

    def __post_init__(self) -> None:
        if self.lookahead_landings < 1 or self.horizon_steps < 1 or self.reset_steps < 0:
            raise InvalidInputError(
                "lookahead_landings and horizon_steps must be >= 1 and reset_steps >= 0, "
                f"got {self.lookahead_landings}, {self.horizon_steps}, {self.reset_steps}"
            )
        if not 0.0 < self.strength_tolerance <= 1.0:
            raise InvalidInputError(
                f"strength_tolerance must be in (0, 1], got {self.strength_tolerance!r}"
            )


@dataclass(frozen=True)
class RegraspOption:
    """A feasible regrasp and what follows it.

    Attributes:
        seg: the regrasp segment.
        grasp: the contacts after it, object frame.
        reach: trajectory steps the next transfer follows (up to the horizon).
        blocking: the finger that stops that transfer, or None (end or horizon).
        strength: least force-closure quality of the grasp's (n-1)-finger subgrasps.
        releases: the finger that stops the transfer can be let go where it
            stops (True when nothing stops it).
        free: fingers the new grasp can let go where it is made.
    """

    seg: Segment
    grasp: GraspContacts
    reach: int
    blocking: int | None
    strength: float
    releases: bool = True
    free: int = 0


def look_ahead(
    trans: Transitions,
    poses: FloatArray,
    idx: int,
    seg: Segment,
    grasp: GraspContacts,
    settings: GaitSettings,
) -> RegraspOption:
    """The transfer after regrasp ``seg`` (ending on ``grasp``) at trajectory step ``idx``.

    Args:
        trans: local planners.
        poses: (P, 7) dense object trajectory.
        idx: the step the regrasp is made at.
        seg: the regrasp segment.
        grasp: the contacts after it.
        settings: the horizon.
    """
    end = min(len(poses), idx + settings.horizon_steps + 1)
    tr = trans.transfers.transfer(poses[:end], idx, seg.end.q, grasp)
    blocking = tr.blocking if tr.reason is not None else None
    releases = blocking is None or trans.can_release(
        blocking, poses[tr.reached], tr.waypoints[-1].q, tr.grasp
    )
    return RegraspOption(
        seg,
        grasp,
        tr.reached - idx,
        blocking,
        trans.grasp_quality(grasp),
        releases,
        _free_fingers(trans, poses[idx], seg.end.q, grasp),
    )


def _free_fingers(trans: Transitions, pose: FloatArray, q: FloatArray, grasp: GraspContacts) -> int:
    """Fingers of ``grasp`` (held at ``q``, object at ``pose``) the others hold the object without.

    At the stated contacts only (:meth:`HoldChecker.ratio` without shifts):
    a ranking screen, the release itself is checked in full when it is made.
    """
    if trans.holds is None:
        return trans.hand.n_fingers
    n = trans.hand.n_fingers
    pts = grasp.points
    return sum(
        trans.holds.ratio(q, pose, [None if i == f else pts[i] for i in range(n)], shifted=False)
        <= 1.0
        for f in range(n)
    )


def best_option(
    options: Iterable[RegraspOption], settings: GaitSettings, blocking: int
) -> RegraspOption | None:
    """The best option among those whose transfer goes nearly farthest (see the module).

    Ties keep the first (the landing search's order: the finger's own follow).
    An option after which the regrasped finger or the finger that blocked
    (``blocking``) stops the transfer at once gains nothing and is never
    chosen (None when only such are left: the reduction then tries other
    fingers, and landings that give the blocking finger one of its own).
    """
    opts = [o for o in options if o.reach > 0 or o.blocking not in (None, o.seg.finger, blocking)]
    if not opts:
        return None
    far = max(o.reach for o in opts)
    near = [o for o in opts if o.reach >= settings.strength_tolerance * far]
    if any(o.releases for o in near):
        near = [o for o in near if o.releases]
    most = max(o.free for o in near)
    near = [o for o in near if o.free == most]
    near = [o for o in near if o.strength >= settings.strong_quality] or near
    return max(near, key=lambda o: (o.strength, o.reach))
