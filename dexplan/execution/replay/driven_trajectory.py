"""The trajectory a physics replay drives: the plan timed, with its grip controller's forces.

:func:`replay_trajectory` times the plan
(:func:`dexplan.execution.trajectory.build_trajectory`) and gives every sample
the grip forces the replay's fingers feed forward: those of
:class:`dexplan.execution.replay.squeeze.SqueezeSolver`, which presses each
loaded contact harder than the plan's least forces where the hold allows it.
The simulation is :mod:`dexplan.execution.replay.simulation`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from dexplan.core.typing import FloatArray
from dexplan.execution.forces import force_settings_from_plan
from dexplan.execution.replay.squeeze import SqueezeSolver
from dexplan.execution.trajectory import Trajectory, Unbalanced, build_trajectory
from dexplan.model.grasp.grip_forces import ForceSettings, GripForceError
from dexplan.model.hand.hand import Hand
from dexplan.planfile import hand_from_plan

__all__ = ["replay_settings", "replay_trajectory"]


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
    """The timed trajectory a replay drives, with the squeezing grip forces.

    Each sample's forces are :class:`~dexplan.execution.replay.squeeze.SqueezeSolver`'s
    for the fingers the plan loads there; where no forces balance the wrench
    (a tampered plan) the sample has none, which the replay counts
    (:attr:`~dexplan.execution.replay.result.ReplayResult.unbalanced_samples`).
    Its ``settings`` are the replay's (the plan's least normal force).

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
    traj = build_trajectory(
        doc, rate=rate, settings=settings, base_dir=base_dir, hand=hand, unbalanced=Unbalanced.ZERO
    )
    solver = SqueezeSolver(doc, settings, hand, base_dir)
    forces, torsion = traj.forces.copy(), traj.torsion.copy()
    torques, margins = traj.joint_torques.copy(), traj.margins.copy()
    holding = ~np.isnan(traj.forces[:, :, 0])
    loaded = holding & (np.linalg.norm(np.nan_to_num(traj.forces), axis=2) > 0)
    for k in np.flatnonzero(~np.isnan(traj.margins)):
        contacts = [c if h else None for c, h in zip(traj.contacts[k], holding[k], strict=True)]
        try:
            g = solver.solve(traj.q[k], traj.object_pose[k], contacts, tuple(loaded[k]))
        except GripForceError:  # the plan's own forces balanced here: keep them
            continue
        forces[k] = np.where(holding[k][:, None], g.forces, np.nan)
        torsion[k] = np.where(holding[k], g.torsion, np.nan)
        torques[k], margins[k] = g.joint_torques, g.margin
    return replace(traj, forces=forces, torsion=torsion, joint_torques=torques, margins=margins)


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
