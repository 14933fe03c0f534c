"""A replay's drop: the segment and finger it happened in, and how strong the hold was.

The hold's strength is the force-closure quality (:mod:`dexplan.model.grasp.force_closure`)
of the contacts holding the object, twice: at the plan's contacts at the drop,
and at the contacts the same fingertips really had in the simulation, the last
time in the drop's segment before the object lost track that all of them
touched it (tips roll, so these differ). Both are computed by a fresh exact
(``nnls``) solver: the shared default one warm-starts OSQP from whatever it
solved before in the process, and a report must not depend on that.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dexplan.core.typing import FloatArray
from dexplan.execution.replay.control import pose_se3
from dexplan.execution.replay.result import Drop
from dexplan.execution.trajectory import Trajectory
from dexplan.model.grasp.force_closure import ForceClosure
from dexplan.model.hand.hand import Hand
from dexplan.model.objects import Shape
from dexplan.planfile import PlanModels

__all__ = ["DropScene", "describe_drop", "segment_of"]


@dataclass(frozen=True)
class DropScene:
    """What the simulation saw around a drop (``n`` fingers, ``nq`` joints).

    Attributes:
        drop_sample: index of the first trajectory sample farther than the drop
            tolerance from the plan.
        lost_sample: index of the first sample outside the tracking tolerances
            (at or before ``drop_sample``).
        hold_sample: the sample the simulated hold is read at (at or before
            ``lost_sample``).
        sim_pose: (7,) the simulated object pose at ``hold_sample``, world frame.
        sim_q: (nq,) the simulated joints at ``hold_sample``.
        touching: (n,) which of the fingers the plan holds the object with at the
            drop touched it in MuJoCo at ``hold_sample``.
    """

    drop_sample: int
    lost_sample: int
    hold_sample: int
    sim_pose: FloatArray
    sim_q: FloatArray
    touching: np.ndarray


def describe_drop(traj: Trajectory, models: PlanModels, scene: DropScene) -> Drop:
    """The :class:`Drop` record of a replay that dropped the object.

    Args:
        traj: the replayed trajectory (its segments, planned contacts and normals).
        models: the plan's models (object, friction, contact model).
        scene: what the simulation saw.
    """
    k = scene.drop_sample
    seg = segment_of(traj, k)
    kind, finger, _, _ = traj.segments[seg]
    holding = ~np.isnan(traj.contacts[k, :, 0])
    fc = ForceClosure(solver="nnls")
    planned = _quality(fc, models, traj.contacts[k, holding], traj.normals[k, holding])
    P, N = _measured_contacts(models.obj, models.hand, scene)
    measured = _quality(fc, models, P, N)
    return Drop(
        time=float(traj.t[k]),
        lost_track_time=float(traj.t[scene.lost_sample]),
        measured_hold_time=float(traj.t[scene.hold_sample]),
        segment=seg,
        kind=str(kind),
        finger=None if kind == "transfer" else finger,
        planned_hold_quality=planned,
        measured_hold_quality=measured,
        holding_fingers=tuple(int(f) for f in np.flatnonzero(holding)),
    )


def segment_of(traj: Trajectory, k: int) -> int:
    """The segment sample ``k`` lies in (the later one at a shared boundary sample)."""
    found = 0
    for s, (_, _, first, last) in enumerate(traj.segments):
        if first <= k <= last:
            found = s
            if k < last:
                break
    return found


def _measured_contacts(obj: Shape, hand: Hand, scene: DropScene) -> tuple[FloatArray, FloatArray]:
    """(c, 3) contact points and inward normals (object frame) of the touching fingertips.

    Each is the object's surface point closest to the simulated tip centre.
    """
    X = pose_se3(scene.sim_pose)
    tips = hand.fingertip_positions(scene.sim_q)
    pts, nrm = [], []
    for f in np.flatnonzero(scene.touching):
        c, n_out = obj.closest_point(X.actInv(np.asarray(tips[f], dtype=float)))
        pts.append(np.reshape(c, 3))
        nrm.append(-np.reshape(n_out, 3))
    return np.reshape(pts, (-1, 3)), np.reshape(nrm, (-1, 3))


def _quality(fc: ForceClosure, models: PlanModels, P: FloatArray, N: FloatArray) -> float:
    """Force-closure quality of contacts ``P`` with inward normals ``N`` (0 for fewer than 2)."""
    if len(P) < 2:
        return 0.0
    return float(
        fc.quality(
            P,
            N,
            models.mu,
            edges=models.friction_edges,
            torque_scale=models.obj.characteristic_length,
            contact_model=models.contact_model,
            torsion=models.torsion,
        )
    )
