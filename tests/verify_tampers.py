"""The tampered-plan table of ``dexplan verify``: one smallest change per rule.

:data:`TAMPERS` maps every name of :data:`dexplan.planfile.verify.RULES` to a
:class:`Tamper`: a function that takes a plan from a real run and changes it
in the smallest way that breaks that rule, and returns the changed document
with the violations verify must report, as ``(rule, segment, waypoint)``
triples. ``tests/test_verify_tampers.py`` checks that verify reports exactly
those (no more, no fewer) and that the untouched plan passes; a rule added to
``RULES`` without an entry here fails that test.

Adding a case: write ``def _my_rule(doc: Doc) -> Tampered`` that edits
``doc`` (a deep copy, yours to change) and returns ``(doc, {("my_rule", s, w)})``,
then add ``"my_rule": Tamper("the change, in words", _my_rule)`` to
:data:`TAMPERS`. Find segments and waypoints by searching the plan (the
helpers below), never by fixed indices: the plan comes from a real run and may
change with the planner.

Some rules cannot be broken alone; their entries say which other rule breaks
with them and why (``Tamper.also``), and the expected set names both.
"""

from __future__ import annotations

import copy
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from dexplan.core.pose import inverse_transform_points, transform_points
from dexplan.core.segments import Waypoint
from dexplan.model.grasp.holds import HoldChecker
from dexplan.planfile.models import PlanModels, models_from_document
from dexplan.planfile.rules import MAX_STEP_RAD, TIP_DISTANCE_TOL
from dexplan.planfile.tip_contacts import tip_sides

Doc = dict[str, Any]
Where = tuple[str, int, int]
Tampered = tuple[Doc, set[Where]]

#: How far a tampered distance goes past its tolerance: clearly broken, still small.
OVER = 1.5 * TIP_DISTANCE_TOL  # (m)


@dataclass(frozen=True)
class Tamper:
    """One row of the table.

    Attributes:
        change: the change, in words (the closing table of the issue).
        apply: ``apply(doc) -> (tampered doc, expected violations)``; ``doc``
            is the caller's own deep copy.
        also: the other rules the change cannot help breaking, and why ("" when none).
    """

    change: str
    apply: Callable[[Doc], Tampered]
    also: str = ""


# ---------------------------------------------------------------- plan search
def _segments(doc: Doc, kind: str) -> Iterator[tuple[int, dict[str, Any]]]:
    for si, seg in enumerate(doc["segments"]):
        if seg["kind"] == kind:
            yield si, seg


def _first(doc: Doc, kind: str) -> tuple[int, dict[str, Any]]:
    return next(_segments(doc, kind))


def _last_transfer(doc: Doc) -> tuple[int, dict[str, Any]]:
    """The last transfer (its last waypoint has only a step before it to keep)."""
    return list(_segments(doc, "transfer"))[-1]


def _arr(w: dict[str, Any], key: str) -> np.ndarray:
    return np.asarray(w[key], dtype=float)


def _models(doc: Doc) -> PlanModels:
    return models_from_document(doc)


def _tip_obj(m: PlanModels, w: dict[str, Any], f: int) -> np.ndarray:
    """(3,) fingertip centre of finger ``f`` at waypoint ``w``, object frame."""
    tips = m.hand.fingertip_positions(_arr(w, "q"))
    return inverse_transform_points(_arr(w, "object_pose_xyzquat"), tips)[f]


def _move_tip(m: PlanModels, w: dict[str, Any], f: int, target_obj: np.ndarray) -> None:
    """Set finger ``f``'s joints of ``w`` so its tip centre is at ``target_obj`` (object frame)."""
    pose = _arr(w, "object_pose_xyzquat")
    target = transform_points(pose, np.asarray(target_obj, dtype=float).reshape(1, 3))[0]
    q = _arr(w, "q")
    res = m.hand.finger_ik(f, target, q)
    assert res.success and res.residual < 1e-6, "the tampered fingertip is out of reach"
    q[m.hand.finger_q_index[f]] = res.q_finger
    w["q"] = q.tolist()


