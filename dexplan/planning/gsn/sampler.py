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

A finger of fewer than 3 joints reaches almost no chosen point: in both ways its
candidate contacts come from its joint space (:mod:`.contact_curve`).

IK puts the fingertips on the surface to solver precision, so the state lies
on GSk without a projection step. All randomness comes from the
``numpy.random.Generator`` given by the caller: same seed, same samples.
"""

from __future__ import annotations

import time
from collections.abc import Iterator

import numpy as np
import pinocchio as pin

from dexplan.core.errors import InvalidInputError
from dexplan.core.pose import quat_to_matrix, random_quaternion, slerp
from dexplan.core.typing import FloatArray
from dexplan.model.collision import pose_to_se3
from dexplan.model.grasp.halfspace import cannot_be_force_closure
from dexplan.planning.deadline import Deadline
from dexplan.planning.gsn.combinations import (
    Combinations,
    FingerPool,
    combine_pools,
    combine_pools_pairwise,
)
from dexplan.planning.gsn.contact_curve import contact_curve_samples, low_dof
from dexplan.planning.gsn.contact_kinds import faces_only_reason
from dexplan.planning.gsn.finger_reach import fingertip_fits, link_clearance, reach_shell
from dexplan.planning.gsn.sampler_settings import (
    SamplerSettings,
    combines_pairwise,
    resolved_settings,
)
from dexplan.planning.gsn.sampler_stats import SamplerStats
from dexplan.planning.gsn.space import POSE_DIM, GraspSubspace
from dexplan.planning.gsn.validity import GraspValidity


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
        vs = validity.settings  # why face points alone cannot hold (None: they may)
        self.faces_only = faces_only_reason(
            gsn.obj, gsn.hand, len(gsn.contact_ids), vs.mu, vs.subgrasps
        )
        self.settings, self._combinations, self._grasps_per_pose, edges = resolved_settings(
            settings or SamplerSettings(), gsn.hand, self.faces_only is not None
        )
        if self.settings.check_batch < 1:
            raise InvalidInputError(
                f"sampler check_batch must be >= 1, got {self.settings.check_batch}"
            )
        self.stats = SamplerStats()
        self._pairwise = combines_pairwise(
            self.settings, len(gsn.contact_ids), vs.subgrasps, self.faces_only is not None
        )
        self._reach = [reach_shell(gsn.hand, i) for i in range(gsn.hand.n_fingers)]
        hand = gsn.hand
        per_finger = self.settings.per_finger
        self.per_finger = bool(per_finger)
        self._edges = (self.settings.candidate_edges, self.settings.pool_edges) if edges else (0, 0)
        corners = self.faces_only is not None
        if self.settings.vertex_contacts is not None:
            corners = self.settings.vertex_contacts
        self._vertices = (
            (self.settings.candidate_vertices, self.settings.pool_vertices) if corners else (0, 0)
        )
        self.stats.screen_reason = "" if edges else self.faces_only or ""
        world = validity.world
        self._finger_pairs = [world.finger_pairs(i) for i in range(hand.n_fingers)]
        self._finger_data = [world.pairs_data(pairs) for pairs in self._finger_pairs]
        # the rest of a pose's combinations, checked as they are drawn
        self._pending: Iterator[tuple[FloatArray, bool]] | None = None
        self._pending_left = 0

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
            if low_dof(hand, i):  # contacts from joint space (:mod:`.contact_curve`)
                curve = contact_curve_samples(hand, gsn.obj, i, R, t, s.candidates, rng)
                pts, n_out = curve.points, curve.normals_out
            else:
                pts, n_out = gsn.obj.sample_contacts(
                    s.candidates, rng, self._edges[0], self._vertices[0]
                )
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
                    self.stats.screened += 1
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
                        if pose is None and self._grasps_per_pose > 1:
                            self._pending = checks
                            self._pending_left = self._grasps_per_pose - 1
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
        """:func:`~dexplan.planning.gsn.finger_reach.fingertip_fits` on this object and hand."""
        return fingertip_fits(self.gsn.obj, self.gsn.hand.fingertip_radius, points, normals_out)

    def _in_shell(self, finger: int, tips: FloatArray, normals_w: FloatArray) -> np.ndarray:
        """(N,) candidate fingertip centres ``tips: (N, 3)`` in the finger's reach shell.

        The outward normals ``normals_w: (N, 3)`` (world frame) must face the
        finger's base (``min_facing``): the finger comes from outside.
        """
        return self._reach[finger].contains(tips, normals_w, self.settings.min_facing)

    def finger_pools(self, pose_xyzquat: FloatArray) -> dict[int, FingerPool] | None:
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
        cands: dict[int, tuple[FloatArray, FloatArray, FloatArray | None]] = {}
        for i in self.gsn.contact_ids:
            found = self._pool_candidates(i, R, t)
            if found is None:
                self.stats.ik_failures += 1
                return None
            cands[i] = found
        pools: dict[int, FingerPool] = {}
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
    ) -> tuple[FloatArray, FloatArray, FloatArray | None] | None:
        """Finger ``i``'s candidate contacts at object rotation ``R``, position ``t`` (world).

        Sampled surface points whose fingertip centre lies in the finger's
        reach shell and voxels, facing the finger, where the fingertip fits.
        A finger of fewer than 3 joints reaches almost no chosen point: its
        candidates are its joint values projected onto the contacts it can
        make (:mod:`.contact_curve`), with the same facing and fit filters.

        Returns:
            ``(tips, normals, q)``: (C, 3) fingertip centres and outward normals
            (world frame), and the finger's (C, m) joints for a low-DOF finger
            (None otherwise: IK gives them); None when there is none.
        """
        hand, s = self.gsn.hand, self.settings
        if low_dof(hand, i):
            obj, m = self.gsn.obj, s.joint_margin
            c = contact_curve_samples(hand, obj, i, R, t, s.pool_candidates, self.rng, m)
            n_w = c.normals_out @ R.T
            ok = self._in_shell(i, c.tips, n_w)
            ok[ok] = self._fits(c.points[ok], c.normals_out[ok])
            return (c.tips[ok], n_w[ok], c.q[ok]) if ok.any() else None
        pts, n_out = self.gsn.obj.sample_contacts(
            s.pool_candidates, self.rng, self._edges[1], self._vertices[1]
        )
        n_w = n_out @ R.T
        tips = (pts + hand.fingertip_radius * n_out) @ R.T + t
        ok = self._in_shell(i, tips, n_w)
        ok[ok] = hand.reach_voxels(i).contains(tips[ok])
        ok[ok] = self._fits(pts[ok], n_out[ok])
        if not ok.any():
            return None
        return tips[ok], n_w[ok], None

    def _finger_pool(
        self,
        i: int,
        tips: FloatArray,
        n_w: FloatArray,
        known: FloatArray | None,
        R: FloatArray,
        t: FloatArray,
        q: FloatArray,
        M_obj: pin.SE3,
    ) -> FingerPool | None:
        """One finger's pool from its candidates (:meth:`_pool_candidates`).

        ``tips, n_w: (C, 3)`` the candidates' fingertip centres and outward
        normals (world frame), ``known: (C, m)`` their joints when they came
        from joint space (a low-DOF finger), else None; ``R: (3, 3)``,
        ``t: (3,)`` the object's rotation and position (world); ``q: (nq,)`` a
        scratch hand configuration (its other fingers do not matter: only this
        finger's pairs with the palm, the object and the obstacles are checked).
        None when no candidate works.
        """
        hand, s, rng = self.gsn.hand, self.settings, self.rng
        world = self.validity.world
        if known is None:
            q_sol, solved = hand.finger_ik_candidates(i, tips)
        else:
            q_sol, solved = known[:, None, :], np.ones((len(tips), 1), dtype=bool)
        idx = hand.finger_q_index[i]
        # off the limits: a finger at a limit cannot follow the object
        m = s.joint_margin
        solved &= np.all((q_sol >= hand.lower[idx] + m) & (q_sol <= hand.upper[idx] - m), axis=2)
        clearance = link_clearance(hand, self.gsn.obj, i, q_sol, solved, R, t)
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

    def _cannot_hold(self, normals_out: FloatArray) -> np.ndarray:
        """(M,) True where a required (sub)grasp of ``normals_out: (M, k, 3)`` cannot hold.

        The half-space test, :func:`dexplan.model.grasp.halfspace.cannot_be_force_closure`.
        """
        vs = self.validity.settings
        return cannot_be_force_closure(normals_out, vs.mu, subgrasps=vs.subgrasps)

    def combinations(self, pose_xyzquat: FloatArray, pools: dict[int, FingerPool]) -> Combinations:
        """Grasps combined from per-finger pools, most promising first (validity not checked).

        :func:`~dexplan.planning.gsn.combinations.combine_pools` with the
        settings' ``combination_draws``, ``tip_clearance`` and ``combinations``.
        """
        s = self.settings
        if self._pairwise:
            return combine_pools_pairwise(
                pose_xyzquat,
                pools,
                self.gsn.hand,
                self.rng,
                mu=self.validity.settings.mu,
                tip_clearance=s.tip_clearance,
                count=self._combinations,
            )
        return combine_pools(
            pose_xyzquat,
            pools,
            self.gsn.hand,
            self.rng,
            draws=s.combination_draws,
            tip_clearance=s.tip_clearance,
            count=self._combinations,
            cannot_hold=self._cannot_hold,
        )
