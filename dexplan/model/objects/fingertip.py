"""Where a fingertip sphere pushes on a shape: the one contact-reading rule.

The plan verifier, the viewer and the grip forces (:mod:`dexplan.model.grasp.grip_forces`) read a
stated contact and the fingertip centre the same way: on a face, the stated
contact's own normal; at an edge or corner (of a box, or a mesh's sharp convex
one), the direction from the edge to the fingertip centre (a fingertip on an
edge pushes along any direction between the two faces' normals, and the
closest point of the contact itself would give one face's normal).
"""

from __future__ import annotations

import numpy as np

from dexplan.core.pose import length
from dexplan.core.typing import FloatArray
from dexplan.model.objects.shape import Shape

__all__ = ["TIP_DISTANCE_TOL", "fingertip_contact"]

#: Largest |fingertip distance to the surface - radius| of a contact (m).
TIP_DISTANCE_TOL = 1e-3


def fingertip_contact(
    obj: Shape,
    c_obj: FloatArray,
    tip_obj: FloatArray,
    radius: float,
    stated: tuple[FloatArray, FloatArray] | None = None,
) -> tuple[FloatArray, FloatArray, float]:
    """Where and along which normal a fingertip pushes on the object (the one rule).

    The fingertip sphere touches the surface at the closest point to its
    centre, pushing along the normal there. On a face that is the stated
    contact's own normal (exact per contact, so equal contacts give equal
    answers); at an edge or corner (a box's, a mesh's sharp convex one), the
    direction from the edge to the fingertip centre. The verifier and the
    viewer both read contacts this way.

    Args:
        obj: the object shape.
        c_obj: (3,) the stated contact, object frame.
        tip_obj: (3,) the fingertip centre, object frame.
        radius: fingertip radius (m).
        stated: ``obj.closest_point(c_obj)`` when the caller has it already
            (a transfer holds the same contacts at every waypoint).

    Returns:
        ``(p, n_out, gap)``: (3,) the surface point of the contact and (3,) the
        outward unit normal the fingertip pushes along, both object frame, and
        the distance (m) between the stated contact and the fingertip's own.
    """
    p_s, n_s = (np.asarray(v, dtype=float).reshape(3) for v in (stated or obj.closest_point(c_obj)))
    gap = length(p_s + radius * n_s - tip_obj)
    if gap > TIP_DISTANCE_TOL:
        p_t, n_s = (np.asarray(v, dtype=float).reshape(3) for v in obj.closest_point(tip_obj))
        gap = length(p_t - c_obj)
    return p_s, n_s, gap