def _set_contact(m: PlanModels, w: dict[str, Any], f: int, c: Any) -> None:
    """Set finger ``f``'s contact of ``w`` (a list, or None), its tip contact with it.

    A ``dexplan-plan/2`` file states each contact twice, on the object and on
    the fingertip (``tip_contacts``): a change of one is made to both.
    """
    w["contacts"][f] = None if c is None else [float(v) for v in c]
    if "tip_contacts" not in w:
        return
    if c is None:
        w["tip_contacts"][f] = None
        return
    way = Waypoint(
        _arr(w, "object_pose_xyzquat"),
        _arr(w, "q"),
        tuple(None if v is None else np.asarray(v, dtype=float) for v in w["contacts"]),
    )
    w["tip_contacts"][f] = tip_sides(m.hand, way)[f].tolist()


def _outward(m: PlanModels, p_obj: np.ndarray) -> np.ndarray:
    """(3,) the outward unit normal of the object at its surface point nearest ``p_obj``."""
    _, n = m.obj.closest_point(p_obj)
    return np.asarray(n, dtype=float).reshape(3)


def _steps_ok(seg: dict[str, Any], wi: int) -> bool:
    """True when waypoint ``wi``'s joint steps to its neighbours are within the step rule."""
    W = seg["waypoints"]
    for a, b in ((wi - 1, wi), (wi, wi + 1)):
        step = (
            float(np.max(np.abs(_arr(W[b], "q") - _arr(W[a], "q"))))
            if a >= 0 and b < len(W)
            else 0.0
        )
        if step > MAX_STEP_RAD:
            return False
    return True


def _tip_moved_at_end(doc: Doc, along: float) -> Tampered:
    """The plan's last waypoint (of a transfer) with finger 0's tip moved ``along`` its normal.

    The last waypoint has no continuity to keep, only the step before it; the
    fingertip moves along the surface normal, so its stated contact stays the
    closest surface point to it.
    """
    m = _models(doc)
    si, seg = _last_transfer(doc)
    assert si == len(doc["segments"]) - 1, "the plan ends with a transfer"
    wi = len(seg["waypoints"]) - 1
    w = seg["waypoints"][wi]
    f = next(i for i, c in enumerate(w["contacts"]) if c is not None)
    tip = _tip_obj(m, w, f)
    _move_tip(m, w, f, tip + along * _outward(m, tip))
    assert _steps_ok(seg, wi), "the tampered tip moved a joint past the step rule"
    return doc, {("fingertip_distance", si, wi), *_off_the_tip(doc, si, wi)}


def _off_the_tip(doc: Doc, si: int, wi: int) -> set[Where]:
    """The tip-contact violation of a contact moved off the tip sphere (format /2 only)."""
    return {("tip_contact", si, wi)} if doc["format"] != "dexplan-plan/1" else set()


# ---------------------------------------------------------------- one per rule
def _object_pose(doc: Doc) -> Tampered:
    si, seg = _first(doc, "transfer")
    wi = len(seg["waypoints"]) // 2
    quat = seg["waypoints"][wi]["object_pose_xyzquat"]
    quat[3:] = [v * (1.0 + 1e-4) for v in quat[3:]]
    return doc, {("object_pose", si, wi)}


