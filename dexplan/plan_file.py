"""Plan files (format ``dexplan-plan/1``): write, read and verify.

A plan file is one self-contained JSON document: the hand (URDF text, joint
names, fingertip frames and radius), the object, friction, obstacles, start,
goal, the transfer/regrasp segments and statistics. It is written atomically
(temporary file in the same folder, then rename), so a reader never sees half a
plan.

:func:`verify_plan` re-checks a plan from the file alone. It rebuilds the
models (Pinocchio hand, object, coal world, force closure) but shares no code
path with the planner: every rule of DESIGN.md is checked again and each
violation names the segment, the waypoint and the rule.

Every document is first checked for structure by
:func:`dexplan.plan_schema.validate_plan` (:func:`read_plan` and
:func:`verify_plan` both call it): a malformed plan is a
:class:`~dexplan.exceptions.PlanFileError` naming the field, never a violation,
a crash or a silent pass.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from dexplan import plan_schema
from dexplan.exceptions import DexplanError, InvalidInputError, PlanFileError, shorten
from dexplan.files import atomic_output, file_sha256
from dexplan.plan_schema import FORMAT, validate_plan
from dexplan.segments import Segment, Waypoint
from dexplan.typing import FloatArray

if TYPE_CHECKING:  # models only: the plan file never imports planning
    from dexplan.collision import CollisionWorld, Obstacle
    from dexplan.hand import Hand
    from dexplan.objects import Shape
    from dexplan.scenario import Scenario

__all__ = [
    "FORMAT",
    "VerifyReport",
    "Violation",
    "build_plan_document",
    "hand_from_plan",
    "read_plan",
    "segments_from_dicts",
    "validate_plan",
    "verify_plan",
    "write_plan",
]

#: Verification tolerances (DESIGN.md).
TIP_DISTANCE_TOL = 1e-3  # |fingertip distance to surface - r| (m)
PENETRATION_TOL = 1e-3  # (m)
MAX_STEP_M = 0.01  # object translation between waypoints (m)
MAX_STEP_RAD = 0.05  # object rotation and joint change between waypoints (rad)
CONTACT_DRIFT_TOL = 1e-3  # transfer contact drift (m)
STILL_TOL = 1e-9  # "does not move" (m, rad)
FC_MIN = 0.0  # force-closure quality must exceed this
#: Verdicts of :func:`dexplan.grasp.exact_force_closure` that pass.
FC_PASS = ("fc_linear", "fc_dense")
GOAL_POSITION_TOL = 0.005  # goal.position_tol when the file has none (m)
GOAL_ANGLE_TOL = 0.05  # goal.angle_tol when the file has none (rad)


# ------------------------------------------------------------------ writing
def waypoint_to_dict(w: Waypoint) -> dict[str, Any]:
    """JSON form of a waypoint."""
    return {
        "object_pose_xyzquat": [float(v) for v in w.object_pose_xyzquat],
        "q": [float(v) for v in w.q],
        "contacts": [None if c is None else [float(v) for v in c] for c in w.contacts],
    }


def segment_to_dict(s: Segment) -> dict[str, Any]:
    """JSON form of a segment."""
    return {
        "kind": s.kind,
        "finger": s.finger,
        "waypoints": [waypoint_to_dict(w) for w in s.waypoints],
    }


def segments_from_dicts(items: Sequence[Mapping[str, Any]]) -> tuple[Segment, ...]:
    """Segments from their JSON form (of a document :func:`validate_plan` accepted)."""
    out = []
    for s in items:
        wps = tuple(
            Waypoint(
                np.asarray(w["object_pose_xyzquat"], dtype=float),
                np.asarray(w["q"], dtype=float),
                tuple(None if c is None else np.asarray(c, dtype=float) for c in w["contacts"]),
            )
            for w in s["waypoints"]
        )
        out.append(Segment(s["kind"], s["finger"], wps))
    return tuple(out)


def write_plan(path: str | Path, doc: Mapping[str, Any]) -> None:
    """Write a plan document as JSON, atomically.

    Raises:
        PlanFileError: the folder does not exist or is not writable.
    """
    text = json.dumps(doc, indent=1, allow_nan=False)
    try:
        with atomic_output(path, "plan") as tmp, open(tmp, "w") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
    except InvalidInputError as exc:
        raise PlanFileError(str(exc)) from exc
    except OSError as exc:
        raise PlanFileError(f"cannot write plan to {str(path)!r}: {exc}") from exc


def read_plan(path: str | Path, base_dir: str | Path | None = None) -> dict[str, Any]:
    """Read a plan file and check its structure (:func:`validate_plan`).

    Args:
        path: the plan file.
        base_dir: folder relative mesh paths resolve against (default: the
            plan file's folder).

    Raises:
        PlanFileError: missing or oversized file
            (:data:`~dexplan.plan_schema.MAX_PLAN_BYTES`),
            invalid or too deeply nested JSON, or a malformed plan (the message
            names the field).
    """
    path = Path(path)
    if not path.is_file():
        raise PlanFileError(f"plan file not found: {str(path)!r}")
    size = path.stat().st_size
    if size > plan_schema.MAX_PLAN_BYTES:
        limit = plan_schema.MAX_PLAN_BYTES
        raise PlanFileError(f"{path}: {size} bytes, more than a plan may have ({limit})")
    try:
        doc = json.loads(path.read_bytes())
    except RecursionError as exc:
        raise PlanFileError(f"{path}: not valid JSON: nested too deeply") from exc
    except (ValueError, UnicodeDecodeError) as exc:  # JSONDecodeError, a 5000-digit int
        raise PlanFileError(f"{path}: not valid JSON: {_clip(str(exc))}") from exc
    try:
        validate_plan(doc, path.resolve().parent if base_dir is None else base_dir)
    except PlanFileError as exc:
        raise PlanFileError(f"{path}: {exc}") from exc
    return doc


def _clip(text: str, limit: int = 200) -> str:
    """``text`` cut to ``limit`` characters (a foreign message in a one-line error)."""
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def hand_from_plan(h: Mapping[str, Any], package_dirs: Sequence[str | Path] = ()) -> Hand:
    """The :class:`~dexplan.hand.Hand` of a validated plan's ``hand`` table.

    Args:
        h: the ``hand`` table.
        package_dirs: folders ``package://`` mesh URIs resolve against.

    Raises:
        PlanFileError: the URDF text does not build a hand with these
            fingertip frames, or its joints are not ``hand.joint_names``.
    """
    from dexplan.hand import Hand

    try:
        hand = Hand(
            h["urdf_xml"],
            h["fingertip_frames"],
            h["fingertip_radius"],
            collision_exclude=[tuple(p) for p in h.get("collision_exclude", [])],
            name="plan hand",
            package_dirs=package_dirs,
        )
    except DexplanError as exc:
        raise PlanFileError(f"hand: {_clip(str(exc))}") from exc
    if list(hand.joint_names) != list(h["joint_names"]):
        raise PlanFileError(
            f"hand.joint_names must be the URDF's joints {shorten(list(hand.joint_names))}, "
            f"got {shorten(list(h['joint_names']))}"
        )
    return hand


# ---------------------------------------------------------------- models
#: Fields of an object or obstacle table that are not shape (mass, placement, label).
NOT_SHAPE_FIELDS = ("mass", "pose_xyzquat", "name")


@dataclass(frozen=True)
class PlanModels:
    """The models a plan file describes, rebuilt from the file alone.

    Attributes:
        hand: the hand (its URDF text, fingertips, exclusions).
        obj: the object shape.
        obstacles: static obstacles, world frame.
        world: the collision world of hand, object and obstacles.
        mu: friction coefficient. friction_edges: edges of the linearized cone.
        contact_model: ``point`` or ``soft``. torsion: soft-finger torsion (m).
    """

    hand: Hand
    obj: Shape
    obstacles: tuple[Obstacle, ...]
    world: CollisionWorld
    mu: float
    friction_edges: int
    contact_model: str
    torsion: float


def shape_of(table: Mapping[str, Any], base_dir: Path, field: str) -> Shape:
    """The shape of an object or obstacle table (its non-shape fields set aside)."""
    from dexplan.objects import shape_from_dict

    shape = {k: v for k, v in table.items() if k not in NOT_SHAPE_FIELDS}
    return shape_from_dict(shape, base_dir, field=field)


def models_from_document(
    doc: Mapping[str, Any],
    base_dir: str | Path = ".",
    *,
    hand: Hand | None = None,
    package_dirs: Sequence[str | Path] = (),
) -> PlanModels:
    """Hand, object, obstacles and collision world of a validated plan document.

    The one way to rebuild a plan's models: the verifier, the viewer, the
    trajectory export and the replay all use it.

    Args:
        doc: a ``dexplan-plan/1`` document (see :func:`read_plan`).
        base_dir: folder relative mesh paths resolve against.
        hand: the hand if already rebuilt (:func:`hand_from_plan`).
        package_dirs: folders ``package://`` mesh URIs of the URDF resolve against.

    Raises:
        PlanFileError: the hand does not build from the file.
    """
    from dexplan.collision import CollisionWorld, Obstacle

    base = Path(base_dir)
    hand = hand if hand is not None else hand_from_plan(doc["hand"], package_dirs)
    obj = shape_of(doc["object"], base, "object")
    obstacles = tuple(
        Obstacle(
            shape_of(ob, base, f"obstacles[{k}]"),
            tuple(float(v) for v in ob["pose_xyzquat"]),
            str(ob.get("name", f"obstacle{k}")),
        )
        for k, ob in enumerate(doc.get("obstacles", []))
    )
    return PlanModels(
        hand=hand,
        obj=obj,
        obstacles=obstacles,
        world=CollisionWorld(hand, obj, list(obstacles)),
        mu=float(doc["mu"]),
        friction_edges=int(doc.get("friction_edges", 8)),
        contact_model=str(doc.get("contact_model", "point")),
        torsion=float(doc.get("torsion", 0.0)),
    )


# ---------------------------------------------------------------- contacts
def fingertip_contact(
    obj: Shape, c_obj: FloatArray, tip_obj: FloatArray, radius: float
) -> tuple[FloatArray, FloatArray, float]:
    """Where and along which normal a fingertip pushes on the object (the one rule).

    The fingertip sphere touches the surface at the closest point to its
    centre, pushing along the normal there. On a face that is the stated
    contact's own normal (exact per contact, so equal contacts give equal
    answers); at a box edge or corner, the direction from the edge to the
    fingertip centre. The verifier and the viewer both read contacts this way.

    Args:
        obj: the object shape.
        c_obj: (3,) the stated contact, object frame.
        tip_obj: (3,) the fingertip centre, object frame.
        radius: fingertip radius (m).

    Returns:
        ``(p, n_out, gap)``: (3,) the surface point of the contact and (3,) the
        outward unit normal the fingertip pushes along, both object frame, and
        the distance (m) between the stated contact and the fingertip's own.
    """
    p_s, n_s = (np.asarray(v, dtype=float).reshape(3) for v in obj.closest_point(c_obj))
    gap = float(np.linalg.norm(p_s + radius * n_s - tip_obj))
    if gap > TIP_DISTANCE_TOL:
        p_t, n_s = (np.asarray(v, dtype=float).reshape(3) for v in obj.closest_point(tip_obj))
        gap = float(np.linalg.norm(p_t - c_obj))
    return p_s, n_s, gap


# ---------------------------------------------------------------- verifying
@dataclass(frozen=True)
class Violation:
    """One broken rule: where (segment, waypoint; -1 for the whole plan) and what."""

    segment: int
    waypoint: int
    rule: str
    message: str

    def __str__(self) -> str:
        where = "plan" if self.segment < 0 else f"segment {self.segment}"
        if self.waypoint >= 0:
            where += f", waypoint {self.waypoint}"
        return f"{where}: {self.rule}: {self.message}"


@dataclass(frozen=True)
class VerifyReport:
    """Result of :func:`verify_plan`."""

    violations: tuple[Violation, ...]
    waypoints: int
    segments: int

    @property
    def ok(self) -> bool:
        """True when no rule is broken."""
        return not self.violations


class _Checker:
    """Rebuilds the models from a plan document and checks every rule."""

    def __init__(self, doc: Mapping[str, Any], base_dir: Path) -> None:
        m = models_from_document(doc, base_dir)
        self.hand, self.obj, self.world = m.hand, m.obj, m.world
        self.mu, self.edges = m.mu, m.friction_edges
        self.contact_model, self.torsion = m.contact_model, m.torsion
        self.n = self.hand.n_fingers
        self.violations: list[Violation] = []
        self._fc_memo: dict[tuple[bytes, bytes, bool], tuple[str, str]] = {}

    def add(self, seg: int, wp: int, rule: str, message: str) -> None:
        self.violations.append(Violation(seg, wp, rule, message))

    # -- per waypoint ------------------------------------------------------
    def waypoint(self, si: int, wi: int, w: Waypoint, *, subgrasps: bool) -> None:
        from dexplan.pose import inverse_transform_points

        hand, obj = self.hand, self.obj
        pose, q = w.object_pose_xyzquat, w.q  # sizes and finiteness: validate_plan
        if abs(float(np.linalg.norm(pose[3:])) - 1.0) > 1e-6:
            self.add(si, wi, "object_pose", "quaternion is not unit length")
            return
        if not hand.within_limits(q, 1e-9):
            bad = [
                hand.joint_names[j]
                for j in np.flatnonzero((q < hand.lower - 1e-9) | (q > hand.upper + 1e-9))
            ]
            self.add(si, wi, "joint_limits", f"joints outside limits: {bad}")
        tips = inverse_transform_points(pose, hand.fingertip_positions(q))
        mask = w.contact_mask()
        r = hand.fingertip_radius
        pts, nrm = [], []
        for i, c in enumerate(w.contacts):
            if c is None:
                continue
            d_tip = float(obj.signed_distance(tips[i])) - r
            if abs(d_tip) > TIP_DISTANCE_TOL:
                self.add(
                    si,
                    wi,
                    "fingertip_distance",
                    f"finger {i}: fingertip is {d_tip * 1e3:+.2f} mm from the surface",
                )
            d_c = float(obj.signed_distance(c))
            if abs(d_c) > TIP_DISTANCE_TOL:
                self.add(
                    si,
                    wi,
                    "contact_on_surface",
                    f"finger {i}: contact is {d_c * 1e3:+.2f} mm off the surface",
                )
            p_s, n_s, gap = fingertip_contact(obj, c, tips[i], r)
            if gap > TIP_DISTANCE_TOL:
                self.add(
                    si,
                    wi,
                    "contact_matches_fingertip",
                    f"finger {i}: stated contact is {gap * 1e3:.2f} mm from the fingertip's",
                )
            pts.append(np.asarray(p_s).reshape(3))
            nrm.append(-np.asarray(n_s).reshape(3))
        rep = self.world.check(q, pose, mask, first_only=True)
        if rep.pair is not None:
            self.add(si, wi, "collision", f"{rep.pair[0]} touches {rep.pair[1]}")
        if rep.max_penetration > PENETRATION_TOL:
            self.add(
                si,
                wi,
                "penetration",
                f"a fingertip sinks {rep.max_penetration * 1e3:.2f} mm into the object",
            )
        if len(pts) < 2:
            self.add(si, wi, "force_closure", f"only {len(pts)} finger(s) hold the object")
            return
        P, N = np.array(pts), np.array(nrm)
        ts = obj.characteristic_length
        # The rules are signs, judged under the plan's contact model against the
        # exact sets (round Coulomb cone, elliptic soft-finger set): the file's
        # own linearization, then dense inner and outer polytopes. The same
        # contacts give the same answer, and along a transfer or a regrasp the
        # holding contacts repeat: remember answers by exact contact values.
        key = (P.tobytes(), N.tobytes(), subgrasps)
        if key not in self._fc_memo:
            fc = self._fc_verdict(P, N, ts, subgrasps=False)
            sub = self._fc_verdict(P, N, ts, subgrasps=True) if subgrasps else "fc_linear"
            self._fc_memo[key] = (fc, sub)
        fc, sub = self._fc_memo[key]
        if fc not in FC_PASS:
            self.add(si, wi, "force_closure", f"holding grasp is {self._fc_text(fc)}")
        elif subgrasps and sub not in FC_PASS:
            self.add(
                si,
                wi,
                "subgrasp_force_closure",
                f"some {len(pts) - 1}-finger subgrasp is {self._fc_text(sub)}",
            )

    def _fc_verdict(self, P: np.ndarray, N: np.ndarray, ts: float, *, subgrasps: bool) -> str:
        from dexplan.grasp import exact_force_closure

        return exact_force_closure(
            P,
            N,
            self.mu,
            edges=self.edges,
            torque_scale=ts,
            subgrasps=subgrasps,
            contact_model=self.contact_model,  # type: ignore[arg-type]
            torsion=self.torsion,
        )

    def _fc_text(self, verdict: str) -> str:
        if self.contact_model == "soft":
            where = f"soft contacts, mu {self.mu:g}, torsion {self.torsion:g} m"
        else:
            where = f"point contacts, mu {self.mu:g}"
        if verdict == "undecided":
            return (
                f"not provably force closure ({where}): within the gap between the "
                "dense inner and outer polytopes of the exact contact sets"
            )
        return f"not force closure ({where})"

    # -- per segment -------------------------------------------------------
    def steps(self, si: int, seg: Segment) -> None:
        from dexplan.pose import quat_angle

        for wi in range(1, len(seg.waypoints)):
            a, b = seg.waypoints[wi - 1], seg.waypoints[wi]
            dp = float(np.linalg.norm(b.object_pose_xyzquat[:3] - a.object_pose_xyzquat[:3]))
            da = quat_angle(a.object_pose_xyzquat[3:], b.object_pose_xyzquat[3:])
            dq = float(np.max(np.abs(b.q - a.q))) if a.q.size else 0.0
            if dp > MAX_STEP_M + 1e-12:
                self.add(
                    si, wi, "step", f"object moves {dp * 1e3:.2f} mm from the previous waypoint"
                )
            if da > MAX_STEP_RAD + 1e-12:
                self.add(si, wi, "step", f"object turns {da:.4f} rad from the previous waypoint")
            if dq > MAX_STEP_RAD + 1e-12:
                self.add(si, wi, "step", f"a joint moves {dq:.4f} rad from the previous waypoint")

    def transfer(self, si: int, seg: Segment) -> None:
        first = seg.waypoints[0]
        for wi, w in enumerate(seg.waypoints):
            if w.contact_mask() != first.contact_mask():
                self.add(si, wi, "transfer_contacts", "the set of contact fingers changes")
                continue
            for i, (c, c0) in enumerate(zip(w.contacts, first.contacts, strict=True)):
                if c is None:
                    continue
                drift = float(np.linalg.norm(np.asarray(c) - np.asarray(c0)))
                if drift > CONTACT_DRIFT_TOL:
                    self.add(
                        si,
                        wi,
                        "transfer_contact_drift",
                        f"finger {i}: contact drifts {drift * 1e3:.2f} mm in the object frame",
                    )

    def regrasp(self, si: int, seg: Segment) -> None:
        f = int(seg.finger)  # in [0, n): validate_plan
        wps = seg.waypoints
        if len(wps) < 3:
            self.add(si, -1, "regrasp_interior", "a regrasp needs at least one interior waypoint")
        first = wps[0]
        others = np.ones(self.hand.nq, dtype=bool)
        others[self.hand.finger_q_index[f]] = False
        for wi, w in enumerate(wps):
            dpose = float(np.max(np.abs(w.object_pose_xyzquat - first.object_pose_xyzquat)))
            if dpose > STILL_TOL:
                self.add(si, wi, "regrasp_object_still", f"the object moves ({dpose:.3g})")
            moved = np.flatnonzero(np.abs(w.q - first.q)[others] > STILL_TOL)
            if len(moved):
                names = [self.hand.joint_names[j] for j in np.flatnonzero(others)[moved]]
                self.add(si, wi, "regrasp_one_finger", f"joints of other fingers move: {names}")
            for i in range(self.n):
                if i == f:
                    continue
                c, c0 = w.contacts[i], first.contacts[i]
                if (c is None) != (c0 is None) or (
                    c is not None and np.linalg.norm(np.asarray(c) - np.asarray(c0)) > STILL_TOL
                ):
                    self.add(si, wi, "regrasp_one_finger", f"finger {i}'s contact changes")
            interior = 0 < wi < len(wps) - 1
            if interior:
                if w.contacts[f] is not None:
                    self.add(
                        si,
                        wi,
                        "regrasp_free_finger",
                        f"finger {f} must be free (contact null) at interior waypoints",
                    )
                else:
                    d = self.world.finger_object_distance(w.q, w.object_pose_xyzquat, f)
                    if d <= 0.0:
                        self.add(
                            si,
                            wi,
                            "regrasp_clearance",
                            f"free finger {f} touches the object ({d * 1e3:.3f} mm)",
                        )
        for wi in (0, len(wps) - 1):
            if wps[wi].contacts[f] is None:
                self.add(si, wi, "regrasp_endpoints", f"finger {f} must be in contact here")


def verify_plan(doc: Mapping[str, Any], base_dir: str | Path = ".") -> VerifyReport:
    """Check every rule of a ``dexplan-plan/1`` document.

    Args:
        doc: the parsed plan (see :func:`read_plan`).
        base_dir: folder that relative mesh paths resolve against.

    Returns:
        A :class:`VerifyReport` listing every violation.

    Raises:
        PlanFileError: the document is malformed (:func:`validate_plan`: the
            message names the field) or its models cannot be rebuilt (the URDF
            text, a mesh file).
    """
    from dexplan.pose import quat_angle

    validate_plan(doc, base_dir)
    try:
        chk = _Checker(doc, Path(base_dir))
    except PlanFileError:
        raise
    except DexplanError as exc:  # a mesh file that changed since validation, coal
        raise PlanFileError(f"cannot rebuild the plan's models: {_clip(str(exc))}") from exc
    segments = segments_from_dicts(doc["segments"])

    if not segments:
        chk.add(-1, -1, "segments", "the plan has no segments")
    total = 0
    for si, seg in enumerate(segments):
        for wi, w in enumerate(seg.waypoints):
            chk.waypoint(si, wi, w, subgrasps=seg.kind == "transfer")
        total += len(seg.waypoints)
        chk.steps(si, seg)
        if seg.kind == "transfer":
            chk.transfer(si, seg)
        else:
            chk.regrasp(si, seg)
        if si > 0:
            a, b = segments[si - 1].waypoints[-1], seg.waypoints[0]
            same = np.allclose(a.q, b.q, atol=STILL_TOL) and np.allclose(
                a.object_pose_xyzquat, b.object_pose_xyzquat, atol=STILL_TOL
            )
            if not same:
                chk.add(si, 0, "continuity", "does not start where the previous segment ends")

    # start and goal (finite, tolerances > 0: validate_plan)
    if segments:
        w0 = segments[0].waypoints[0]
        start = doc["start"]
        sp = np.asarray(start["object_pose_xyzquat"], dtype=float)
        if not np.allclose(sp, w0.object_pose_xyzquat, atol=1e-9):
            chk.add(0, 0, "start", "first waypoint is not the start object pose")
        if start.get("q") is not None:
            sq = np.asarray(start["q"], dtype=float)
            if not np.allclose(sq, w0.q, atol=1e-9):
                chk.add(0, 0, "start", "first waypoint is not the start configuration")
        wl = segments[-1].waypoints[-1]
        goal = doc["goal"]
        gp = np.asarray(goal["object_pose_xyzquat"], dtype=float)
        dp = float(np.linalg.norm(wl.object_pose_xyzquat[:3] - gp[:3]))
        da = quat_angle(wl.object_pose_xyzquat[3:], gp[3:])
        last = (len(segments) - 1, len(segments[-1].waypoints) - 1)
        if not dp <= float(goal.get("position_tol", GOAL_POSITION_TOL)) + 1e-12:
            chk.add(*last, "goal", f"object ends {dp * 1e3:.2f} mm from the goal position")
        if not da <= float(goal.get("angle_tol", GOAL_ANGLE_TOL)) + 1e-12:
            msg = f"object ends {math.degrees(da):.2f} deg from the goal orientation"
            chk.add(*last, "goal", msg)
    return VerifyReport(tuple(chk.violations), total, len(segments))


def _portable_shape(shape: Mapping[str, Any], base_dir: Path, out_dir: Path) -> dict[str, Any]:
    """Shape dict with a mesh path relative to the plan's folder and its sha256."""
    d = dict(shape)
    if d.get("shape") == "mesh":
        src = (base_dir / str(d["path"])).resolve()
        try:
            d["path"] = os.path.relpath(src, out_dir.resolve())
        except ValueError:  # another drive
            d["path"] = str(src)
        d["sha256"] = file_sha256(src)
    return d


