"""The trajectory a physics replay drives: the plan timed, with its grip controller's forces.

:func:`replay_trajectory` times the plan and computes the grip forces
(:func:`dexplan.execution.trajectory.build_trajectory`) the replay's fingers
feed forward, every loaded contact pressed with at least :data:`SQUEEZE`
where the effort limits allow it. The simulation is
:mod:`dexplan.execution.replay.simulation`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from dexplan.core.typing import FloatArray
from dexplan.execution.forces import force_settings_from_plan
from dexplan.execution.trajectory import Trajectory, Unbalanced, build_trajectory
from dexplan.model.grasp.grip_forces import ForceSettings
from dexplan.model.hand.hand import Hand
from dexplan.planfile import hand_from_plan

__all__ = ["SQUEEZE", "replay_settings", "replay_trajectory"]

#: Least normal force (N) the replay's grip controller presses every loaded contact
#: with, where the effort limits allow it (elsewhere the plan's own least force).
#: The fingers are position servos (gain ``KP``): a grip force is a target offset
#: of force / stiffness, and the paper hand's fingertips are 650-2300 N/m stiff
#: along the contact normals. The exporter's least force (0.2 N, what balances
#: the weight with the least squeeze) is then a 0.1-0.3 mm offset, less than the
#: object's tracking error: a finger on the side the object has moved away from
#: lets go (box_roll90's rolling seed 1 dropped the box that way, open and
#: closed loop). 2 N is a 1-3 mm offset; it stays within the effort limits and
#: the friction cones, as every grip force of the replay does.
SQUEEZE = 2.0


def replay_trajectory(
    doc: Mapping[str, Any],
    *,
    gravity: bool = True,
    base_dir: str | Path = ".",
    rate: float = 100.0,
    mass: float | None = None,
    gravity_vector: FloatArray | None = None,
    hand: Hand | None = None,
) -> Trajectory:
    """The timed trajectory a replay drives: grip forces pressing each contact with >= SQUEEZE.

    Where no such forces balance the wrench within the effort limits and the
    friction cones (a weak hold), the sample keeps the forces with the plan's
    own least normal force (or none, which the replay counts:
    :attr:`~dexplan.execution.replay.result.ReplayResult.unbalanced_samples`).
    Its ``settings`` are the squeezing ones.

    Args:
        doc: a validated plan.
        gravity: gravity on or off (as :func:`~dexplan.execution.replay.simulation.replay_plan`).
        base_dir: the plan's folder (mesh paths).
        rate: trajectory samples per second.
        mass: object mass (kg), default the plan's ``object.mass`` or 0.1.
        gravity_vector: (3,) overrides the plan's gravity (world frame).
        hand: the plan's hand (rebuilt from the file when None).

    Raises:
        TimingError: the plan cannot be timed.
    """
    if hand is None:
        hand = hand_from_plan(doc["hand"])
    settings, _ = replay_settings(doc, gravity, mass, gravity_vector)
    squeezed = replace(settings, min_normal_force=max(settings.min_normal_force, SQUEEZE))
    traj = build_trajectory(
        doc, rate=rate, settings=squeezed, base_dir=base_dir, hand=hand, unbalanced=Unbalanced.ZERO
    )
    short = np.isnan(traj.margins)
    if not short.any() or squeezed == settings:
        return traj
    plain = build_trajectory(
        doc, rate=rate, settings=settings, base_dir=base_dir, hand=hand, unbalanced=Unbalanced.ZERO
    )
    return replace(
        traj,
        forces=np.where(short[:, None, None], plain.forces, traj.forces),
        torsion=np.where(short[:, None], plain.torsion, traj.torsion),
        joint_torques=np.where(short[:, None], plain.joint_torques, traj.joint_torques),
        margins=np.where(short, plain.margins, traj.margins),
    )


def replay_settings(
    doc: Mapping[str, Any],
    gravity: bool,
    mass: float | None,
    gravity_vector: FloatArray | None,
) -> tuple[ForceSettings, FloatArray]:
    """The force settings of the replay and its gravity vector (zero with gravity off).

    Args:
        doc: a validated plan.
        gravity: gravity on or off.
        mass: object mass (kg) overriding the plan's, or None.
        gravity_vector: (3,) gravity overriding the plan's, or None.

    Returns:
        ``(settings, g)``: the :class:`~dexplan.model.grasp.grip_forces.ForceSettings` (their
        gravity ``g``) and (3,) ``g`` (m/s^2, world frame).
    """
    settings = force_settings_from_plan(doc, mass=mass, gravity=gravity_vector)
    g = np.asarray(settings.gravity, dtype=float) if gravity else np.zeros(3)
    settings = ForceSettings(
        mass=settings.mass,
        gravity=(float(g[0]), float(g[1]), float(g[2])),
        cone_margin=settings.cone_margin,
        min_normal_force=settings.min_normal_force,
    )
    return settings, g