def _joint_limits(doc: Doc) -> Tampered:
    """Lower a joint's URDF upper limit just under the plan's one highest value of it."""
    values = [
        (si, wi, _arr(w, "q"))
        for si, seg in enumerate(doc["segments"])
        for wi, w in enumerate(seg["waypoints"])
    ]
    Q = np.array([q for _, _, q in values])
    orders = [np.argsort(Q[:, j]) for j in range(Q.shape[1])]
    unique = [j for j, o in enumerate(orders) if Q[o[-1], j] - Q[o[-2], j] > 1e-6]
    assert unique, "no joint has one highest value in the plan"
    j, order = unique[0], orders[unique[0]]
    name = doc["hand"]["joint_names"][j]
    top, second = Q[order[-1], j], Q[order[-2], j]
    limit = float(0.5 * (top + second))
    pattern = rf'(<joint name="{re.escape(name)}".*?<limit[^>]*upper=")([^"]*)(")'
    urdf, n = re.subn(pattern, rf"\g<1>{limit!r}\g<3>", doc["hand"]["urdf_xml"], flags=re.S)
    assert n == 1, f"joint {name}'s limit not found in the URDF"
    doc["hand"]["urdf_xml"] = urdf
    si, wi, _ = values[order[-1]]
    return doc, {("joint_limits", si, wi)}


def _fingertip_distance(doc: Doc) -> Tampered:
    return _tip_moved_at_end(doc, OVER)


def _regrasp_end_contact(
    doc: Doc, move: Callable[[PlanModels, np.ndarray], np.ndarray]
) -> Tampered:
    """The first regrasp's last waypoint with the regrasping finger's stated contact moved.

    The regrasping finger's contact at the end of its regrasp is its own (no
    transfer drift, no other finger's stillness to keep).
    """
    m = _models(doc)
    si, seg = _first(doc, "regrasp")
    wi = len(seg["waypoints"]) - 1
    w = seg["waypoints"][wi]
    f = seg["finger"]
    _set_contact(m, w, f, move(m, np.asarray(w["contacts"][f], dtype=float)))
    rule = RULE_OF_MOVE[move]
    # a contact moved out along the normal is as far off the fingertip sphere
    return doc, {(rule, si, wi), *(_off_the_tip(doc, si, wi) if move is _off_surface else ())}


def _off_surface(m: PlanModels, c: np.ndarray) -> np.ndarray:
    return c + OVER * _outward(m, c)


def _along_surface(m: PlanModels, c: np.ndarray) -> np.ndarray:
    n = _outward(m, c)
    t = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    p, _ = m.obj.closest_point(c + OVER * t / np.linalg.norm(t))
    return np.asarray(p, dtype=float).reshape(3)


RULE_OF_MOVE = {_off_surface: "contact_on_surface", _along_surface: "contact_matches_fingertip"}


def _collision(doc: Doc) -> Tampered:
    """A small sphere obstacle just touching the fingertip farthest from the object.

    Every fingertip of every waypoint is nearer the object's centre than the
    farthest one, by more than the sphere's overlap: only that waypoint touches it.
    """
    m = _models(doc)
    r = m.hand.fingertip_radius
    found = []
    for si, seg in enumerate(doc["segments"]):
        for wi, w in enumerate(seg["waypoints"]):
            tips = m.hand.fingertip_positions(_arr(w, "q"))
            centre = _arr(w, "object_pose_xyzquat")[:3]
            for f, p in enumerate(tips):
                found.append((float(np.linalg.norm(p - centre)), si, wi, f, p, centre))
    found.sort(key=lambda x: x[0])
    d1, si, wi, _, p, centre = found[-1]
    overlap = min(1e-4, 0.5 * (d1 - found[-2][0]))
    assert overlap > 1e-7, "two fingertips are equally far from the object"
    rho = 0.002
    u = (p - centre) / d1
    x = p + (r + rho - overlap) * u
    doc["obstacles"].append(
        {"shape": "sphere", "radius": rho, "pose_xyzquat": [*x.tolist(), 0.0, 0.0, 0.0, 1.0]}
    )
    return doc, {("collision", si, wi)}


def _penetration(doc: Doc) -> Tampered:
    doc, _ = _tip_moved_at_end(doc, -OVER)
    si = len(doc["segments"]) - 1
    wi = len(doc["segments"][si]["waypoints"]) - 1
    return doc, {
        ("penetration", si, wi),
        ("fingertip_distance", si, wi),
        *_off_the_tip(doc, si, wi),
    }


