"""Fingertip spheres: one sphere of the fingertip radius centred on each tip frame.

A fingertip is what dexplan says it is: a sphere of radius ``fingertip_radius``
centred on the fingertip frame. Only that sphere may touch the object; every
other collision element of the finger, the rest of the distal link included,
is checked against the object like any link (see ``docs/hands.md``).

Where the URDF has a ``<sphere>`` collision element centred on the tip frame
(on the tip link or on a link rigidly attached to it), that sphere is the
fingertip and its radius is the fingertip radius: a stated radius that differs
is refused. Where it has none, dexplan adds the sphere (named
``<tip frame>_fingertip``) to the collision model: the URDF text is left as
given, and the same hand built again (from a plan file) gets the same sphere.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import coal
import numpy as np
import pinocchio as pin

from dexplan.core.errors import ModelError, shorten
from dexplan.model.scenario.spec import MAX_FINGERTIP_RADIUS

__all__ = ["FingertipSpheres", "check_fingertip_radius", "fingertip_spheres"]

#: How far (m) a URDF sphere's centre may lie from the tip frame's origin and
#: still be the fingertip (URDF files carry 6 to 9 significant digits).
CENTRE_TOL = 1e-6
#: Relative difference between a stated radius and the URDF's sphere tolerated.
RADIUS_RTOL = 1e-6


@dataclass(frozen=True)
class FingertipSpheres:
    """Each finger's fingertip sphere in a hand's collision model.

    Attributes:
        radius: the fingertip radius (m), the same for every finger.
        geom_ids: per finger, the index of its sphere in the collision model.
        added: per finger, True when dexplan added the sphere (the URDF has none).
    """

    radius: float
    geom_ids: tuple[int, ...]
    added: tuple[bool, ...]


def check_fingertip_radius(value: object, name: str) -> float:
    """``value`` as a fingertip radius (m) in ``(0, MAX_FINGERTIP_RADIUS]``, else ModelError.

    The one rule for the radius everywhere (scenario, Python API, plan files):
    larger values are taken for a unit mistake.
    """
    try:
        # any object: float() raises on the wrong ones, reported below
        r = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        r = math.nan
    if isinstance(value, bool) or not (math.isfinite(r) and 0.0 < r <= MAX_FINGERTIP_RADIUS):
        raise ModelError(
            f"hand {name!r}: fingertip_radius must be a finite number in "
            f"(0, {MAX_FINGERTIP_RADIUS}] m, got {shorten(value)}"
        )
    return r


def _urdf_sphere(model: pin.Model, geom: pin.GeometryModel, fid: int) -> int | None:
    """Index of a sphere moved by tip frame ``fid``'s joint and centred on it, or None."""
    frame = model.frames[fid]
    for g, go in enumerate(geom.geometryObjects):
        if go.parentJoint != frame.parentJoint or not isinstance(go.geometry, coal.Sphere):
            continue
        offset = go.placement.translation - frame.placement.translation
        if float(np.linalg.norm(offset)) <= CENTRE_TOL:
            return g
    return None


def fingertip_spheres(
    model: pin.Model,
    geom: pin.GeometryModel,
    tip_frame_ids: Sequence[int],
    radius: object | None,
    name: str,
) -> FingertipSpheres:
    """Find each finger's fingertip sphere in ``geom``, adding the missing ones.

    Args:
        model: the hand's kinematic model.
        geom: its collision model; spheres are added to it in place.
        tip_frame_ids: per finger, the fingertip frame's id.
        radius: the stated fingertip radius (m), or None to read it from the
            URDF's spheres at the tip frames.
        name: the hand's name, for messages.

    Raises:
        ModelError: a radius outside ``(0, MAX_FINGERTIP_RADIUS]``; a stated
            radius that disagrees with a URDF sphere at a tip frame; URDF tip
            spheres of different radii; no radius stated and a tip frame
            without a sphere.
    """
    found = [_urdf_sphere(model, geom, fid) for fid in tip_frame_ids]
    urdf_radii = {
        model.frames[fid].name: float(geom.geometryObjects[g].geometry.radius)
        for fid, g in zip(tip_frame_ids, found, strict=True)
        if g is not None
    }
    if radius is None:
        missing = [
            model.frames[f].name for f, g in zip(tip_frame_ids, found, strict=True) if g is None
        ]
        if missing:
            raise ModelError(
                f"hand {name!r}: fingertip_radius is not given and fingertip frame "
                f"{missing[0]!r} has no <sphere> collision element centred on it: give "
                "fingertip_radius (dexplan then adds the sphere), or add "
                f'<collision><geometry><sphere radius="..."/></geometry></collision> to '
                "the fingertip link"
            )
        radius = next(iter(urdf_radii.values()))
    r = check_fingertip_radius(radius, name)
    for tip, r_urdf in urdf_radii.items():
        if abs(r_urdf - r) > RADIUS_RTOL * r:
            raise ModelError(
                f"hand {name!r}: fingertip_radius={r!r} m disagrees with the URDF's "
                f"<sphere radius={r_urdf!r}> at fingertip frame {tip!r}: give "
                f"fingertip_radius={r_urdf!r}, or leave it out to use the URDF's"
            )
    ids: list[int] = []
    for fid, g in zip(tip_frame_ids, found, strict=True):
        if g is None:
            frame = model.frames[fid]
            g = geom.addGeometryObject(
                pin.GeometryObject(
                    f"{frame.name}_fingertip",
                    frame.parentJoint,
                    fid,
                    frame.placement,
                    coal.Sphere(r),
                )
            )
        ids.append(int(g))
    return FingertipSpheres(r, tuple(ids), tuple(g is None for g in found))
