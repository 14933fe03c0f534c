"""A cheap, sound rejection of grasps that cannot be force closure: the half-space test.

If every inward contact normal of a (sub)grasp lies within ``90 deg - atan(mu)``
of one direction ``v`` (``v . n_c > sin(atan(mu))`` for every contact ``c``),
every friction cone (and every soft-finger generator, whose force lies in the
cone) lies in the open half-space ``v . f > 0``. No positive combination of
contact forces is then zero, so the (sub)grasp is not force closure, whatever
the torques. The test uses the mean inward normal as ``v``: it never rejects a
grasp the force-closure quality would accept, and it is vectorised over many
candidate grasps, so samplers and landing searches run it before the exact
(and far costlier) quality.
"""

from __future__ import annotations

import itertools

import numpy as np

from dexplan.core.typing import FloatArray


def cannot_be_force_closure(
    normals_out: FloatArray, mu: float, *, subgrasps: bool = True
) -> np.ndarray:
    """Which candidate grasps the half-space test proves not force closure.

    Args:
        normals_out: (M, k, 3) outward unit contact normals of M grasps of k
            contacts each, any common frame.
        mu: Coulomb friction coefficient (>= 0).
        subgrasps: test every (k-1)-contact subgrasp (a grasp is rejected
            when any of them is confined to a half-space), as GSn validity
            needs; False tests the k-contact grasp itself.

    Returns:
        (M,) True where the grasp (or one of its required subgrasps) cannot
        be force closure; False means "not ruled out", not "force closure".
    """
    inward = -np.asarray(normals_out, dtype=float)
    k = inward.shape[1]
    if subgrasps and k >= 2:
        keep = ~np.eye(k, dtype=bool)  # row j: the subgrasp without contact j
        subs = np.stack([inward[:, row] for row in keep], axis=1)  # (M, k, k-1, 3)
    else:
        subs = inward[:, None]  # (M, 1, k, 3)
    mean = subs.sum(axis=2)
    norm = np.linalg.norm(mean, axis=2, keepdims=True)
    v = mean / np.maximum(norm, 1e-12)
    cos = np.einsum("msc,msjc->msj", v, subs).min(axis=2)
    bound = mu / np.sqrt(1.0 + mu * mu)  # sin(atan(mu))
    return np.any((cos > bound) & (norm[..., 0] > 1e-9), axis=1)


#: Most distinct face normals :func:`faces_cannot_hold` enumerates combinations of.
MAX_FACE_NORMALS = 12


def faces_cannot_hold(
    face_normals_out: FloatArray, contacts: int, mu: float, *, subgrasps: bool = True
) -> bool:
    """Whether no grasp with every contact on a face passes the half-space test.

    Every choice of ``contacts`` face normals (repeats allowed: two fingers
    may share a face) is tested; True when :func:`cannot_be_force_closure`
    rules out all of them. A 3-finger hand on a cube at mu 0.8 is such a case:
    two fingers on adjacent faces push 90 degrees apart, more than their
    friction cones (2 x 38.7 degrees) can close, so some 2-finger subgrasp of
    every face-only grasp fails. Grasps then need edge or vertex contacts.

    Args:
        face_normals_out: (F, 3) distinct outward face normals, F at most
            :data:`MAX_FACE_NORMALS` (more: False, not decided).
        contacts: fingers in contact.
        mu: Coulomb friction coefficient.
        subgrasps: as for :func:`cannot_be_force_closure`.
    """
    normals = np.asarray(face_normals_out, dtype=float).reshape(-1, 3)
    if not 0 < len(normals) <= MAX_FACE_NORMALS or contacts < 1:
        return False
    choice = np.array(
        list(itertools.combinations_with_replacement(range(len(normals)), contacts)),
        dtype=np.int64,
    )
    return bool(cannot_be_force_closure(normals[choice], mu, subgrasps=subgrasps).all())
