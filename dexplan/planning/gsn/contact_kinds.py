"""Which contacts the GSn sampler draws: face points, and edge points where faces cannot hold.

A fingertip on a face pushes inside the friction cone of the face normal; one
on an edge pushes along any direction between the two faces' normals. Some
hands hold a box only with edges: fingers of more than 3 joints whose pads
touch the faces they reach with parallel normals (the Allegro), and every
hand whose required subgrasps cannot be force closure with faces alone (a
3-finger hand on a cube: some 2-finger subgrasp of every face-only grasp
pushes across adjacent faces, see
:func:`dexplan.model.grasp.halfspace.faces_cannot_hold`).
"""

from __future__ import annotations

import numpy as np

from dexplan.model.grasp.halfspace import MAX_FACE_NORMALS, faces_cannot_hold
from dexplan.model.hand.hand import Hand
from dexplan.model.objects import Shape

__all__ = ["face_normals", "faces_only_reason"]

#: Surface samples read for an object's distinct face normals (fixed seed).
_FACE_SAMPLES = 4096


def face_normals(obj: Shape) -> np.ndarray | None:
    """The object's distinct outward face normals ``(F, 3)`` (object frame), or None.

    None for curved shapes and shapes without edges (more than
    :data:`~dexplan.model.grasp.halfspace.MAX_FACE_NORMALS` normals, or no
    edge points): there is no face-only question to ask.
    """
    e_pts, _ = obj.sample_edges(1, np.random.default_rng(0))
    if len(e_pts) == 0:
        return None
    _, normals = obj.sample_surface(_FACE_SAMPLES, np.random.default_rng(0))
    distinct = np.unique(np.round(normals, 6), axis=0)
    return distinct if len(distinct) <= MAX_FACE_NORMALS else None


def faces_only_reason(
    obj: Shape, hand: Hand, contacts: int, mu: float, subgrasps: bool = True
) -> str | None:
    """Why face points alone cannot give a valid grasp of ``obj``, or None when they may.

    Args:
        obj: the object.
        hand: the hand (unused by the test; named for the message).
        contacts: fingers in contact.
        mu: friction coefficient.
        subgrasps: every (contacts - 1) subgrasp must be force closure.

    Returns:
        A short reason (``"faces only: no 2-finger subgrasp can be force
        closure at mu 0.8"``), or None.
    """
    normals = face_normals(obj)
    if normals is None or not faces_cannot_hold(normals, contacts, mu, subgrasps=subgrasps):
        return None
    k = contacts - 1 if subgrasps else contacts
    what = f"{k}-finger subgrasp" if subgrasps else f"{k}-finger grasp"
    return f"faces only: no {what} of hand {hand.name!r} can be force closure at mu {mu:g}"
