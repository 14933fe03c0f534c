"""Validity of grasp-subspace states: joint limits, collisions, force closure.

Checks run cheapest first and stop at the first failure:

1. joint limits (and the object centre inside its workspace box);
2. collisions (coal): hand links, object, obstacles; contact fingertips may
   touch the object but not sink into it by more than 1 mm;
3. force closure: the minimum quality over the full grasp and every
   (k-1)-finger subgrasp must exceed a margin, so that any finger may let go
   (the paper's GSn validity). For a regrasp (k = n-1 holding fingers) the
   holding grasp itself must be force closure.

Rejections are counted by reason, for the planner's statistics.
"""

from __future__ import annotations

import enum
from collections import Counter
from dataclasses import dataclass, field
from typing import TypedDict

import numpy as np

from dexplan.core.typing import FloatArray, as_positive
from dexplan.model.collision import CollisionWorld
from dexplan.model.grasp import (
    ContactModel,
    check_contact_model,
    force_closure_quality,
    min_contacts,
    min_subgrasp_quality,
    min_subgrasp_quality_batch,
)
from dexplan.planning.gsn.space import POSE_DIM, GraspSubspace


class Rejection(enum.StrEnum):
    """Why the checker rejects a state (a member equals its string, as in statistics).

    Attributes:
        BOUNDS: the object outside the workspace box.
        JOINT_LIMITS: a joint outside its limits.
        COLLISION: a collision, or the object too near an obstacle.
        FORCE_CLOSURE: some required (sub)grasp is not force closure.
        REACH: a fingertip cannot touch the object at that pose at all (the
            planner's check of the start and goal poses, never the checker's).
    """

    BOUNDS = "bounds"
    JOINT_LIMITS = "joint_limits"
    COLLISION = "collision"
    FORCE_CLOSURE = "force_closure"
    REACH = "reach"


REASONS: tuple[Rejection, ...] = tuple(r for r in Rejection if r != Rejection.REACH)
"""The reasons the validity checker rejects states for (its counters)."""


class QualityArgs(TypedDict):
    """Keyword arguments of the ``dexplan.model.grasp`` quality functions (see ``quality_args``)."""

    edges: int
    margin: float
    contact_model: ContactModel | str
    torsion: float


KEPT_PER_REASON = 32
"""Rejected states kept per reason (the first ones), for ``--debug-rrd``."""


@dataclass(frozen=True)
class RejectedSample:
    """A state the checker rejected, kept so the user can look at it.

    Attributes:
        x: (7 + nq,) the ambient state (object pose XYZW in the world, joints).
        reason: one of :data:`REASONS`.
        detail: the colliding pair, or the force-closure quality, as text.
    """

    x: FloatArray
    reason: Rejection
    detail: str = ""


@dataclass(frozen=True)
class ValiditySettings:
    """Settings of the validity checker.

    Attributes:
        mu: Coulomb friction coefficient (>= 0).
        friction_edges: edges of the linearized friction cone.
        fc_margin: minimum force-closure quality (see ``dexplan.model.grasp``) of
            every (k-1)-finger subgrasp.
        contact_model: ``"point"`` (Coulomb friction, the paper) or ``"soft"``
            (plus torsional friction about the normal).
        torsion: soft-finger torsion coefficient (m), ``|tau_n| <= torsion f_n``;
            0 for point contacts.
        subgrasps: require force closure of every (k-1) subgrasp (GSn
            validity); False checks the k-finger grasp only.
        object_clearance: GSn states keep the object this far (m) from the
            obstacles. GSn motions are checked at discrete states (``delta``
            apart); the object trajectory the reduction follows is the chord
            between them, which cuts inside the arc by up to ``R theta^2 / 8``
            (0.1 mm for a 3.5 cm corner and a 0.15 rad step), enough to graze
            an obstacle. Transfers and the verifier check the object exactly.
    """

    mu: float = 0.8
    friction_edges: int = 8
    fc_margin: float = 0.005
    subgrasps: bool = True
    object_clearance: float = 0.0005
    contact_model: ContactModel | str = ContactModel.POINT
    torsion: float = 0.0

    def quality_args(self) -> QualityArgs:
        """Keyword arguments of the ``dexplan.model.grasp`` quality functions under these settings.

        Friction edges, the margin and the contact model; the friction ``mu``
        and the torque scale are passed as arguments of their own.
        """
        return {
            "edges": self.friction_edges,
            "margin": self.fc_margin,
            "contact_model": self.contact_model,
            "torsion": self.torsion,
        }

    def __post_init__(self) -> None:
        as_positive(self.mu, "contact.mu", allow_zero=True)
        check_contact_model(self.contact_model, self.torsion)
        as_positive(self.fc_margin, "fc_margin", allow_zero=True)
        as_positive(self.object_clearance, "object_clearance", allow_zero=True)


