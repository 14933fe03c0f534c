"""Rerun recording of a physics replay: the plan and the replay side by side (extra ``viz``).

Two 3D views on one ``time`` timeline (seconds from the trajectory's start):
``world/plan`` (the timed plan: object and fingertips) and ``world/replay``
(the MuJoCo replay), each with the obstacles, and a plot of the object's
position error (mm) and orientation error (rad) against the plan. Rerun is
imported here (and in :mod:`dexplan.viz`) only.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from dexplan.viz import _recording, _rerun, _shape_archetype

__all__ = ["record_replay"]

_PLAN = (90, 140, 230, 255)
_REPLAY = (230, 120, 60, 255)
_OBSTACLE = (150, 150, 150, 120)


def _blueprint() -> Any:
    rr = _rerun()
    rrb = rr.blueprint
    return rrb.Blueprint(
        rrb.Vertical(
            rrb.Horizontal(
                rrb.Spatial3DView(origin="world/plan", name="plan"),
                rrb.Spatial3DView(origin="world/replay", name="replay (MuJoCo)"),
            ),
            rrb.TimeSeriesView(origin="errors", name="object error vs plan"),
            row_shares=[3, 1],
        ),
        collapse_panels=True,
    )


def record_replay(
    doc: Mapping[str, Any], result: Any, path: str | Path, *, base_dir: str | Path = "."
) -> Path:
    """Write a recording of a plan and its :class:`~dexplan.replay.ReplayResult`.

    Args:
        doc: the validated plan.
        result: what :func:`dexplan.replay.replay_plan` returned.
        path: the ``.rrd`` file (written atomically).
        base_dir: the plan's folder (mesh paths).

    Returns:
        ``path``.
    """
    rr = _rerun()
    from dexplan.objects import shape_from_dict
    from dexplan.plan_file import hand_from_plan

    base_dir = Path(base_dir)
    hand = hand_from_plan(doc["hand"])
    obj = shape_from_dict({k: v for k, v in doc["object"].items() if k != "mass"}, base_dir)
    t = np.asarray(result.t, dtype=float)
    # the planned joints at the sample times: the replay's trajectory samples
    plan_tips = np.array([hand.fingertip_positions(q) for q in _planned_q(doc, result, hand)])
    sim_tips = np.array([hand.fingertip_positions(q) for q in result.sim_q])
    with _recording(path, f"replay of {doc.get('scenario', 'plan')}", _blueprint()) as rec:
        for side, color in (("plan", _PLAN), ("replay", _REPLAY)):
            root = f"world/{side}"
            rec.log(root, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
            rec.log(f"{root}/object/shape", _shape_archetype(obj, color), static=True)
            for k, ob in enumerate(doc.get("obstacles", [])):
                sh = shape_from_dict(
                    {kk: v for kk, v in ob.items() if kk not in ("pose_xyzquat", "name")},
                    base_dir,
                )
                p = np.asarray(ob["pose_xyzquat"], dtype=float)
                e = f"{root}/obstacles/obstacle{k}"
                rec.log(e, rr.Transform3D(translation=p[:3], quaternion=p[3:]), static=True)
                rec.log(f"{e}/shape", _shape_archetype(sh, _OBSTACLE), static=True)
        idx = [rr.TimeColumn("time", duration=t)]
        for side, poses, tips in (
            ("plan", result.planned_pose, plan_tips),
            ("replay", result.sim_pose, sim_tips),
        ):
            P = np.asarray(poses, dtype=float)
            rec.send_columns(
                f"world/{side}/object",
                indexes=idx,
                columns=rr.Transform3D.columns(translation=P[:, :3], quaternion=P[:, 3:]),
            )
            color = _PLAN if side == "plan" else _REPLAY
            for i in range(tips.shape[1]):
                rec.send_columns(
                    f"world/{side}/fingertips/f{i}",
                    indexes=idx,
                    columns=rr.Points3D.columns(positions=tips[:, i, :]),
                )
                rec.log(
                    f"world/{side}/fingertips/f{i}",
                    rr.Points3D.from_fields(radii=[hand.fingertip_radius], colors=[list(color)]),
                    static=True,
                )
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


def _planned_q(doc: Mapping[str, Any], result: Any, hand: Any) -> np.ndarray:
    """(m, nq) the planned joints at the replay's sample times."""
    return np.asarray(result.planned_q, dtype=float)