def _drop_contact(seg: dict[str, Any], f: int) -> None:
    for w in seg["waypoints"]:
        w["contacts"][f] = None
        if "tip_contacts" in w:
            w["tip_contacts"][f] = None


def _force_closure(doc: Doc) -> Tampered:
    """A regrasp's holding finger set free all along: two fingers cannot hold a sphere."""
    si, seg = _first(doc, "regrasp")
    other = next(i for i, c in enumerate(seg["waypoints"][1]["contacts"]) if c is not None)
    _drop_contact(seg, other)
    interior = range(1, len(seg["waypoints"]) - 1)
    touching = {("collision", si, wi) for wi in range(len(seg["waypoints"]))}
    unheld = {(rule, si, wi) for wi in interior for rule in ("force_closure", "holds")}
    return doc, unheld | touching


def _subgrasp_force_closure(doc: Doc) -> Tampered:
    """A transfer held by one finger fewer all along: its two-finger subgrasps fail."""
    si, seg = _first(doc, "transfer")
    _drop_contact(seg, 0)
    every = range(len(seg["waypoints"]))
    return doc, {(rule, si, wi) for wi in every for rule in ("subgrasp_force_closure", "collision")}


def _holds(doc: Doc) -> Tampered:
    """The object made heavier, just enough that its hardest holds need more than the limits.

    A hold's torque ratio grows in proportion to the weight: the mass is set
    between the values where the hardest and the next hardest holds reach
    ratio 1, so only the hardest fail (a regrasp's interior waypoints are one
    hold, the same fingers still on the same contacts: they fail together).
    """
    m = _models(doc)
    chk = HoldChecker(
        m.hand,
        m.obj,
        m.mu,
        m.friction_edges,
        m.contact_model,
        m.torsion,
        m.forces,
        shift_m=m.hold_shift,
    )
    ratios = []
    for si, seg in enumerate(doc["segments"]):
        f, W = seg["finger"], seg["waypoints"]
        for wi, w in enumerate(W):
            if f is not None and not 0 < wi < len(W) - 1:
                continue  # a regrasp's hold: the n-1 fingers, at interior waypoints
            held = [None if i == f else c for i, c in enumerate(w["contacts"])]
            r = chk.ratio(_arr(w, "q"), _arr(w, "object_pose_xyzquat"), held, shifted=f is not None)
            ratios.append((r, si, wi))
    top = max(r for r, _, _ in ratios)
    hardest = {("holds", si, wi) for r, si, wi in ratios if r > top * (1 - 1e-9)}
    below = max(r for r, _, _ in ratios if r <= top * (1 - 1e-9))
    assert top > 1.01 * below, "the hardest holds are not clearly harder than the others"
    doc["object"]["mass"] = m.forces.mass * 2.0 / (top + below)
    return doc, hardest


def _no_segments(doc: Doc) -> Tampered:
    doc["segments"] = []
    return doc, {("segments", -1, -1)}


def _step(doc: Doc) -> Tampered:
    """One waypoint of a transfer removed where its two steps add up past the step rule."""
    for si, seg in _segments(doc, "transfer"):
        W = seg["waypoints"]
        for wi in range(1, len(W) - 1):
            if float(np.max(np.abs(_arr(W[wi + 1], "q") - _arr(W[wi - 1], "q")))) > MAX_STEP_RAD:
                del W[wi]
                return doc, {("step", si, wi)}
    raise AssertionError("no transfer waypoint whose removal breaks the step rule")


def _transfer_contacts(doc: Doc) -> Tampered:
    si, seg = _first(doc, "transfer")
    wi = len(seg["waypoints"]) // 2
    _set_contact(_models(doc), seg["waypoints"][wi], 0, None)
    return doc, {
        ("transfer_contacts", si, wi),
        ("subgrasp_force_closure", si, wi),
        ("collision", si, wi),
    }