def let_go_problem(n_fingers: int, settings: ValiditySettings) -> str | None:
    """Why no grasp of this hand can be valid under the settings, or None.

    Validity needs every (n-1)-finger subgrasp force closure (the regrasp's
    holding grasp has n-1 fingers too), and no grasp of fewer contacts than
    :func:`dexplan.model.grasp.min_contacts` is: 3 point contacts with friction (two
    leave the torque about the line through them free), 2 soft ones, 7 or 4
    without friction. A hand with too few fingers can then never let one go.

    Args:
        n_fingers: fingers of the hand.
        settings: the contact model and friction.

    Returns:
        A one-line explanation with what to change, or None if some grasp may be
        valid.
    """
    model, mu = settings.contact_model, settings.mu
    need = min_contacts(mu, model)
    k = n_fingers - 1 if settings.subgrasps else n_fingers
    if k >= need:
        return None
    what = f"{k}-finger subgrasp" if settings.subgrasps else f"{k}-finger grasp"
    if mu == 0.0:
        return (
            f"without friction (contact.mu = 0) no {what} is force closure with {model} "
            f"contacts (force closure needs {need} of them): a {n_fingers}-finger hand needs "
            "contact.mu > 0"
        )
    if model == "point" and k == 2:
        why = "the torque about the line through the two contacts is free"
    elif model == "point":
        why = "force closure needs 3 point contacts with friction"
    else:
        why = "force closure needs 2 soft contacts"
    fix = (
        '[contact] model = "soft" (with torsion > 0), or a fourth finger'
        if model == "point" and n_fingers == 3
        else f"at least {need + 1} fingers"
    )
    return (
        f"with {model} contacts no {what} is force closure ({why}): "
        f"a {n_fingers}-finger hand needs {fix}"
    )


@dataclass
class ValidityStats:
    """Counters of checked states and rejections by reason."""

    checked: int = 0
    valid: int = 0
    rejected: dict[str, int] = field(default_factory=lambda: dict.fromkeys(REASONS, 0))
    #: collision rejections by colliding pair (geometry names, sorted)
    collision_pairs: Counter[tuple[str, str]] = field(default_factory=Counter)
    #: the first :data:`KEPT_PER_REASON` rejected states of each reason
    samples: list[RejectedSample] = field(default_factory=list)

    def keep(self, x: FloatArray, reason: Rejection, detail: str = "") -> None:
        """Record a rejected state while fewer than the cap of its reason are kept."""
        if self.rejected.get(reason, 0) < KEPT_PER_REASON:  # counted after this call
            self.samples.append(RejectedSample(np.array(x, dtype=float), reason, detail))

    def top_collision_pairs(self, k: int = 3) -> list[tuple[tuple[str, str], int]]:
        """The ``k`` pairs that rejected most states, most frequent first."""
        return self.collision_pairs.most_common(k)

    def as_dict(self) -> dict[str, object]:
        """Plain-dict view for statistics output."""
        return {
            "checked": self.checked,
            "valid": self.valid,
            "rejected": dict(self.rejected),
            "collision_pairs": [[a, b, n] for (a, b), n in self.top_collision_pairs(5)],
        }


@dataclass(frozen=True)
class Verdict:
    """Outcome of one validity check: ``reason`` is None when valid."""

    valid: bool
    reason: Rejection | None
    fc_quality: float = float("nan")


#: Valid states :meth:`GraspValidity.check` remembers before it forgets them all.
_VALID_KEPT = 4096