class PlannedPath(Protocol):
    """What a plan document is built from (a planner result has these).

    The plan file sits below planning and does not import it: any object with
    these attributes will do (:class:`~dexplan.planning.planner.PlanResult` is one).
    """

    segments: Sequence[Segment]
    start_pose: FloatArray
    start_q: FloatArray | None

    @property
    def stats(self) -> _StatsLike: ...


class _StatsLike(Protocol):
    def as_dict(self) -> Mapping[str, Any]: ...


def _object_table(scenario: Any, base: Path, out_dir: Path) -> dict[str, Any]:
    """The plan's ``object`` table: the shape, and ``mass`` when the scenario gives one."""
    d = _portable_shape(scenario.object, base, out_dir)
    mass = getattr(scenario, "object_mass", None)
    if mass is not None:
        d["mass"] = float(mass)
    return d


def build_plan_document(
    scenario: Scenario, hand: Hand, result: PlannedPath, out_dir: str | Path = "."
) -> dict[str, Any]:
    """The ``dexplan-plan/1`` document of a planner's result.

    Args:
        scenario: the scenario planned.
        hand: the hand used.
        result: the planner's result (segments, start pose and joints, statistics).
        out_dir: folder the plan will be written to (mesh paths are relative to it).
    """
    out_dir = Path(out_dir)
    base = scenario.base_dir
    g = scenario.goal
    doc = {
        "format": FORMAT,
        "scenario": scenario.name,
        "hand": {
            "urdf_xml": hand.urdf_xml,
            "joint_names": list(hand.joint_names),
            "fingertip_frames": list(hand.fingertip_frames),
            "fingertip_radius": hand.fingertip_radius,
            "collision_exclude": [list(p) for p in hand.collision_exclude],
        },
        "object": _object_table(scenario, base, out_dir),
        "mu": scenario.mu,
        "friction_edges": scenario.friction_edges,
        "contact_model": scenario.contact_model,
        "torsion": scenario.torsion,
        "obstacles": [_portable_shape(o, base, out_dir) for o in scenario.obstacles],
        "start": {
            "object_pose_xyzquat": [float(v) for v in result.start_pose],
            "q": None if result.start_q is None else [float(v) for v in result.start_q],
        },
        "goal": {
            "object_pose_xyzquat": [float(v) for v in g.object_pose_xyzquat],
            "position_tol": g.position_tol,
            "angle_tol": g.angle_tol,
        },
        "segments": [segment_to_dict(s) for s in result.segments],
        "stats": _jsonable(result.stats.as_dict()),
    }
    gravity = getattr(scenario, "gravity", None)
    if gravity is not None:  # [world] gravity, for executing the plan
        doc["world"] = {"gravity": [float(v) for v in gravity]}
    return doc


def _jsonable(value: Any) -> Any:
    """Statistics as plain JSON values (NumPy scalars and arrays converted)."""
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
