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

IK puts the fingertips on the surface to solver precision, so the state lies
on GSk without a projection step. All randomness comes from the
``numpy.random.Generator`` given by the caller: same seed, same samples.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from dexplan.planning.deadline import Deadline
from dexplan.planning.gsn import POSE_DIM, GraspSubspace
from dexplan.planning.validity import GraspValidity
from dexplan.pose import quat_to_matrix, random_quaternion, slerp
from dexplan.typing import FloatArray


@dataclass(frozen=True)
class SamplerSettings:
    """Settings of :class:`GraspSampler`.

    Attributes:
        candidates: surface points drawn per finger and attempt.
        max_attempts: attempts per :meth:`GraspSampler.sample` call before None.
        tip_clearance: minimum gap between two fingertip spheres (m).
        min_facing: minimum cosine between a candidate's outward normal and
            the direction to the finger's base (links stay clear of the object).
        balance_pool: reachable candidates compared for normal balance.
    """

    candidates: int = 48
    max_attempts: int = 50
    tip_clearance: float = 0.004
    min_facing: float = -0.3
    balance_pool: int = 6


@dataclass
class SamplerStats:
    """Counters of the sampler: attempts, valid samples, IK failures, time."""

    attempts: int = 0
    valid: int = 0
    ik_failures: int = 0
    time_s: float = 0.0

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
            "valid_fraction": self.valid_fraction,
            "samples_per_second": self.samples_per_second,
        }


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
        self.settings = settings or SamplerSettings()
        self.stats = SamplerStats()
        self._reach = [self._reach_shell(i) for i in range(gsn.hand.n_fingers)]

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
            pts, n_out = gsn.obj.sample_surface(s.candidates, rng)
            tips = (pts + r * n_out) @ R.T + t  # candidate tip centres, world frame
            centre, dmin, dmax = self._reach[i]
            to_base = centre - tips
            d = np.linalg.norm(to_base, axis=1)
            ok = (d >= dmin) & (d <= dmax)
            # the finger comes from outside: the surface must face its base
            ok &= np.einsum("ij,ij->i", n_out @ R.T, to_base) > s.min_facing * d
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
