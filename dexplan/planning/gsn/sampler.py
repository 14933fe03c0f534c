"""RLG-style sampling of valid grasp-subspace states.

The paper samples GSn with the Random Loop Generator: the hand and the object
form closed kinematic chains, and virtual degrees of freedom on the object
surface (the contacts) close them. Here:

1. sample an object pose near the hand (or take a given one);
2. for each contact finger, in random order, sample contact candidates on the
   surface, keep those whose fingertip centre (contact + r * outward normal)
   lies in the finger's reach shell and away from the other fingertips, and
   solve the finger's IK to the first that works;
3. the free fingers (GSk, k < n) get random joint values;
4. check validity (limits, collisions, force closure of every subgrasp).

**Per-finger pools** (:attr:`SamplerSettings.per_finger`, the default for
every hand: on the Allegro the links mostly collide when the fingers are
placed one after the other, and on the paper hand the pools give 3x the
valid grasps a second on a sphere and 14x on a box): step 2 becomes, at the object
pose, per contact finger, candidate contacts, every IK solution to them
(branches and, for redundant fingers, the free-joint grid), each checked for
joint limits and for collisions of that finger's links against the palm, the
object and the obstacles alone; a pool of good per-finger solutions is kept.
Grasps are then combined from the pools (spread normals for force closure,
fingertips apart) and the rest (finger-finger collisions, full validity with
every (n-1) subgrasp force closure) is checked, several combinations per pose.

IK puts the fingertips on the surface to solver precision, so the state lies
on GSk without a projection step. All randomness comes from the
``numpy.random.Generator`` given by the caller: same seed, same samples.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass, replace

import numpy as np
import pinocchio as pin

from dexplan.core.errors import InvalidInputError
from dexplan.core.pose import quat_to_matrix, random_quaternion, slerp
from dexplan.core.typing import FloatArray
from dexplan.model.collision import pose_to_se3
from dexplan.model.grasp.halfspace import cannot_be_force_closure
from dexplan.model.hand.hand import Hand
from dexplan.planning.deadline import Deadline
from dexplan.planning.gsn.space import POSE_DIM, GraspSubspace
from dexplan.planning.gsn.validity import GraspValidity

#: Depth (m) a fingertip sphere on a candidate contact may dip into the object
#: elsewhere: in a concavity tighter than the fingertip it does, and the state
#: is off GSn by that much per finger. OMPL rejects a start state whose
#: constraint norm exceeds 1e-5 (``constraint_spec`` in
#: :mod:`dexplan.planning.roadmap.roadmap`); five fingers at this depth stay below it.
FIT_TOL = 2e-6

#: Of a pose's combination draws, those best balanced, this many per combination
#: kept (:attr:`SamplerSettings.combinations`), get the half-space test; the rest
#: are dropped unranked (on the Allegro sphere 10 % of the draws pass the test
#: and no valid grasp ranked past 200).
RANKED_PER_COMBINATION = 4


@dataclass(frozen=True)
class SamplerSettings:
    """Settings of :class:`GraspSampler`.

    Attributes:
        candidates: surface points drawn per finger and attempt.
        candidate_edges: edge points drawn with them when ``edge_contacts``
            is on (shapes with edges).
        edge_contacts: sample grasps with fingertips on the object's edges
            too (a fingertip on an edge pushes between the faces' normals);
            None: for hands with fingers of more than 3 joints. The Allegro
            holds a cube only that way (its pads touch the faces it reaches
            with parallel normals, docs/hands.md); the paper hand holds boxes
            on their faces, and edge grasps there cost regrasps (box turns,
            seeds 1-8: median 3.5-7.5 regrasps without, 7-8 with).
        max_attempts: attempts per :meth:`GraspSampler.sample` call before None.
        tip_clearance: minimum gap between two fingertip spheres (m).
        min_facing: minimum cosine between a candidate's outward normal and
            the direction to the finger's base (links stay clear of the object).
        balance_pool: reachable candidates compared for normal balance.
        per_finger: sample per finger first (pools of collision-free
            per-finger IK solutions, then combinations); False: the RLG
            steps above, contacts placed finger after finger.
        pool_size: per-finger solutions kept in a pool.
        pool_candidates: surface points drawn per finger for a pool.
        pool_edges: edge points (normals inside the edge's cone) drawn with
            them when ``edge_contacts`` is on, on shapes that have edges (boxes).
        solutions_per_contact: IK solutions (random among those within
            limits) collision-checked per candidate contact.
        combinations: grasps combined from one set of pools and checked
            before a new object pose is drawn (sample() returns at the first
            valid one). None: 96 for hands with fingers of more than 3
            joints, 40 otherwise (see ``grasps_per_pose``).
        combination_draws: random combinations ranked to choose those.
        joint_margin: pool solutions keep this far (rad) from joint limits
            (transfers stop short of them, ``TransitionSettings.joint_margin``).
        grasps_per_pose: with random poses (:meth:`GraspSampler.sample`),
            up to this many valid grasps are returned, one per call, from the
            ranked combinations of a pose before a new pose is drawn (1: a
            new pose every call). None: 64 for hands with fingers of more
            than 3 joints, whose pools are costly (Allegro sphere: 481 valid
            grasps/s with 96 combinations and 64 grasps a pose, 291 with 40
            and 24; its plans the same with 2), 2 otherwise: a roadmap
            gains more from distinct object poses than from a faster
            sampler, since checking its motions costs far more than
            sampling (the suite's cube_post, seeds 1-10, 30 s: PRM 6/10
            solved with 96 and 64, 9/10 with 40 and 24, 10/10 with 40 and
            2 in a median 1.8 s; PRMstar 6/10, 7/10, 10/10).
        check_batch: ranked combinations whose force closure is computed in
            one batch; a pose is left after a batch with no valid grasp. The
            normal-balance ranking puts a pose's valid grasps first (on the
            Allegro sphere, seed 1, 150 poses of 400 ranked combinations:
            25 % of the first 25 valid, 4 % of ranks 50-75, none past 200;
            half the poses have none in their first 24 and almost never one
            later): half the force-closure work for 2 % fewer valid grasps.
    """

    candidates: int = 48
    candidate_edges: int = 12
    edge_contacts: bool | None = None
    max_attempts: int = 50
    tip_clearance: float = 0.004
    min_facing: float = -0.3
    balance_pool: int = 6
    per_finger: bool = True
    pool_size: int = 24
    pool_candidates: int = 256
    pool_edges: int = 64
    solutions_per_contact: int = 3
    combinations: int | None = None
    combination_draws: int = 4000
    joint_margin: float = 0.03
    grasps_per_pose: int | None = None
    check_batch: int = 24


@dataclass(frozen=True)
class Combinations:
    """Grasps combined from one pose's per-finger pools (:meth:`GraspSampler.combinations`).

    Attributes:
        states: ambient states ``(7 + nq,)``, most promising first.
        points_obj: (M, k, 3) their contact points, object frame (contact
            fingers in ``GraspSubspace.contact_ids`` order).
        normals_in_obj: (M, k, 3) inward unit surface normals there, object frame.
    """

    states: list[FloatArray]
    points_obj: FloatArray
    normals_in_obj: FloatArray

    def __len__(self) -> int:
        return len(self.states)


@dataclass
class SamplerStats:
    """Counters of the sampler: attempts, valid samples, IK failures, time.

    With per-finger pools an attempt is one combined grasp (or one pose whose
    pools came out empty); ``pools`` counts the poses pools were built at and
    ``finger_rejections`` the per-finger IK solutions dropped for a collision.
    """

    attempts: int = 0
    valid: int = 0
    ik_failures: int = 0
    time_s: float = 0.0
    pools: int = 0
    finger_rejections: int = 0

    @property
    def valid_fraction(self) -> float:
        """Fraction of attempts that gave a valid state."""
        return self.valid / self.attempts if self.attempts else 0.0

    @property
    def samples_per_second(self) -> float:
        """Valid samples per second of sampling time."""
        return self.valid / self.time_s if self.time_s > 0 else 0.0

    def as_dict(self) -> dict[str, float]:
        """Plain-dict view for statistics output."""
        return {
            "attempts": self.attempts,
            "valid": self.valid,
            "ik_failures": self.ik_failures,
            "pools": self.pools,
            "finger_rejections": self.finger_rejections,
            "valid_fraction": self.valid_fraction,
            "samples_per_second": self.samples_per_second,
        }


def _long_fingers(hand: Hand) -> bool:
    """Whether some finger of ``hand`` has more than 3 joints (redundant for a contact)."""
    return max(len(idx) for idx in hand.finger_q_index) > 3


def _resolved(settings: SamplerSettings, hand: Hand) -> SamplerSettings:
    """``settings`` with the hand-dependent defaults (None fields) filled in."""
    long = _long_fingers(hand)
    combinations, per_pose = settings.combinations, settings.grasps_per_pose
    return replace(
        settings,
        combinations=(96 if long else 40) if combinations is None else combinations,
        grasps_per_pose=(64 if long else 2) if per_pose is None else per_pose,
    )


class GraspSampler:
    """Samples valid states of a grasp subspace.

    Args:
        gsn: the grasp subspace.
        validity: its validity checker.
        rng: random generator (the only source of randomness).
        settings: sampler settings.
        deadline: when sampling gives up (None: never); the planner shares
            its query deadline here.
    """

    def __init__(
        self,
        gsn: GraspSubspace,
        validity: GraspValidity,
        rng: np.random.Generator,
        settings: SamplerSettings | None = None,
        deadline: Deadline | None = None,
    ) -> None:
        self.gsn = gsn
        self.deadline = deadline or Deadline()
        self.validity = validity
        self.rng = rng
        self.settings = _resolved(settings or SamplerSettings(), gsn.hand)
        if self.settings.check_batch < 1:
            raise InvalidInputError(
                f"sampler check_batch must be >= 1, got {self.settings.check_batch}"
            )
        self.stats = SamplerStats()
        self._reach = [self._reach_shell(i) for i in range(gsn.hand.n_fingers)]
        hand = gsn.hand
        per_finger = self.settings.per_finger
        self.per_finger = bool(per_finger)
        edges = self.settings.edge_contacts
        if edges is None:
            edges = _long_fingers(hand)
        self._edges = (self.settings.candidate_edges, self.settings.pool_edges) if edges else (0, 0)
        world = validity.world
        self._finger_pairs = [world.finger_pairs(i) for i in range(hand.n_fingers)]
        self._finger_data = [world.pairs_data(pairs) for pairs in self._finger_pairs]
        # the rest of a pose's combinations, checked as they are drawn
        self._pending: Iterator[tuple[FloatArray, bool]] | None = None
        self._pending_left = 0

    def _reach_shell(self, finger: int) -> tuple[FloatArray, float, float]:
        """Centre (first joint origin), min and max reach of a fingertip, estimated by FK."""
        hand = self.gsn.hand
        idx = hand.finger_q_index[finger]
        rng = np.random.default_rng(finger)
        q = np.tile(hand.neutral, (400, 1))
        q[:, idx] = rng.uniform(hand.lower[idx], hand.upper[idx], size=(400, len(idx)))
        q[0, idx], q[1, idx] = hand.lower[idx], hand.upper[idx]
        tips = np.array([hand.fingertip_positions(qi)[finger] for qi in q])
        centre = hand.joint_origin(int(idx[0]), hand.neutral)
        d = np.linalg.norm(tips - centre, axis=1)
        return centre, float(d.min()) * 0.9, float(d.max()) * 1.02

    # -------------------------------------------------------------- sampling
    def sample_pose(self) -> FloatArray:
        """Uniform object pose: centre in the workspace box, uniform orientation."""
        gsn = self.gsn
        pos = self.rng.uniform(gsn.lower[:3], gsn.upper[:3])
        return np.concatenate([pos, random_quaternion(self.rng)])

    def sample_pose_near(self, pose_xyzquat: FloatArray, radius: float) -> FloatArray:
        """Object pose within ``radius`` (position m, orientation rad) of a pose."""
        gsn = self.gsn
        pos = pose_xyzquat[:3] + self.rng.uniform(-radius, radius, 3) * 0.1
        pos = np.clip(pos, gsn.lower[:3], gsn.upper[:3])
        q = random_quaternion(self.rng)
        s = min(1.0, radius / np.pi) * self.rng.random()
        return np.concatenate([pos, slerp(pose_xyzquat[3:7], q, s)])

    def sample(self) -> FloatArray | None:
        """A valid state at a random pose, or None after ``max_attempts``."""
        return self._run(None)

    def sample_at_pose(self, pose_xyzquat: FloatArray) -> FloatArray | None:
        """A valid state with the object at ``pose_xyzquat``, or None."""
        return self._run(np.asarray(pose_xyzquat, dtype=float))

    def _run(self, pose: FloatArray | None) -> FloatArray | None:
        if self.per_finger:
            return self._run_pools(pose)
        t0 = time.perf_counter()
        try:
            for _ in range(self.settings.max_attempts):
                if self.deadline.expired():
                    return None
                self.stats.attempts += 1
                pose_k = self.sample_pose() if pose is None else pose
                if self.validity.world.object_collides(pose_k):
                    continue
                x = self.grasp_at(pose_k)
                if x is not None and self.validity.is_valid(x):
                    self.stats.valid += 1
                    return x
            return None
        finally:
            self.stats.time_s += time.perf_counter() - t0

    def grasp_at(self, pose_xyzquat: FloatArray) -> FloatArray | None:
        """Sample contacts and solve IK at a fixed object pose (validity not checked).

        Returns:
            The ambient state, or None when some contact finger has no
            reachable contact among the candidates.
        """
        gsn, hand, s = self.gsn, self.gsn.hand, self.settings
        rng = self.rng
        R = quat_to_matrix(pose_xyzquat[3:7] / np.linalg.norm(pose_xyzquat[3:7]))
        t = pose_xyzquat[:3]
        r = hand.fingertip_radius
        q = rng.uniform(hand.lower, hand.upper)
        placed: list[FloatArray] = []
        n_sum = np.zeros(3)
        order = list(gsn.contact_ids)
        rng.shuffle(order)
        for i in order:
            pts, n_out = gsn.obj.sample_contacts(s.candidates, rng, self._edges[0])
            tips = (pts + r * n_out) @ R.T + t  # candidate tip centres, world frame
            ok = self._in_shell(i, tips, n_out @ R.T)
            ok[ok] = self._fits(pts[ok], n_out[ok])
            for other in placed:
                ok &= np.linalg.norm(tips - other, axis=1) >= 2 * r + s.tip_clearance
            found = False
            cand = np.flatnonzero(ok)
            rng.shuffle(cand)
            if hand.has_closed_form_ik(i) and len(cand):
                # vectorized solves, a chunk of candidates at a time
                for lo in range(0, len(cand), 16):
                    chunk = cand[lo : lo + 16]
                    q_sol, solved = hand.finger_ik_batch(i, tips[chunk])
                    if solved.any():
                        cand = chunk
                        break
                hits = np.flatnonzero(solved)[: s.balance_pool]
                if len(hits):
                    # among a few reachable ones, the contact whose normal best
                    # balances those placed so far: force closure needs spread normals
                    n_w = n_out[cand[hits]] @ R.T
                    best = hits[int(np.argmin(np.linalg.norm(n_sum + n_w, axis=1)))]
                    q[hand.finger_q_index[i]] = q_sol[best]
                    placed.append(tips[cand[best]])
                    n_sum += n_out[cand[best]] @ R.T
                    found = True
            else:
                for c in cand:
                    if self.deadline.expired():  # iterative IK: ~0.4 ms a candidate
                        return None
                    res = hand.finger_ik(i, tips[c], q)
                    if res.success:
                        q[hand.finger_q_index[i]] = res.q_finger
                        placed.append(tips[c])
                        n_sum += n_out[c] @ R.T
                        found = True
                        break
            if not found:
                self.stats.ik_failures += 1
                return None
        return np.concatenate([pose_xyzquat[:POSE_DIM], q])

    # ------------------------------------------------------ per-finger pools
    def _run_pools(self, pose: FloatArray | None) -> FloatArray | None:
        """:meth:`_run` with per-finger pools: ``max_attempts`` combined grasps at most."""
        found = self._pool_samples(pose, 1, self.settings.max_attempts)
        return found[0] if found else None

    def samples_at_pose(
        self, pose_xyzquat: FloatArray, count: int, rng: np.random.Generator | None = None
    ) -> list[FloatArray]:
        """Up to ``count`` valid states with the object at ``pose_xyzquat``.

        With per-finger pools, one pose's pools and combinations serve them
        all (``count * max_attempts`` combined grasps at most); otherwise
        :meth:`sample_at_pose` is called ``count`` times. ``rng``: draw from
        this stream instead of the sampler's own (which is left as it was), so
        that a caller's samples do not depend on how much the search sampled.
        """
        pose = np.asarray(pose_xyzquat, dtype=float)
        own = self.rng
        self.rng = own if rng is None else rng
        try:
            if self.per_finger:
                return self._pool_samples(pose, count, count * self.settings.max_attempts)
            found = (self._run(pose) for _ in range(count))
            return [x for x in found if x is not None]
        finally:
            self.rng = own

    def _pool_samples(self, pose: FloatArray | None, want: int, budget: int) -> list[FloatArray]:
        """Valid states from per-finger pools, ``want`` at most, ``budget`` grasps checked.

        ``pose`` None: a random pose per round, and one state (the rest of the
        round's checks wait in ``_pending`` for the next calls).
        """
        t0 = time.perf_counter()
        s = self.settings
        out: list[FloatArray] = []
        try:
            if pose is None and self._pending is not None:
                for x, valid in self._pending:
                    if self.deadline.expired():
                        return out
                    self.stats.attempts += 1
                    budget -= 1
                    if valid:
                        self.stats.valid += 1
                        self._pending_left -= 1
                        if self._pending_left <= 0:
                            self._pending = None
                        return [x]
                    if budget <= 0:
                        return out
                self._pending = None
            while budget > 0:
                if self.deadline.expired():
                    return out
                pose_k = self.sample_pose() if pose is None else pose
                if self.validity.world.object_collides(pose_k):
                    self.stats.attempts += 1
                    budget -= 1
                    continue
                pools = self.finger_pools(pose_k)
                if pools is None:
                    self.stats.attempts += 1
                    budget -= 1
                    continue
                found = self.combinations(pose_k, pools)
                if not found.states:
                    self.stats.attempts += 1
                    budget -= 1
                    continue
                checks = self._checked(found)
                for x, valid in checks:
                    self.stats.attempts += 1
                    budget -= 1
                    if valid:
                        self.stats.valid += 1
                        out.append(x)
                        if pose is None and s.grasps_per_pose > 1:
                            self._pending = checks
                            self._pending_left = s.grasps_per_pose - 1
                        if len(out) >= want or pose is None:
                            return out
                    if budget <= 0 or self.deadline.expired():
                        return out
            return out
        finally:
            self.stats.time_s += time.perf_counter() - t0

    def _checked(self, found: Combinations) -> Iterator[tuple[FloatArray, bool]]:
        """Each of a pose's ranked combinations with its validity, best first.

        Force closure, the costliest check, decides most rejections: it is
        computed a batch of ``check_batch`` combinations at a time (from the
        pools' contacts, which the states' own contacts equal to rounding: no
        forward kinematics and projection again); grasps the certified bounds
        leave undecided are skipped, not solved exactly. The pose is left
        after a batch with no valid grasp: the ranking puts the valid ones
        first (see :class:`SamplerSettings`).
        """
        n = self.settings.check_batch
        for start in range(0, len(found.states), n):
            part = slice(start, start + n)
            qualities = self.validity.contact_qualities(
                found.points_obj[part], found.normals_in_obj[part], exact=False
            ).tolist()
            any_valid = False
            for x, quality in zip(found.states[part], qualities, strict=True):
                valid = self.validity.check(x, quality).valid
                any_valid |= valid
                yield x, valid
            if not any_valid:
                return

    def _fits(self, points: FloatArray, normals_out: FloatArray) -> np.ndarray:
        """(N,) True where a fingertip sphere on the contact touches the object there only.

        ``points, normals_out: (N, 3)`` candidate contacts and outward normals,
        object frame. In a concavity tighter than the fingertip (the bean's
        waist) the sphere centred at ``point + r * normal`` dips into the
        object elsewhere; the state would be off GSn by that depth (the
        collision check tolerates it, the constraint does not), so such
        contacts are not offered (up to :data:`FIT_TOL`).
        """
        if not len(points):
            return np.zeros(0, dtype=bool)
        r = self.gsn.hand.fingertip_radius
        d = np.atleast_1d(np.asarray(self.gsn.obj.signed_distance(points + r * normals_out)))
        return d >= r - FIT_TOL

    def _in_shell(self, finger: int, tips: FloatArray, normals_w: FloatArray) -> np.ndarray:
        """(N,) candidate fingertip centres ``tips: (N, 3)`` in the finger's reach shell.

        The outward normals ``normals_w: (N, 3)`` (world frame) must face the
        finger's base (``min_facing``): the finger comes from outside.
        """
        centre, dmin, dmax = self._reach[finger]
        to_base = centre - tips
        d = np.linalg.norm(to_base, axis=1)
        ok = (d >= dmin) & (d <= dmax)
        ok &= np.einsum("ij,ij->i", normals_w, to_base) > self.settings.min_facing * d
        return ok

    def finger_pools(
        self, pose_xyzquat: FloatArray
    ) -> dict[int, tuple[FloatArray, FloatArray, FloatArray]] | None:
        """Per contact finger, collision-free IK solutions to sampled contacts.

        Args:
            pose_xyzquat: (7,) object pose, world frame, XYZW.

        Returns:
            ``{finger: (tips, normals, q)}`` with ``tips: (P, 3)`` fingertip
            centres and ``normals: (P, 3)`` outward surface normals (world
            frame) and ``q: (P, m)`` the finger's joints; None when some
            contact finger has an empty pool.
        """
        self.stats.pools += 1
        R = quat_to_matrix(pose_xyzquat[3:7] / np.linalg.norm(pose_xyzquat[3:7]))
        t = pose_xyzquat[:3]
        q = self.gsn.hand.neutral.copy()
        M_obj = pose_to_se3(pose_xyzquat)
        # every finger's candidate contacts first (cheap): a pose where some
        # finger reaches none is dropped before any IK or collision check
        cands = {}
        for i in self.gsn.contact_ids:
            cands[i] = self._pool_candidates(i, R, t)
            if cands[i] is None:
                self.stats.ik_failures += 1
                return None
        pools = {}
        # fewest candidates first: the pool most likely to come out empty
        for i in sorted(cands, key=lambda f: len(cands[f][0])):
            pool = self._finger_pool(i, *cands[i], R, t, q, M_obj)
            if pool is None:
                self.stats.ik_failures += 1
                return None
            pools[i] = pool
        return {i: pools[i] for i in self.gsn.contact_ids}

    def _pool_candidates(
        self, i: int, R: FloatArray, t: FloatArray
    ) -> tuple[FloatArray, FloatArray] | None:
        """Finger ``i``'s candidate contacts at object rotation ``R``, position ``t`` (world).

        Sampled surface points whose fingertip centre lies in the finger's
        reach shell and voxels, facing the finger, where the fingertip fits.

        Returns:
            ``(tips, normals)``: (C, 3) fingertip centres and outward normals
            (world frame), or None when there is none.
        """
        hand, s = self.gsn.hand, self.settings
        pts, n_out = self.gsn.obj.sample_contacts(s.pool_candidates, self.rng, self._edges[1])
        n_w = n_out @ R.T
        tips = (pts + hand.fingertip_radius * n_out) @ R.T + t
        ok = self._in_shell(i, tips, n_w)
        ok[ok] = hand.reach_voxels(i).contains(tips[ok])
        ok[ok] = self._fits(pts[ok], n_out[ok])
        if not ok.any():
            return None
        return tips[ok], n_w[ok]

    def _finger_pool(
        self,
        i: int,
        tips: FloatArray,
        n_w: FloatArray,
        R: FloatArray,
        t: FloatArray,
        q: FloatArray,
        M_obj: pin.SE3,
    ) -> tuple[FloatArray, FloatArray, FloatArray] | None:
        """One finger's pool from its candidates (:meth:`_pool_candidates`).

        ``tips, n_w: (C, 3)`` the candidates' fingertip centres and outward
        normals (world frame); ``R: (3, 3)``, ``t: (3,)`` the object's rotation and position
        (world); ``q: (nq,)`` a scratch hand configuration (its other fingers
        do not matter: only this finger's pairs with the palm, the object and
        the obstacles are checked). None when no candidate works.
        """
        hand, s, rng = self.gsn.hand, self.settings, self.rng
        world = self.validity.world
        q_sol, solved = hand.finger_ik_candidates(i, tips)
        idx = hand.finger_q_index[i]
        # off the limits: a finger at a limit cannot follow the object
        m = s.joint_margin
        solved &= np.all((q_sol >= hand.lower[idx] + m) & (q_sol <= hand.upper[idx] - m), axis=2)
        clearance = self._link_clearance(i, q_sol, solved, R, t)
        # per contact, the solutions whose links stay farthest from the object
        # first (one sort for all rows; unsolved ones last, not tried)
        order = np.argsort(np.where(solved, -clearance, np.inf), axis=1, kind="stable")
        tries = np.minimum(solved.sum(axis=1), s.solutions_per_contact)
        keep_c, keep_q = [], []
        for row in rng.permutation(len(tips)):
            for opt in order[row, : tries[row]]:
                q[idx] = q_sol[row, opt]
                if world.pairs_collide(self._finger_data[i], q, M_obj):
                    self.stats.finger_rejections += 1
                    continue
                keep_c.append(row)
                keep_q.append(q_sol[row, opt].copy())
                break
            if len(keep_c) >= s.pool_size:
                break
        if not keep_c:
            return None
        c = np.array(keep_c)
        return tips[c], n_w[c], np.array(keep_q)

    def _link_clearance(
        self, finger: int, q_sol: FloatArray, solved: np.ndarray, R: FloatArray, t: FloatArray
    ) -> FloatArray:
        """Signed distance from the object to a finger's joint axes and link midpoints.

        Args:
            finger: the finger.
            q_sol: (N, C, m) IK solutions.
            solved: (N, C) which of them exist.
            R: (3, 3) object rotation (world frame).
            t: (3,) object position (world frame).

        Returns:
            (N, C) the smallest signed distance (m) over the finger's joint
            origins after the first and the midpoints of its links (-inf
            where not solved; 0 where the finger has no vectorised chain).
        """
        out = np.full(solved.shape, -np.inf)
        chain = self.gsn.hand._chains[finger]
        if chain is None:
            out[solved] = 0.0
            return out
        q = q_sol[solved]
        if not len(q):
            return out
        tip, origins, _ = chain.forward(q)
        pts = np.concatenate([origins[:, 1:], tip[:, None]], axis=1)
        mids = 0.5 * (pts[:, 1:] + pts[:, :-1])
        probe = np.concatenate([origins[:, 1:], mids], axis=1)
        sd = self.gsn.obj.signed_distance((probe.reshape(-1, 3) - t) @ R)
        out[solved] = np.asarray(sd).reshape(len(q), -1).min(axis=1)
        return out

    def _cannot_hold(self, normals_out: FloatArray) -> np.ndarray:
        """(M,) True where a required (sub)grasp of ``normals_out: (M, k, 3)`` cannot hold.

        The half-space test, :func:`dexplan.model.grasp.halfspace.cannot_be_force_closure`.
        """
        vs = self.validity.settings
        return cannot_be_force_closure(normals_out, vs.mu, subgrasps=vs.subgrasps)

    def combinations(
        self, pose_xyzquat: FloatArray, pools: dict[int, tuple[FloatArray, FloatArray, FloatArray]]
    ) -> Combinations:
        """Grasps combined from per-finger pools, most promising first (validity not checked).

        Draws ``combination_draws`` random combinations (one pool entry per
        contact finger), drops those whose fingertips come closer than
        ``2 r + tip_clearance``, and sorts the rest by normal balance: the
        largest, over the grasp's (k-1)-finger subgrasps, length of the mean
        outward normal (0 when the normals of every subgrasp cancel, which
        force closure of every subgrasp needs on a sphere). Of the best
        ``RANKED_PER_COMBINATION * combinations``, those the half-space test
        does not rule out are kept, best first, duplicates dropped. Free
        fingers get random joint values.

        Returns:
            Up to ``combinations`` ambient states ``(7 + nq,)`` and their contacts.
        """
        hand, s, rng = self.gsn.hand, self.settings, self.rng
        fingers = list(pools)
        sizes = np.array([len(pools[i][0]) for i in fingers])
        M = s.combination_draws
        pick = (rng.random((M, len(fingers))) * sizes).astype(np.int64)
        # fingertips apart: each pair of pools' distances once, then looked up
        gap = 2 * hand.fingertip_radius + s.tip_clearance
        ok = np.ones(len(pick), dtype=bool)
        for a in range(len(fingers)):
            for b in range(a + 1, len(fingers)):
                ta, tb = pools[fingers[a]][0], pools[fingers[b]][0]
                apart = np.linalg.norm(ta[:, None] - tb[None], axis=2) >= gap
                ok &= apart[pick[:, a], pick[:, b]]
        pick = pick[ok]
        # per finger (M, 3) arrays: sums and norms of small stacked axes are slow
        each = [pools[i][1][pick[:, j]] for j, i in enumerate(fingers)]
        k = len(fingers)
        total = np.sum(each, axis=0)
        if k >= 3:
            # subgrasp without finger j: (total - n_j) / (k - 1)
            worst = np.zeros(len(pick))
            for n_j in each:
                d = total - n_j
                np.maximum(worst, np.einsum("ij,ij->i", d, d), out=worst)
            score = np.sqrt(worst) / (k - 1)
        else:
            score = np.sqrt(np.einsum("ij,ij->i", total, total)) / max(k, 1)
        # only the best-balanced draws are worth the half-space test: the
        # valid grasps rank first (see ``check_batch``)
        best = np.arange(len(score))
        keep = RANKED_PER_COMBINATION * s.combinations
        if len(score) > keep:
            best = np.sort(np.argpartition(score, keep)[:keep])
        pick, score = pick[best], score[best]
        normals = np.stack([n_j[best] for n_j in each], axis=1)
        held = ~self._cannot_hold(normals)
        pick, normals, score = pick[held], normals[held], score[held]
        rows: list[int] = []
        seen: set[bytes] = set()
        for row in np.argsort(score, kind="stable"):
            key = pick[row].tobytes()
            if key in seen:
                continue
            seen.add(key)
            if len(rows) >= s.combinations:
                break
            rows.append(int(row))
        # free fingers at random joint values (one draw, as one per grasp would give)
        q = rng.uniform(hand.lower, hand.upper, size=(len(rows), len(hand.lower)))
        for j, i in enumerate(fingers):
            q[:, hand.finger_q_index[i]] = pools[i][2][pick[rows, j]]
        states = np.empty((len(rows), POSE_DIM + q.shape[1]))
        states[:, :POSE_DIM] = pose_xyzquat[:POSE_DIM]
        states[:, POSE_DIM:] = q
        out = list(states)
        R = quat_to_matrix(pose_xyzquat[3:7] / np.linalg.norm(pose_xyzquat[3:7]))
        n_w = normals[rows]
        tips_w = np.stack([pools[i][0][pick[rows, j]] for j, i in enumerate(fingers)], axis=1)
        points = (tips_w - hand.fingertip_radius * n_w - pose_xyzquat[:3]) @ R
        return Combinations(out, points.reshape(-1, k, 3), -(n_w @ R).reshape(-1, k, 3))