def _transfer_contact_drift(doc: Doc) -> Tampered:
    """A transfer's contact and fingertip slid 1.5 mm along the surface at one waypoint.

    The first waypoint, from the plan's end backwards, and finger where the
    slide keeps the joints within the step rule.
    """
    m = _models(doc)
    for si, seg in reversed(list(_segments(doc, "transfer"))):
        for wi in range(len(seg["waypoints"]) - 1, 0, -1):
            for f in range(len(seg["waypoints"][wi]["contacts"])):
                w = copy.deepcopy(seg["waypoints"][wi])
                c = _along_surface(m, np.asarray(w["contacts"][f], dtype=float))
                _move_tip(m, w, f, c + m.hand.fingertip_radius * _outward(m, c))
                _set_contact(m, w, f, c)
                if _steps_ok(
                    {"waypoints": [*seg["waypoints"][:wi], w, *seg["waypoints"][wi + 1 :]]}, wi
                ):
                    seg["waypoints"][wi] = w
                    return doc, {("transfer_contact_drift", si, wi)}
    raise AssertionError("no transfer waypoint where a slid fingertip keeps the step rule")


def _transfer_no_slip(doc: Doc) -> Tampered:
    """A fixed-contact plan said to roll: its fingertips slide over the object instead."""
    assert doc["contact_motion"] == "fixed"
    doc["contact_motion"] = "rolling"
    return doc, {
        ("transfer_no_slip", si, len(seg["waypoints"]) - 1)
        for si, seg in _segments(doc, "transfer")
    }


def _tip_contact(doc: Doc) -> Tampered:
    """One tip contact (the contact seen from the tip link) moved 1.5 mm."""
    si, seg = _first(doc, "transfer")
    wi = len(seg["waypoints"]) // 2
    row = seg["waypoints"][wi]["tip_contacts"]
    f = next(i for i, t in enumerate(row) if t is not None)
    row[f] = [row[f][0] + OVER, row[f][1], row[f][2]]
    return doc, {("tip_contact", si, wi)}


def _regrasp_object_still(doc: Doc) -> Tampered:
    si, seg = _first(doc, "regrasp")
    seg["waypoints"][1]["object_pose_xyzquat"][0] += 1e-6
    return doc, {("regrasp_object_still", si, 1)}


def _regrasp_one_finger(doc: Doc) -> Tampered:
    si, seg = _first(doc, "regrasp")
    f = seg["finger"]
    other = (f + 1) % len(seg["waypoints"][0]["contacts"])
    j = int(_models(doc).hand.finger_q_index[other][0])
    seg["waypoints"][1]["q"][j] += 1e-6
    return doc, {("regrasp_one_finger", si, 1)}


def _regrasp_interior(doc: Doc) -> Tampered:
    """A motionless regrasp of two waypoints inserted after the first transfer."""
    si, seg = _first(doc, "transfer")
    end = seg["waypoints"][-1]
    doc["segments"].insert(
        si + 1, {"kind": "regrasp", "finger": 0, "waypoints": [copy.deepcopy(end) for _ in "ab"]}
    )
    return doc, {("regrasp_interior", si + 1, -1)}


def _regrasp_free_finger(doc: Doc) -> Tampered:
    """The free finger given a contact where it is nearest the object (its closest surface point).

    Where that finger is more than 1 mm off the surface, the contact is also a
    fingertip-distance violation.
    """
    m = _models(doc)
    best = None
    for si, seg in _segments(doc, "regrasp"):
        f = seg["finger"]
        for wi in range(1, len(seg["waypoints"]) - 1):
            w = seg["waypoints"][wi]
            d = m.world.finger_object_distance(_arr(w, "q"), _arr(w, "object_pose_xyzquat"), f)
            if best is None or d < best[0]:
                best = (d, si, wi, f)
    assert best is not None
    _, si, wi, f = best
    w = doc["segments"][si]["waypoints"][wi]
    tip = _tip_obj(m, w, f)
    p, _ = m.obj.closest_point(tip)
    _set_contact(m, w, f, np.asarray(p, dtype=float).reshape(3))
    gap = float(m.obj.signed_distance(tip)) - m.hand.fingertip_radius
    out = {("regrasp_free_finger", si, wi)}
    if gap > TIP_DISTANCE_TOL:  # the contact is as far from the fingertip as the surface
        out |= {("fingertip_distance", si, wi), *_off_the_tip(doc, si, wi)}
    return doc, out


