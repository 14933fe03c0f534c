"""Grip forces at a plan file's waypoints (the model is :mod:`dexplan.model.grasp.grip_forces`).

:func:`plan_waypoint_forces` solves :class:`~dexplan.model.grasp.grip_forces.GripForceSolver` at
every waypoint of a validated plan, with the plan's object mass and gravity
(:func:`force_settings_from_plan`); the export, the timing and the replay
read their forces here.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, cast

import numpy as np

from dexplan.core.typing import FloatArray
from dexplan.model.grasp.grip_forces import (
    DEFAULT_GRAVITY,
    DEFAULT_MASS,
    ForceSettings,
    GripForces,
    GripForceSolver,
    loaded_fingers,
)
from dexplan.model.hand.hand import Hand
from dexplan.planfile import hand_from_plan, shape_of

__all__ = [
    "force_settings_from_plan",
    "plan_waypoint_forces",
    "solver_from_plan",
]


def force_settings_from_plan(
    doc: Mapping[str, Any],
    *,
    mass: float | None = None,
    gravity: Sequence[float] | FloatArray | None = None,
    **kwargs: Any,
) -> ForceSettings:
    """Settings from a plan's ``object.mass`` and ``world.gravity``, overridden by arguments.

    Args:
        doc: a validated plan document.
        mass: object mass (kg) overriding the plan's.
        gravity: (3,) gravity (m/s^2, world frame) overriding the plan's.
        **kwargs: other :class:`ForceSettings` fields.
    """
    m = mass if mass is not None else doc["object"].get("mass", DEFAULT_MASS)
    world = doc.get("world") or {}
    g = gravity if gravity is not None else world.get("gravity", DEFAULT_GRAVITY)
    # ForceSettings checks that there are three: a wrong count is its InvalidInputError
    g3 = cast("tuple[float, float, float]", tuple(float(v) for v in g))
    return ForceSettings(mass=float(m), gravity=g3, **kwargs)


def solver_from_plan(
    doc: Mapping[str, Any],
    settings: ForceSettings,
    hand: Hand | None = None,
    base_dir: str | Path = ".",
) -> GripForceSolver:
    """A :class:`GripForceSolver` for a validated plan (hand, object, friction from the file)."""
    if hand is None:
        hand = hand_from_plan(doc["hand"])
    obj = shape_of(doc["object"], Path(base_dir), "object")
    return GripForceSolver(
        hand,
        obj,
        float(doc["mu"]),
        int(doc.get("friction_edges", 8)),
        str(doc.get("contact_model", "point")),
        float(doc.get("torsion", 0.0)),
        settings,
    )


def plan_waypoint_forces(
    doc: Mapping[str, Any],
    settings: ForceSettings | None = None,
    *,
    hand: Hand | None = None,
    base_dir: str | Path = ".",
) -> list[list[GripForces]]:
    """Grip forces at every waypoint of a validated plan, per segment.

    A regrasp's free finger carries no load at any of its waypoints (its end
    waypoints included: it lifts off unloaded and lands before taking load).

    Raises:
        GripForceError: at some waypoint no forces balance the wrench; the
            message names the segment and the waypoint.
    """
    settings = force_settings_from_plan(doc) if settings is None else settings
    solver = solver_from_plan(doc, settings, hand, base_dir)
    out = []
    for si, seg in enumerate(doc["segments"]):
        free = seg["finger"] if seg["kind"] == "regrasp" else None
        rows = []
        for wi, w in enumerate(seg["waypoints"]):
            contacts = [None if c is None else np.asarray(c, dtype=float) for c in w["contacts"]]
            rows.append(
                solver.solve(
                    np.asarray(w["q"], dtype=float),
                    np.asarray(w["object_pose_xyzquat"], dtype=float),
                    contacts,
                    loaded_fingers(contacts, free),
                    where=f"segment {si}, waypoint {wi}",
                )
            )
        out.append(rows)
    return out
