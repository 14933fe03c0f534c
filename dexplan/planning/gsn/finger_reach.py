"""Where a finger can touch the object: its reach shell, the fingertip's fit, its links' clearance.

The cheap filters of the grasp sampler's contact candidates, before any IK
or collision check.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dexplan.core.typing import FloatArray
from dexplan.model.hand.hand import Hand
from dexplan.model.objects import Shape

#: Depth (m) a fingertip sphere on a candidate contact may dip into the object
#: elsewhere: in a concavity tighter than the fingertip it does, and the state
#: is off GSn by that much per finger. OMPL rejects a start state whose
#: constraint norm exceeds 1e-5 (the roadmap's constraint tolerance); five
#: fingers at this depth stay below it.
FIT_TOL = 2e-6

#: Random finger configurations whose fingertips estimate a reach shell.
_SHELL_SAMPLES = 400


@dataclass(frozen=True)
class ReachShell:
    """A fingertip's reach, estimated by forward kinematics.

    Attributes:
        centre: (3,) the finger's first joint origin at the neutral configuration.
        inner: smallest fingertip distance from ``centre`` (m), 10 % inside.
        outer: largest fingertip distance from ``centre`` (m), 2 % outside.
    """

    centre: FloatArray
    inner: float
    outer: float

    def contains(self, tips: FloatArray, normals_w: FloatArray, min_facing: float) -> np.ndarray:
        """(N,) candidate fingertip centres ``tips: (N, 3)`` in the shell, facing the finger.

        The outward normals ``normals_w: (N, 3)`` (world frame) must face the
        finger's base (cosine above ``min_facing``): the finger comes from outside.
        """
        to_base = self.centre - tips
        d = np.linalg.norm(to_base, axis=1)
        ok = (d >= self.inner) & (d <= self.outer)
        ok &= np.einsum("ij,ij->i", normals_w, to_base) > min_facing * d
        return ok


def reach_shell(hand: Hand, finger: int) -> ReachShell:
    """The reach shell of ``finger``'s fingertip (seeded by the finger: same hand, same shell)."""
    idx = hand.finger_q_index[finger]
    rng = np.random.default_rng(finger)
    q = np.tile(hand.neutral, (_SHELL_SAMPLES, 1))
    q[:, idx] = rng.uniform(hand.lower[idx], hand.upper[idx], size=(_SHELL_SAMPLES, len(idx)))
    q[0, idx], q[1, idx] = hand.lower[idx], hand.upper[idx]
    chain = hand.finger_chain(finger)  # batched forward kinematics, when revolute
    if chain is not None:
        tips = chain.tips(q[:, idx])
    else:
        tips = np.array([hand.fingertip_positions(qi)[finger] for qi in q])
    centre = hand.joint_origin(int(idx[0]), hand.neutral)
    d = np.linalg.norm(tips - centre, axis=1)
    return ReachShell(centre, float(d.min()) * 0.9, float(d.max()) * 1.02)


def fingertip_fits(
    obj: Shape, radius: float, points: FloatArray, normals_out: FloatArray
) -> np.ndarray:
    """(N,) True where a fingertip sphere on the contact touches the object there only.

    ``points, normals_out: (N, 3)`` candidate contacts and outward normals,
    object frame. In a concavity tighter than the fingertip the sphere
    centred at ``point + radius * normal`` dips into the object elsewhere;
    the state would be off GSn by that depth (the collision check tolerates
    it, the constraint does not), so such contacts are not offered (up to
    :data:`FIT_TOL`).
    """
    if not len(points):
        return np.zeros(0, dtype=bool)
    d = np.atleast_1d(np.asarray(obj.signed_distance(points + radius * normals_out)))
    return np.asarray(d >= radius - FIT_TOL)


def link_clearance(
    hand: Hand,
    obj: Shape,
    finger: int,
    q_sol: FloatArray,
    solved: np.ndarray,
    R: FloatArray,
    t: FloatArray,
) -> FloatArray:
    """Signed distance from the object to a finger's joint axes and link midpoints.

    Args:
        hand: the hand.
        obj: the object.
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
    chain = hand.finger_chain(finger)
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
    sd = obj.signed_distance((probe.reshape(-1, 3) - t) @ R)
    out[solved] = np.asarray(sd).reshape(len(q), -1).min(axis=1)
    return out