def _regrasp_clearance(doc: Doc) -> Tampered:
    """The free finger's tip pushed 0.1 mm into the object at one interior waypoint.

    The interior waypoint nearest the object where the move keeps the joints
    within the step rule.
    """
    m = _models(doc)
    near = []
    for si, seg in _segments(doc, "regrasp"):
        f = seg["finger"]
        for wi in range(1, len(seg["waypoints"]) - 1):
            w = seg["waypoints"][wi]
            d = m.world.finger_object_distance(_arr(w, "q"), _arr(w, "object_pose_xyzquat"), f)
            near.append((d, si, wi, f))
    for _, si, wi, f in sorted(near):
        seg = doc["segments"][si]
        w = copy.deepcopy(seg["waypoints"][wi])
        p, _ = m.obj.closest_point(_tip_obj(m, w, f))
        p = np.asarray(p, dtype=float).reshape(3)
        _move_tip(m, w, f, p + (m.hand.fingertip_radius - 1e-4) * _outward(m, p))
        if _steps_ok({"waypoints": [*seg["waypoints"][:wi], w, *seg["waypoints"][wi + 1 :]]}, wi):
            seg["waypoints"][wi] = w
            return doc, {("regrasp_clearance", si, wi), ("collision", si, wi)}
    raise AssertionError("no interior waypoint where the free tip reaches the object in a step")


def _regrasp_endpoints(doc: Doc) -> Tampered:
    si, seg = _first(doc, "regrasp")
    wi = len(seg["waypoints"]) - 1
    _set_contact(_models(doc), seg["waypoints"][wi], seg["finger"], None)
    return doc, {("regrasp_endpoints", si, wi), ("collision", si, wi)}


def _continuity(doc: Doc) -> Tampered:
    """The regrasping finger's first joint moved 1e-6 rad at the start of a regrasp."""
    si, seg = _first(doc, "regrasp")
    assert si > 0
    j = int(_models(doc).hand.finger_q_index[seg["finger"]][0])
    seg["waypoints"][0]["q"][j] += 1e-6
    return doc, {("continuity", si, 0)}


def _start(doc: Doc) -> Tampered:
    if doc["start"].get("q") is not None:
        doc["start"]["q"][0] += 1e-6
    else:
        doc["start"]["object_pose_xyzquat"][0] += 1e-6
    return doc, {("start", 0, 0)}


def _goal(doc: Doc) -> Tampered:
    tol = float(doc["goal"].get("position_tol", 0.005))
    doc["goal"]["object_pose_xyzquat"][0] += tol + 1e-4
    last = len(doc["segments"]) - 1
    return doc, {("goal", last, len(doc["segments"][last]["waypoints"]) - 1)}


