"""Recording of a physics replay: the plan and the replay side by side (extra ``viz``).

Two 3D views on one ``time`` timeline (seconds from the trajectory's start):
``world/plan`` (the timed plan: object and fingertips) and ``world/replay``
(the MuJoCo replay), each with the obstacles, and a plot of the object's
position error (mm) and orientation error (rad) against the plan.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from dexplan.core.typing import FloatArray
from dexplan.planfile import hand_from_plan, shape_of
from dexplan.viz.blueprints import replay_blueprint
from dexplan.viz.scene import obstacles_from_dicts
from dexplan.viz.session import TIME, recording, rerun_module, transform
from dexplan.viz.shapes import shape_archetype

if TYPE_CHECKING:  # rerun's types for annotations; at run time rerun loads on first use
    import rerun

__all__ = ["ReplayTrace", "record_replay"]

_PLAN = (90, 140, 230, 255)
_REPLAY = (230, 120, 60, 255)
_OBSTACLE = (150, 150, 150, 120)


class ReplayTrace(Protocol):
    """What a recording reads of a replay: a ``ReplayResult`` of :mod:`dexplan.execution.replay`.

    Arrays have one row per trajectory sample; poses are ``[x, y, z, qx, qy, qz, qw]``
    in the world frame.
    """

    @property
    def t(self) -> FloatArray:
        """``(m,)`` sample times (s from the trajectory's start)."""

    @property
    def planned_pose(self) -> FloatArray:
        """``(m, 7)`` the plan's object pose at the sample times."""

    @property
    def sim_pose(self) -> FloatArray:
        """``(m, 7)`` the simulated object pose."""

    @property
    def planned_q(self) -> FloatArray:
        """``(m, nq)`` the planned joints at the sample times."""

    @property
    def sim_q(self) -> FloatArray:
        """``(m, nq)`` the simulated joints."""

    @property
    def position_error(self) -> FloatArray:
        """``(m,)`` distance between the simulated and planned object positions (m)."""

    @property
    def angle_error(self) -> FloatArray:
        """``(m,)`` angle between the simulated and planned object orientations (rad)."""


def record_replay(
    doc: Mapping[str, Any], result: ReplayTrace, path: str | Path, *, base_dir: str | Path = "."
) -> Path:
    """Write a recording of a plan and its replay's result.

    The result is a :class:`~dexplan.execution.replay.simulation.ReplayResult`.

    Args:
        doc: the validated plan.
        result: what :func:`dexplan.execution.replay.simulation.replay_plan` returned.
        path: the ``.rrd`` file (written atomically).
        base_dir: the plan's folder (mesh paths).

    Returns:
        ``path``.
    """
    rr = rerun_module()
    base_dir = Path(base_dir)
    hand = hand_from_plan(doc["hand"])
    obj = shape_of(doc["object"], base_dir, "object")
    obstacles = obstacles_from_dicts(doc.get("obstacles", []), base_dir)
    idx = [rr.TimeColumn(TIME, duration=np.asarray(result.t, dtype=float))]
    # the planned joints at the sample times: the replay's trajectory samples
    planned_q = np.asarray(result.planned_q, dtype=float)
    sides = (
        ("plan", _PLAN, result.planned_pose, [hand.fingertip_positions(q) for q in planned_q]),
        ("replay", _REPLAY, result.sim_pose, [hand.fingertip_positions(q) for q in result.sim_q]),
    )
    with recording(path, f"replay of {doc.get('scenario', 'plan')}", replay_blueprint()) as rec:
        for side, color, _, _ in sides:
            root = f"world/{side}"
            rec.log(root, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
            rec.log(f"{root}/object/shape", shape_archetype(obj, color), static=True)
            for k, (_, shape, pose) in enumerate(obstacles):
                e = f"{root}/obstacles/obstacle{k}"
                rec.log(e, transform(pose), static=True)
                rec.log(f"{e}/shape", shape_archetype(shape, _OBSTACLE), static=True)
        for side, color, poses, tips in sides:
            P = np.asarray(poses, dtype=float)
            _send_side(rec, side, color, P, np.array(tips), idx, hand.fingertip_radius)
        rec.send_columns(
            "errors/position_mm",
            indexes=idx,
            columns=rr.Scalars.columns(scalars=1e3 * np.asarray(result.position_error)),
        )
        rec.send_columns(
            "errors/angle_rad",
            indexes=idx,
            columns=rr.Scalars.columns(scalars=np.asarray(result.angle_error)),
        )
    return Path(path)


def _send_side(
    rec: rerun.RecordingStream,
    side: str,
    color: tuple[int, ...],
    poses: FloatArray,
    tips: FloatArray,
    idx: list[rerun.TimeColumn],
    tip_radius: float,
) -> None:
    """One side's object poses ``(m, 7)`` and fingertip positions ``(m, n, 3)``, on ``time``."""
    rr = rerun_module()
    rec.send_columns(
        f"world/{side}/object",
        indexes=idx,
        columns=rr.Transform3D.columns(translation=poses[:, :3], quaternion=poses[:, 3:]),
    )
    for i in range(tips.shape[1]):
        rec.send_columns(
            f"world/{side}/fingertips/f{i}",
            indexes=idx,
            columns=rr.Points3D.columns(positions=tips[:, i, :]),
        )
        rec.log(
            f"world/{side}/fingertips/f{i}",
            rr.Points3D.from_fields(radii=[tip_radius], colors=[list(color)]),
            static=True,
        )
