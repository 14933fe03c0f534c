"""Contacts of fingers with fewer than 3 joints: where their fingertip can touch.

A fingertip centre has 3 coordinates. A finger of 3 or more joints reaches a
volume of them, so the sampler and the landings choose a contact point on the
surface and solve the finger's IK to it (the paper's way; it assumes 3 joints
or more). A finger of m = 2 joints reaches only a surface of fingertip centres,
which meets the sphere of centres at distance r from the object along a curve:
a contact chosen on the object is almost never reachable. So for such a finger
the contacts come from its joint space instead: the joint values where its
fingertip sphere touches the object,

    C = {q : sd(tip(q)) = r}     (sd: the object's signed distance, world frame)

a curve in the finger's 2-D joint space. :func:`contact_curve_samples` draws
joint values uniformly and projects each onto C by Newton steps of least norm
in joint space,

    q <- q - (sd(tip(q)) - r) a / |a|^2,    a = J(q)^T n,

where ``J`` is the fingertip centre's position Jacobian and ``n`` the outward
normal at the closest surface point (the gradient of ``sd``, so ``a`` is the
gradient of ``sd(tip(q))``). A projected configuration's contact is then what
the finger reaches: the closest surface point, not a point chosen beforehand.
The projection converges quadratically wherever ``a`` is not zero (the finger
moves its tip across the surface, not along it); configurations that leave the
joint limits or do not converge are dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dexplan.core.typing import FloatArray
from dexplan.model.hand.hand import Hand
from dexplan.model.objects.shape import Shape

__all__ = ["LOW_DOF_JOINTS", "ContactCurveSamples", "contact_curve_samples", "low_dof"]

#: Fingers of at most this many joints get their contacts from joint space.
LOW_DOF_JOINTS = 2
#: Distance error (m) under which a projected fingertip touches the surface.
CURVE_TOL = 1e-10
#: Newton steps of the projection.
_STEPS = 30
#: A step's joint change is capped (rad): Newton from far off can overshoot.
_MAX_STEP = 0.3


@dataclass(frozen=True)
class ContactCurveSamples:
    """Configurations of one finger whose fingertip touches the object.

    Attributes:
        q: ``(K, m)`` the finger's joints, within its limits.
        tips: ``(K, 3)`` fingertip centres, world frame (at distance r from
            the surface to :data:`CURVE_TOL`).
        points: ``(K, 3)`` contact points, object frame.
        normals_out: ``(K, 3)`` outward unit normals there, object frame.
    """

    q: FloatArray
    tips: FloatArray
    points: FloatArray
    normals_out: FloatArray


def low_dof(hand: Hand, finger: int) -> bool:
    """Whether ``finger`` has fewer than 3 joints (its contacts lie on a curve)."""
    return len(hand.finger_q_index[finger]) <= LOW_DOF_JOINTS


def contact_curve_samples(
    hand: Hand,
    obj: Shape,
    finger: int,
    rotation: FloatArray,
    position: FloatArray,
    count: int,
    rng: np.random.Generator,
    margin: float = 0.0,
) -> ContactCurveSamples:
    """Draw ``count`` joint values of ``finger`` and project them onto its contacts.

    Args:
        hand: the hand (the finger must be a revolute chain).
        obj: the object.
        finger: the finger.
        rotation: (3, 3) the object's rotation (world from object).
        position: (3,) the object's position, world frame.
        count: joint values drawn.
        rng: the random generator.
        margin: the kept configurations stay this far (rad) inside the limits.

    Returns:
        The converged configurations (possibly none), in drawing order.
    """
    idx = hand.finger_q_index[finger]
    lo, hi = hand.lower[idx] + margin, hand.upper[idx] - margin
    chain = hand.finger_chain(finger)
    m = len(idx)
    empty = np.zeros((0, 3))
    if chain is None or count <= 0 or np.any(lo > hi):
        return ContactCurveSamples(np.zeros((0, m)), empty, empty, empty)
    R, t, r = rotation, np.asarray(position, dtype=float), hand.fingertip_radius
    q = rng.uniform(lo, hi, size=(count, m))
    for _ in range(_STEPS):
        tips, J = chain.jacobian(q)
        sd, grad = obj.signed_distance_and_gradient((tips - t) @ R)
        g = np.atleast_1d(np.asarray(sd)) - r
        a = np.einsum("nim,ni->nm", J, np.atleast_2d(grad) @ R.T)
        norm2 = np.maximum(np.einsum("nm,nm->n", a, a), 1e-18)
        dq = np.clip(-(g / norm2)[:, None] * a, -_MAX_STEP, _MAX_STEP)
        q = np.clip(q + dq, lo, hi)
    tips = chain.tips(q)
    p_obj = (tips - t) @ R
    sd, grad = obj.signed_distance_and_gradient(p_obj)
    sd = np.atleast_1d(np.asarray(sd))
    grad = np.atleast_2d(grad)
    ok = np.abs(sd - r) < CURVE_TOL
    points = p_obj[ok] - sd[ok, None] * grad[ok]
    return ContactCurveSamples(q[ok], tips[ok], points, grad[ok])