#: Every verify rule, its smallest breaking change.
TAMPERS: dict[str, Tamper] = {
    "object_pose": Tamper("a transfer waypoint's quaternion scaled by 1 + 1e-4", _object_pose),
    "joint_limits": Tamper(
        "a joint's URDF upper limit lowered just under the plan's one highest value of it",
        _joint_limits,
    ),
    "fingertip_distance": Tamper(
        "the last waypoint's fingertip moved 1.5 mm out along the normal (joints by IK)",
        _fingertip_distance,
        also="tip_contact (format /2): the contact is 1.5 mm off the tip sphere",
    ),
    "contact_on_surface": Tamper(
        "a regrasping finger's end contact moved 1.5 mm out along the normal",
        lambda doc: _regrasp_end_contact(doc, _off_surface),
        also="tip_contact (format /2): the contact is 1.5 mm inside the tip sphere",
    ),
    "contact_matches_fingertip": Tamper(
        "a regrasping finger's end contact slid 1.5 mm along the surface",
        lambda doc: _regrasp_end_contact(doc, _along_surface),
    ),
    "collision": Tamper(
        "a 2 mm sphere obstacle overlapping the farthest fingertip by at most 0.1 mm",
        _collision,
    ),
    "penetration": Tamper(
        "the last waypoint's fingertip moved 1.5 mm into the object (joints by IK)",
        _penetration,
        also=(
            "fingertip_distance: a tip 1.5 mm deep is 1.5 mm from touching; tip_contact "
            "(format /2): the contact is 1.5 mm inside the tip sphere"
        ),
    ),
    "force_closure": Tamper(
        "a holding finger of a regrasp set free all along (contact null)",
        _force_closure,
        also=(
            "holds: two fingers cannot carry the weight either; collision: the freed "
            "fingertip still touches the object without a stated contact"
        ),
    ),
    "subgrasp_force_closure": Tamper(
        "finger 0 set free all along a transfer (contact null)",
        _subgrasp_force_closure,
        also="collision: the freed fingertip still touches the object without a stated contact",
    ),
    "holds": Tamper("the object's mass set just past what its hardest hold can carry", _holds),
    "segments": Tamper("every segment removed", _no_segments),
    "step": Tamper("one transfer waypoint removed where its two steps add past 0.05 rad", _step),
    "transfer_contacts": Tamper(
        "a transfer waypoint's contact of finger 0 set to null",
        _transfer_contacts,
        also=(
            "subgrasp_force_closure: a three-finger grasp of a sphere has two-finger "
            "subgrasps; collision: the freed fingertip still touches the object"
        ),
    ),
    "transfer_contact_drift": Tamper(
        "the last waypoint's contact of finger 0 and its fingertip slid 1.5 mm along the surface",
        _transfer_contact_drift,
    ),
    "transfer_no_slip": Tamper(
        "contact_motion fixed -> rolling (the fixed contacts slide on the fingertips)",
        _transfer_no_slip,
    ),
    "tip_contact": Tamper("one tip_contacts entry moved 1.5 mm", _tip_contact),
    "regrasp_object_still": Tamper(
        "the object moved 1e-6 m at a regrasp's first interior waypoint", _regrasp_object_still
    ),
    "regrasp_one_finger": Tamper(
        "a holding finger's joint moved 1e-6 rad at a regrasp's interior waypoint",
        _regrasp_one_finger,
    ),
    "regrasp_interior": Tamper(
        "a motionless two-waypoint regrasp inserted after a transfer", _regrasp_interior
    ),
    "regrasp_free_finger": Tamper(
        "the free finger given a contact where it is nearest the object",
        _regrasp_free_finger,
        also="only where that is over 1 mm: fingertip_distance, tip_contact (it is that far)",
    ),
    "regrasp_clearance": Tamper(
        "the free finger's tip moved 0.1 mm into the object (joints by IK)",
        _regrasp_clearance,
        also="collision: the free fingertip is not a contact, so touching the object collides",
    ),
    "regrasp_endpoints": Tamper(
        "the regrasping finger's contact at its regrasp's end set to null",
        _regrasp_endpoints,
        also="collision: the fingertip still touches the object without a stated contact",
    ),
    "continuity": Tamper(
        "the regrasping finger's joint moved 1e-6 rad at its regrasp's first waypoint",
        _continuity,
    ),
    "start": Tamper(
        "start.q's first joint moved 1e-6 rad (without start.q, the start object pose 1e-6 m)",
        _start,
    ),
    "goal": Tamper("the goal moved its position tolerance + 0.1 mm", _goal),
}