class GraspValidity:
    """Validity checker for states of a :class:`GraspSubspace`.

    Args:
        gsn: the grasp subspace (its contact fingers hold the object).
        world: the collision world of the same hand and object.
        settings: friction and force-closure settings.
    """

    def __init__(
        self, gsn: GraspSubspace, world: CollisionWorld, settings: ValiditySettings
    ) -> None:
        self.gsn = gsn
        self.world = world
        self.settings = settings
        self.stats = ValidityStats()
        self.torque_scale = gsn.obj.characteristic_length
        # valid states by their bytes: OMPL asks again about the states of a
        # path it checks (a state's motions both ways, the path's own check),
        # and a valid state costs every test, force closure last
        self._valid: dict[bytes, Verdict] = {}

    def grasp_quality(self, p_obj: FloatArray, n_in_obj: FloatArray) -> float:
        """Force-closure quality of contacts ``p_obj, n_in_obj: (k, 3)`` (object frame).

        With ``settings.subgrasps`` it is the minimum over the grasp and its
        (k-1)-contact subgrasps.
        """
        s = self.settings
        if s.subgrasps:
            return min_subgrasp_quality(
                p_obj, n_in_obj, s.mu, torque_scale=self.torque_scale, **s.quality_args()
            )
        return force_closure_quality(
            p_obj,
            n_in_obj,
            s.mu,
            edges=s.friction_edges,
            torque_scale=self.torque_scale,
            contact_model=s.contact_model,
            torsion=s.torsion,
        )

    def grasp_qualities(self, xs: list[FloatArray]) -> FloatArray:
        """:meth:`grasp_quality` of the contacts of many states, in one batch.

        Args:
            xs: ambient states ``(7 + nq,)`` of this subspace.

        Returns:
            ``(len(xs),)`` qualities, each what :meth:`check` computes for its
            state (the same decision at the margin; values equal up to the pair
            solver's tolerance), for :meth:`check`'s ``fc_quality``.
        """
        contacts = [self.gsn.contacts(x) for x in xs]
        k = len(self.gsn.contact_ids)
        return self.contact_qualities(
            np.array([p for p, _ in contacts]).reshape(-1, k, 3),
            np.array([n for _, n in contacts]).reshape(-1, k, 3),
        )

    def contact_qualities(
        self, points_obj: FloatArray, normals_in_obj: FloatArray, *, exact: bool = True
    ) -> FloatArray:
        """:meth:`grasp_quality` of many contact sets, in one batch.

        Args:
            points_obj: (M, k, 3) contact points, object frame.
            normals_in_obj: (M, k, 3) inward unit normals there, object frame.
            exact: False: a grasp whose certified bounds straddle the margin
                gets its lower bound (so :meth:`check` rejects it) instead of
                an exact solve. For a sampler, which may skip any grasp: on
                the Allegro sphere about 7 % of the combined grasps are such,
                and their solves took 17 % of the sampling time. Only with
                ``subgrasps``; a grasp accepted this way is force closure
                above the margin all the same (its lower bound is).

        Returns:
            ``(M,)`` qualities (see :meth:`grasp_qualities`).
        """
        s = self.settings
        if not s.subgrasps or not len(points_obj):
            return np.array(
                [self.grasp_quality(p, n) for p, n in zip(points_obj, normals_in_obj, strict=True)]
            )
        return min_subgrasp_quality_batch(
            points_obj,
            normals_in_obj,
            s.mu,
            torque_scale=self.torque_scale,
            solve=exact,
            **s.quality_args(),
        )

    def check(self, x: FloatArray, fc_quality: float | None = None) -> Verdict:
        """Check ambient state ``x: (7 + nq,)``, cheapest test first.

        Args:
            x: the state.
            fc_quality: its force-closure quality when already known (from
                :meth:`grasp_qualities`): then free, so checked first.
        """
        gsn = self.gsn
        self.stats.checked += 1
        known = self._valid.get(x.tobytes()) if fc_quality is None else None
        if known is not None:
            self.stats.valid += 1
            return known
        if fc_quality is not None and fc_quality <= self.settings.fc_margin:
            verdict = self._reject_force_closure(x, fc_quality)
        else:
            verdict = self._check(x, gsn, fc_quality)
        if verdict.valid:
            self.stats.valid += 1
            if fc_quality is None:
                if len(self._valid) >= _VALID_KEPT:
                    self._valid.clear()
                self._valid[x.tobytes()] = verdict
        elif verdict.reason is not None:  # every rejection names its reason
            self.stats.rejected[verdict.reason] += 1
        return verdict

    def _reject_force_closure(self, x: FloatArray, quality: float) -> Verdict:
        self.stats.keep(x, Rejection.FORCE_CLOSURE, f"quality {quality:.3g}")
        return Verdict(False, Rejection.FORCE_CLOSURE, quality)

    def _check(self, x: FloatArray, gsn: GraspSubspace, quality: float | None = None) -> Verdict:
        pos = x[:3]
        if np.any(pos < gsn.lower[:3]) or np.any(pos > gsn.upper[:3]):
            return Verdict(False, Rejection.BOUNDS)
        q = x[POSE_DIM:]
        if not gsn.hand.within_limits(q):
            self.stats.keep(x, Rejection.JOINT_LIMITS)
            return Verdict(False, Rejection.JOINT_LIMITS)
        clearance = self.settings.object_clearance
        if clearance > 0.0 and self.world.object_clearance(x[:POSE_DIM]) < clearance:
            return Verdict(False, Rejection.COLLISION)
        rep = self.world.check(q, x[:POSE_DIM], gsn.contact_fingers)
        if not rep.free:
            pair = rep.pair or ("fingertip", "object (penetration)")
            first, second = sorted(pair)
            self.stats.collision_pairs[(first, second)] += 1
            self.stats.keep(x, Rejection.COLLISION, f"{pair[0]} / {pair[1]}")
            return Verdict(False, Rejection.COLLISION)
        if quality is None:
            quality = self.grasp_quality(*gsn.contacts(x))
        if quality <= self.settings.fc_margin:
            return self._reject_force_closure(x, quality)
        return Verdict(True, None, quality)

    def is_valid(self, x: FloatArray) -> bool:
        """True when ``x`` passes every check."""
        return self.check(x).valid
