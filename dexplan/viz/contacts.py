"""Contacts of a plan: contact points, friction cones and the force-closure series.

Per ``plan_step``: each holding finger's contact point and its linearized
friction cone (with the torsion ring for soft contacts), and the force-closure
quality of the holding grasp and the minimum over its subgrasps
(:mod:`dexplan.model.grasp`), all sent as columns.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from dexplan.core.errors import DexplanError
from dexplan.core.pose import inverse_transform_points, transform_points
from dexplan.core.segments import Segment
from dexplan.core.typing import FloatArray
from dexplan.model.grasp import force_closure_quality, min_subgrasp_quality
from dexplan.planfile import fingertip_contact
from dexplan.viz.scene import Scene
from dexplan.viz.session import finger_color, plan_index, rerun_module, rgba, set_step

if TYPE_CHECKING:  # rerun's types for annotations; at run time rerun loads on first use
    import rerun

QualityFunctions = tuple[Callable[..., float], Callable[..., float]]
"""``(quality of a grasp, minimum over its subgrasps)``, called as
``f(points (k, 3), inward normals (k, 3), mu, *, edges, torque_scale, contact_model, torsion)``."""


# --------------------------------------------------------------- geometry
def friction_cone(
    apex: FloatArray, axis: FloatArray, mu: float, edges: int, height: float
) -> list[FloatArray]:
    """Line strips of a linearized friction cone: ``edges`` generators and the rim.

    The cone opens from ``apex`` along the unit ``axis`` with half-angle
    ``atan(mu)``; generators end at axial distance ``height``.

    Args:
        apex: ``(3,)`` the contact point.
        axis: ``(3,)`` the cone's axis (any length), in the frame of ``apex``.
        mu: friction coefficient.
        edges: number of generators.
        height: axial length of the generators (m).

    Returns:
        ``edges`` strips ``(2, 3)`` (apex to rim), then the rim ``(edges + 1, 3)``,
        in the frame of ``apex``.
    """
    a = axis / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t1 = np.cross(a, helper)
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(a, t1)
    th = 2 * np.pi * np.arange(edges) / edges
    ends = apex + height * (a + mu * (np.cos(th)[:, None] * t1 + np.sin(th)[:, None] * t2))
    strips = [np.stack([apex, e]) for e in ends]
    strips.append(np.vstack([ends, ends[:1]]))
    return strips


def _contact_strips(
    apex: FloatArray, axis: FloatArray, scene: Scene, height: float
) -> list[FloatArray]:
    """The friction cone's strips, and for soft contacts the torsion ring.

    The ring is a circle of radius ``torsion`` about the contact in its tangent
    plane: the lever arm of the largest torsional moment per unit normal force
    (``|tau_n| <= torsion f_n``), drawn at scale. ``apex: (3,)`` and
    ``axis: (3,)`` are in the object frame, and so are the strips.
    """
    strips = friction_cone(apex, axis, scene.mu, scene.friction_edges, height)
    if scene.contact_model == "soft":
        a = axis / np.linalg.norm(axis)
        rim = friction_cone(np.zeros(3), a, 1.0, 24, 1.0)[-1]  # a + unit circle
        strips.append(apex + scene.torsion * (rim - a))
    return strips


# ---------------------------------------------------------- force closure
def fc_functions() -> QualityFunctions:
    """``(force_closure_quality, min_subgrasp_quality)`` of :mod:`dexplan.model.grasp`."""
    return force_closure_quality, min_subgrasp_quality


def _fc_values(
    fc: QualityFunctions,
    pts: list[FloatArray],
    nrm: list[FloatArray],
    scene: Scene,
    ts: float,
    n: int,
) -> tuple[float | None, float | None]:
    """(quality of the holding grasp, min over its subgrasps when all n fingers hold)."""
    quality, min_sub = fc
    if len(pts) < 2:
        return None, None
    P, N = np.array(pts), np.array(nrm)
    kw = {
        "edges": scene.friction_edges,
        "torque_scale": ts,
        "contact_model": scene.contact_model,
        "torsion": scene.torsion,
    }
    try:
        full = float(quality(P, N, scene.mu, **kw))
        sub = float(min_sub(P, N, scene.mu, **kw)) if len(pts) == n else None
    except DexplanError:
        return None, None
    return full, sub


# ----------------------------------------------------------------- series
@dataclass
class _ContactSeries:
    """Per finger and step, the world-frame contact points and cone strips; FC per step."""

    n: int
    points: list[list[FloatArray]] = field(init=False)  # per finger, per step (k, 3)
    strips: list[list[FloatArray]] = field(init=False)  # per finger, cone strips
    n_strips: list[list[int]] = field(init=False)  # per finger, strips per step
    full_q: list[float | None] = field(default_factory=list)
    sub_q: list[float | None] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.points = [[] for _ in range(self.n)]
        self.strips = [[] for _ in range(self.n)]
        self.n_strips = [[] for _ in range(self.n)]


def _contact_series(
    scene: Scene, segments: Sequence[Segment], fc: QualityFunctions
) -> _ContactSeries:
    """Contact points, cone strips and FC values at every waypoint of the plan."""
    hand, obj = scene.hand, scene.obj
    assert hand is not None and obj is not None
    n = hand.n_fingers
    ts = obj.characteristic_length
    cone_h = min(0.025, 0.5 * ts)
    n_edges = scene.friction_edges
    # generators (2 points each), then the rim, then the soft torsion ring
    strip_sizes = [2] * n_edges + ([n_edges + 1] if scene.contact_model == "soft" else [])
    # per stated contact (object frame): surface point, outward normal, [c; cone points]
    local: dict[tuple[bytes, bytes], FloatArray] = {}  # (contact, normal) -> cone points
    fc_cache: dict[bytes, tuple[float | None, float | None]] = {}
    out = _ContactSeries(n)
    r = hand.fingertip_radius
    for w in (w for seg in segments for w in seg.waypoints):
        pose = w.object_pose_xyzquat
        tips = inverse_transform_points(pose, hand.fingertip_positions(w.q))
        pts_obj, nrm_in = [], []
        for i, c in enumerate(w.contacts):
            if c is None:
                out.points[i].append(np.zeros((0, 3)))
                out.n_strips[i].append(0)
                continue
            c = np.asarray(c, dtype=float)
            # the verifier's rule (a fingertip on a box edge pushes along
            # the normal at its own closest point)
            p_s, n_s, _ = fingertip_contact(obj, c, tips[i], r)
            key = (c.tobytes(), n_s.tobytes())
            if key not in local:  # along a transfer the same cone repeats
                local[key] = np.vstack([c[None], *_contact_strips(c, n_s, scene, cone_h)])
            pts_obj.append(p_s)
            nrm_in.append(-n_s)
            pts_w = transform_points(pose, local[key])
            out.points[i].append(pts_w[:1])
            out.strips[i].extend(np.split(pts_w[1:], np.cumsum(strip_sizes)))
            out.n_strips[i].append(len(strip_sizes) + 1)
        key_fc = b"".join(p.tobytes() for p in pts_obj) + bytes(w.contact_mask())
        if key_fc not in fc_cache:
            fc_cache[key_fc] = _fc_values(fc, pts_obj, nrm_in, scene, ts, n)
        full, sub = fc_cache[key_fc]
        out.full_q.append(full)
        out.sub_q.append(sub)
    return out


# ---------------------------------------------------------------- logging
def _log_styles(rec: rerun.RecordingStream, n: int) -> None:
    """Static colours and sizes of the contact points, cones and FC lines."""
    rr = rerun_module()
    for i in range(n):
        col = [rgba(finger_color(i))]
        path = f"world/contacts/finger_{i}"
        rec.log(
            path,
            rr.Points3D.from_fields(colors=col, radii=[0.002], labels=[f"f{i}"]),
            static=True,
        )
        rec.log(
            path + "/cone", rr.LineStrips3D.from_fields(colors=col, radii=[0.0004]), static=True
        )
    rec.log(
        "plan/fc/full",
        rr.SeriesLines(colors=[[40, 120, 220, 255]], names=["holding grasp"], widths=[2.0]),
        static=True,
    )
    rec.log(
        "plan/fc/min_subgrasp",
        rr.SeriesLines(colors=[[230, 90, 40, 255]], names=["min over subgrasps"], widths=[2.0]),
        static=True,
    )


def _send_contacts(
    rec: rerun.RecordingStream, series: _ContactSeries, indexes: list[rerun.TimeColumn]
) -> None:
    """Each finger's contact point and cone strips, one (maybe empty) batch per step."""
    rr = rerun_module()
    for i in range(series.n):
        path = f"world/contacts/finger_{i}"
        lengths = [len(p) for p in series.points[i]]
        pos = np.concatenate(series.points[i]) if series.points[i] else np.zeros((0, 3))
        rec.send_columns(
            path, indexes=indexes, columns=rr.Points3D.columns(positions=pos).partition(lengths)
        )
        rec.send_columns(
            path + "/cone",
            indexes=indexes,
            columns=rr.LineStrips3D.columns(strips=series.strips[i]).partition(series.n_strips[i]),
        )


