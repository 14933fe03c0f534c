"""Hand-overs: a replay moves the load between fingers gradually, at rest.

A plan switches the set of fingers holding the object at segment boundaries:
a regrasp's finger lands (its last sample) and the next regrasp's finger lets
go (the same sample). The timed trajectory
(:func:`dexplan.execution.trajectory.build_trajectory`) switches the grip
forces from one balancing set to the other within one sample and moves on at
once, so a landing finger must take its load, and a releasing finger's load
pass to the others, within one sample period (10 ms). Physical fingers are
position servos: a step in the force set is a step in the targets, and the
object slips while the new force set builds up (on the Allegro hand, whose
effort limits leave small grip forces, most drops of the replay without
hand-overs came 0.05-0.3 s after a landing or a release).

:func:`insert_handovers` stretches the trajectory: at every boundary where the
loaded fingers change it inserts :data:`HANDOVER_TIME` at rest in the
boundary's configuration, in which the forces go linearly from the old
loaded set to the new one, both solved at that configuration. Equilibrium is
linear in the forces and the (margin-shrunk) friction cones and the effort
limits are convex, so every blended force set balances the object within the
cones and the limits. A landing finger is in contact from the first sample of
its hand-over with no load, and a releasing finger keeps its contact until
its load is zero: it lifts only after the hand-over.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from dexplan.core.typing import FloatArray
from dexplan.execution.replay.squeeze import SqueezeSolver
from dexplan.execution.trajectory import Trajectory
from dexplan.model.grasp.grip_forces import GripForceError, GripForceSolver

__all__ = ["HANDOVER_TIME", "HandOvers", "insert_handovers", "loaded_fingers_of"]

#: Time (s) a hand-over takes: the load ramps linearly over it, the hand at rest.
HANDOVER_TIME = 0.3


@dataclass(frozen=True)
class HandOvers:
    """Where a stretched trajectory hands load over (``m`` samples, ``n`` fingers).

    Attributes:
        blend: (m,) how far each sample is into its hand-over, from 0 (the old
            loaded set's forces) to 1 (the new one's); NaN outside hand-overs.
        loaded_from: (m, n) the fingers loaded before each sample's hand-over
            (outside hand-overs, those loaded at the sample).
        loaded_to: (m, n) the fingers loaded after it (likewise).
        count: how many hand-overs were inserted.
        added_time: the time they add to the plan's execution (s).
    """

    blend: FloatArray
    loaded_from: np.ndarray
    loaded_to: np.ndarray
    count: int
    added_time: float


def loaded_fingers_of(traj: Trajectory) -> np.ndarray:
    """(m, n) the fingers each sample loads: in contact with a nonzero planned force."""
    holding = ~np.isnan(traj.forces[:, :, 0])
    return holding & (np.linalg.norm(np.nan_to_num(traj.forces), axis=2) > 0)


def insert_handovers(
    traj: Trajectory,
    solver: GripForceSolver | SqueezeSolver,
    duration: float = HANDOVER_TIME,
    rate: float = 100.0,
) -> tuple[Trajectory, HandOvers]:
    """The trajectory with a hand-over at every boundary where the loaded fingers change.

    Boundary sample ``b`` (shared by segments ``s`` and ``s + 1``) becomes
    ``N + 1`` samples at ``b``'s configuration and at rest, ``N = duration *
    rate``: sample ``j`` carries ``(1 - j / N) F_old + (j / N) F_new``, with
    ``F_old`` the forces of the fingers loaded at ``b - 1`` and ``F_new`` those
    loaded at ``b``, both at ``b``'s configuration and contacts. Segment ``s``
    ends, and ``s + 1`` starts, at the last of them; later samples and
    segments are delayed by ``N / rate``.

    Args:
        traj: the replay's timed trajectory (its forces from ``solver``'s settings).
        solver: the plan's grip-force solver (the replay's settings).
        duration: each hand-over's time (s); 0 inserts none.
        rate: the trajectory's samples per second.

    Returns:
        ``(stretched, handovers)``.
    """
    loaded = loaded_fingers_of(traj)
    n_ins = round(duration * rate)
    bounds = np.array(
        [
            last
            for _, _, _, last in traj.segments[:-1]
            if n_ins > 0 and last > 0 and not np.array_equal(loaded[last - 1], loaded[last])
        ],
        dtype=int,
    )
    counts = np.ones(traj.t.size, dtype=int)
    counts[bounds] += n_ins
    src = np.repeat(np.arange(traj.t.size), counts)
    within = np.arange(src.size) - np.repeat(np.cumsum(counts) - counts, counts)
    delay = (np.searchsorted(bounds, src) * n_ins + within) / rate
    new = {k: getattr(traj, k)[src] for k in _COLUMNS}
    new["t"] = traj.t[src] + delay
    blend = np.full(src.size, np.nan)
    lfrom, lto = loaded[src], loaded[src]
    for k, b in enumerate(bounds):
        rows = b + k * n_ins + np.arange(n_ins + 1)  # the hand-over's samples
        lam = np.arange(n_ins + 1) / n_ins
        blend[rows], lfrom[rows], lto[rows] = lam, loaded[b - 1], loaded[b]
        _blend_forces(new, rows, lam, _old_forces(traj, solver, b, loaded[b - 1]), traj, b)

    def moved(k: int) -> int:  # old sample k's last copy
        return k + n_ins * int(np.searchsorted(bounds, k, side="right"))

    segments = tuple((kind, f, moved(a), moved(z)) for kind, f, a, z in traj.segments)
    starts = np.asarray(traj.timing.start_times, dtype=float) + np.array(
        [(moved(a) - a) / rate for _, _, a, _ in traj.segments]
    )
    stretched = replace(
        traj, segments=segments, timing=replace(traj.timing, start_times=starts), **new
    )
    return stretched, HandOvers(blend, lfrom, lto, int(bounds.size), bounds.size * n_ins / rate)


#: The trajectory's per-sample columns (``t`` included).
_COLUMNS = (
    "t",
    "q",
    "qd",
    "qdd",
    "object_pose",
    "object_velocity",
    "object_acceleration",
    "contacts",
    "normals",
    "forces",
    "torsion",
    "joint_torques",
    "margins",
)


def _old_forces(
    traj: Trajectory, solver: GripForceSolver | SqueezeSolver, b: int, loaded_old: np.ndarray
) -> tuple[FloatArray, FloatArray, FloatArray, float]:
    """The forces of the fingers loaded before boundary ``b``, at ``b``'s configuration.

    Returns:
        ``(forces (n, 3), torsion (n,), joint_torques (nq,), margin)``; where
        they do not balance there, those of sample ``b - 1`` (its own
        configuration, 10 ms earlier).
    """
    contacts = [None if np.isnan(c[0]) else c for c in traj.contacts[b]]
    use = tuple(bool(x) and c is not None for x, c in zip(loaded_old, contacts, strict=True))
    try:
        g = solver.solve(traj.q[b], traj.object_pose[b], contacts, use)
    except GripForceError:
        a = b - 1
        return traj.forces[a], traj.torsion[a], traj.joint_torques[a], float(traj.margins[a])
    return g.forces, g.torsion, g.joint_torques, g.margin


def _blend_forces(
    new: dict[str, FloatArray],
    rows: np.ndarray,
    lam: FloatArray,
    old: tuple[FloatArray, FloatArray, FloatArray, float],
    traj: Trajectory,
    b: int,
) -> None:
    """Fill a hand-over's samples: at rest at ``b``, forces blended from ``old`` to ``b``'s.

    A finger in contact on either side holds (zero force where it is not
    loaded); the margin kept is the smaller of the two sets'.
    """
    f_old, tor_old, tau_old, m_old = old
    f_new, tor_new, tau_new = traj.forces[b], traj.torsion[b], traj.joint_torques[b]
    free = np.isnan(traj.contacts[b, :, 0])  # no contact on either side of the boundary
    w, v = lam[:, None, None], (1.0 - lam)[:, None, None]
    f = v * np.nan_to_num(f_old) + w * np.nan_to_num(f_new)
    f[:, free] = np.nan
    tor = v[:, :, 0] * np.nan_to_num(tor_old) + w[:, :, 0] * np.nan_to_num(tor_new)
    tor[:, free] = np.nan
    new["forces"][rows], new["torsion"][rows] = f, tor
    new["joint_torques"][rows] = v[:, :, 0] * tau_old + w[:, :, 0] * tau_new
    new["margins"][rows] = min(m_old, float(traj.margins[b]))
    for key in ("qd", "qdd", "object_velocity", "object_acceleration"):
        new[key][rows] = 0.0
