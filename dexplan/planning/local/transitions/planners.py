"""Transfer and regrasp local planners (paper, section IV) for one hand, object and world.

:class:`Transitions` owns the components and shares their state explicitly:
the per-finger checks (:mod:`.checks`), the follow scores (:mod:`.following`),
the landing choice (:mod:`.landings`), transfers (:mod:`.transfer`) and
regrasps (:mod:`.regrasp`). They draw from one random stream, count into one
``stats`` dict and give up at one deadline.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from dexplan.core.segments import Segment
from dexplan.core.typing import FloatArray, IntArray
from dexplan.model.collision import CollisionWorld
from dexplan.model.grasp import min_subgrasp_quality
from dexplan.model.grasp.holds import HoldChecker
from dexplan.model.grasp.rolling import ContactMotion
from dexplan.model.hand.hand import Hand
from dexplan.model.objects import Shape
from dexplan.planning.deadline import Deadline
from dexplan.planning.gsn.validity import ValiditySettings
from dexplan.planning.local.transitions.checks import FingerChecks
from dexplan.planning.local.transitions.contacts import GraspContacts
from dexplan.planning.local.transitions.counts import LocalCounts, new_counts
from dexplan.planning.local.transitions.following import FingerFollower
from dexplan.planning.local.transitions.landings import LandingPool, Landings
from dexplan.planning.local.transitions.regrasp import RegraspPlanner
from dexplan.planning.local.transitions.rolling_transfer import RollingTransferPlanner
from dexplan.planning.local.transitions.settings import TransitionSettings
from dexplan.planning.local.transitions.transfer import TransferPlanner, TransferResult


class Transitions:
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
        holds: the hold check (the scenario's object mass, gravity, effort
            limits and hold shift): a finger is let go only where the others
            hold the object (:meth:`can_release`); None: force closure alone
            decides.

    Attributes:
        checks: per-finger collision checks and joint bounds.
        follower: how long a finger follows the object's motion from a contact.
        landings: the landing choice of regrasps.
        transfers: the transfer planner.
        regrasps: the regrasp planner.
        stats: counters of all of them (transfers, regrasps, landing checks...).
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
        holds: HoldChecker | None = None,
    ) -> None:
        self.hand = hand
        self.holds = holds
        self.deadline = deadline or Deadline()
        self.obj = obj
        self.world = world
        self.validity = validity
        self.settings = settings
        self.stats: LocalCounts = new_counts()
        self.checks = FingerChecks(hand, world, settings)
        self.follower = FingerFollower(hand, settings, self.checks)
        self.landings = Landings(
            hand,
            obj,
            validity,
            settings,
            self.checks,
            self.follower,
            rng,
            self.deadline,
            self.stats,
        )
        self.transfers: TransferPlanner | RollingTransferPlanner = TransferPlanner(
            hand, settings, self.checks, self.stats
        )
        if settings.contact_motion == ContactMotion.ROLLING:
            self.transfers = RollingTransferPlanner(
                hand, obj, settings, self.checks, self.stats, self.grasp_quality, validity.fc_margin
            )
        self.regrasps = RegraspPlanner(
            hand,
            settings,
            self.checks,
            self.landings.postures,
            rng,
            self.deadline,
            holds,
            self.stats,
        )
        # the components' inner steps and stores, under the names the tests probe
        self._moved_free = self.checks.moved_free
        self._segment_free = self.regrasps.segment_free
        self._joint_move = self.regrasps.joint_move
        self._tracks = self.follower.tracks
        self._postures = self.landings.postures

    @property
    def rng(self) -> np.random.Generator:
        """The random stream of landing samples, via points and OMPL seeds."""
        return self.landings.rng

    @rng.setter
    def rng(self, rng: np.random.Generator) -> None:
        self.landings.rng = rng
        self.regrasps.rng = rng

    @property
    def all_contact(self) -> tuple[bool, ...]:
        """The contact mask with every finger in contact."""
        return self.checks.all_contact

    def tip_targets(self, pose: FloatArray, grasp: GraspContacts) -> FloatArray:
        """World fingertip centres ``(n, 3)`` of a grasp at an object pose ``(7,)``."""
        return grasp.tip_centres(pose, self.hand.fingertip_radius)

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

    # ----------------------------------------------------------------- transfer
    def transfer(
        self, poses: FloatArray, start: int, q_start: FloatArray, grasp: GraspContacts
    ) -> TransferResult:
        """Follow ``poses[start:]`` on a grasp, contacts fixed or rolling (``contact_motion``).

        :meth:`TransferPlanner.transfer` or :meth:`RollingTransferPlanner.transfer`.
        """
        return self.transfers.transfer(poses, start, q_start, grasp)

    # ------------------------------------------------------------------ regrasp
    def can_release(
        self, finger: int, pose: FloatArray, q: FloatArray, grasp: GraspContacts
    ) -> bool:
        """:meth:`RegraspPlanner.can_release`: the others hold the object without ``finger``."""
        return self.regrasps.can_release(finger, pose, q, grasp)

    def regrasp(
        self,
        pose: FloatArray,
        q: FloatArray,
        grasp: GraspContacts,
        finger: int,
        new_point: FloatArray,
        new_normal_out: FloatArray,
    ) -> Segment | None:
        """:meth:`RegraspPlanner.regrasp`: move ``finger`` to a new contact, or None."""
        return self.regrasps.regrasp(pose, q, grasp, finger, new_point, new_normal_out)

    # ----------------------------------------------------------------- landings
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
        """:meth:`Landings.landing_candidates`: ``(point, normal_out, score)``, best first."""
        return self.landings.landing_candidates(finger, pose, q, grasp, future_poses, hint, limit)

    def landing_pool(
        self, finger: int, pose: FloatArray, future_poses: FloatArray
    ) -> LandingPool | None:
        """:meth:`Landings.landing_pool`: contacts ``finger`` reaches and follows from."""
        return self.landings.landing_pool(finger, pose, future_poses)

    def can_land(
        self,
        finger: int,
        q: FloatArray,
        grasp: GraspContacts,
        pool: LandingPool,
        future_poses: FloatArray,
        tries: int = 16,
    ) -> bool:
        """:meth:`Landings.can_land`: ``finger`` has a landing from ``pool`` on ``grasp``."""
        return self.landings.can_land(finger, q, grasp, pool, future_poses, tries)

    def tracked_count(self, finger: int) -> int:
        """:meth:`Landings.tracked_count`: landings of ``finger`` tracked, links checked."""
        return self.landings.tracked_count(finger)

    def follow_scores(
        self,
        finger: int,
        candidates_tip_obj: FloatArray,
        future_poses: FloatArray,
        normals_obj: FloatArray | None = None,
    ) -> IntArray:
        """:meth:`FingerFollower.follow_scores`: the IK-only follow bound per candidate."""
        return self.follower.follow_scores(finger, candidates_tip_obj, future_poses, normals_obj)

    def track_score(
        self,
        finger: int,
        q: FloatArray,
        tip_obj: FloatArray,
        normal_obj: FloatArray,
        future_poses: FloatArray,
        limit: int,
    ) -> tuple[int, FloatArray | None]:
        """:meth:`FingerFollower.track_score`: poses followed from a contact, links checked."""
        return self.follower.track_score(finger, q, tip_obj, normal_obj, future_poses, limit)

    def redundant(self, finger: int) -> bool:
        """Whether ``finger`` has more postures per contact than IK branches (4+ joints)."""
        return self.follower.redundant(finger)