def _send_fc(rec: rerun.RecordingStream, series: _ContactSeries) -> None:
    """The two FC series where defined, cleared (a gap in the line) where not."""
    rr = rerun_module()
    for path, values in (("plan/fc/full", series.full_q), ("plan/fc/min_subgrasp", series.sub_q)):
        have = np.array([v is not None for v in values], dtype=bool)
        if have.any():
            sub_idx = plan_index(np.flatnonzero(have))
            vals = np.array([v for v in values if v is not None], dtype=float)
            rec.send_columns(path, indexes=sub_idx, columns=rr.Scalars.columns(scalars=vals))
        for step in np.flatnonzero(~have):  # break the line where it is undefined
            set_step(rec, int(step))
            rec.log(path, rr.Clear(recursive=False))
    rec.reset_time()


def log_contacts_and_fc(
    rec: rerun.RecordingStream,
    scene: Scene,
    segments: Sequence[Segment],
    indexes: list[rerun.TimeColumn],
) -> None:
    """Log contact points, friction cones and force-closure quality per step (as columns).

    A free finger's contact point and cone are empty batches at its steps, so
    they disappear; the FC series are cleared where they are undefined (fewer
    than two holding fingers; for ``min_subgrasp``, while a finger is free).

    Args:
        rec: the recording stream.
        scene: the plan's models (hand and object required).
        segments: the plan's segments.
        indexes: the ``plan_step`` and ``time`` columns, one row per waypoint.
    """
    assert scene.hand is not None
    _log_styles(rec, scene.hand.n_fingers)
    series = _contact_series(scene, segments, fc_functions())
    _send_contacts(rec, series, indexes)
    _send_fc(rec, series)
