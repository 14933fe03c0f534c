"""The structure of plan files (``dexplan-plan/2``, and ``/1``), checked in one place.

:func:`validate_plan` is the one gate every plan document passes before it is
used: :func:`dexplan.planfile.document.read_plan` calls it (so ``dexplan verify``, ``dexplan
show`` and the benchmark all get it), and :func:`dexplan.planfile.verify.verify_plan` and
:func:`dexplan.viz.record_plan` call it for documents given in memory.

A document that passes is *well formed*: every table holds only known fields,
every required field is there, every value has its type, every number is
finite and within :data:`MAX_ABS_VALUE`, every list has its length (a pose 7
numbers, ``q`` one per ``hand.joint_names`` entry, ``contacts`` and
``tip_contacts`` one per ``hand.fingertip_frames`` entry, null together) and
every size is within the limits below, so a hostile file cannot make a reader
hang or crash. Whether a well-formed plan obeys the rules (force closure, steps,
contacts, goal) is the verifier's business
(:func:`dexplan.planfile.verify.verify_plan`); whether the URDF text builds a
hand is settled when the hand is built.

Errors are :class:`~dexplan.core.errors.PlanFileError` naming the field path
(``segments[0].waypoints[3].object_pose_xyzquat``) and the offending value,
shortened (:func:`~dexplan.core.errors.shorten`).

Format ``/2`` adds ``contact_motion`` (``fixed`` or ``rolling``) and, on
every waypoint, ``tip_contacts`` (the fingertip side of each contact, in its
tip link's frame). A ``/1`` document has neither: its transfers keep their
contacts fixed.
"""

from __future__ import annotations

import math
import numbers
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NoReturn

from dexplan.core.errors import DexplanError, PlanFileError, shorten, unknown_field
from dexplan.core.segments import SegmentKind
from dexplan.model.grasp import CONTACT_MODELS, MAX_FRICTION_EDGES, MAX_TORSION, MIN_FRICTION_EDGES
from dexplan.model.grasp.holds import MAX_HOLD_SHIFT
from dexplan.model.grasp.rolling import CONTACT_MOTIONS
from dexplan.model.objects import shape_from_dict
from dexplan.model.scenario.spec import MAX_FINGERTIP_RADIUS

__all__ = [
    "CONTACT_MODELS",
    "FORMAT",
    "FORMATS",
    "MAX_ABS_VALUE",
    "MAX_FINGERS",
    "MAX_JOINTS",
    "MAX_OBSTACLES",
    "MAX_PLAN_BYTES",
    "MAX_SEGMENTS",
    "MAX_WAYPOINTS",
    "SEGMENT_KINDS",
    "validate_plan",
]

#: The format tag of the plan files dexplan writes.
FORMAT = "dexplan-plan/2"
#: The format tags it reads (``/1``: contacts fixed during transfers, no tip side).
FORMATS = ("dexplan-plan/1", FORMAT)

# ------------------------------------------------------------------ limits
#: Largest plan file read (bytes).
MAX_PLAN_BYTES = 256 * 2**20
#: Most segments in a plan.
MAX_SEGMENTS = 10_000
#: Most waypoints in a plan, over all segments (a 180-degree turn in 0.05 rad
#: steps takes 63; the planner's plans have hundreds).
MAX_WAYPOINTS = 200_000
#: Most hand joints (entries of ``q`` and ``hand.joint_names``).
MAX_JOINTS = 128
#: Most fingers (entries of ``contacts`` and ``hand.fingertip_frames``).
MAX_FINGERS = 16
#: Most obstacles.
MAX_OBSTACLES = 1_000
#: Most ``hand.collision_exclude`` pairs.
MAX_EXCLUDE_PAIRS = 10_000
#: Most entries of ``hand.mesh_sha256``; longest mesh URI (characters).
MAX_MESHES = 4096
MAX_PATH_CHARS = 4096
#: Longest ``hand.urdf_xml`` (characters).
MAX_URDF_CHARS = 16 * 2**20
#: Longest joint, frame, link or obstacle name (characters).
MAX_NAME_CHARS = 256
#: Largest magnitude of any number in a plan (metres, radians, friction).
MAX_ABS_VALUE = 1e6
#: A pose's quaternion must have a norm within this of 1 (as in scenarios);
#: the verifier then holds waypoints to 1e-6.
QUAT_NORM_TOL = 1e-3

#: Values of a segment's ``kind`` (those of ``contact_model`` are the grasp
#: model's :data:`~dexplan.model.grasp.CONTACT_MODELS`).
SEGMENT_KINDS: tuple[str, ...] = tuple(k.value for k in SegmentKind)

# ------------------------------------------------------------------ tables
# (required fields, optional fields) of every strict table. Shape tables
# (object, obstacles) are checked by dexplan.model.objects.shape_from_dict; stats may
# hold anything.
_Fields = tuple[set[str], set[str]]
_TOP: _Fields = (
    {"format", "hand", "object", "mu", "start", "goal", "segments"},
    {
        "scenario",
        "friction_edges",
        "contact_model",
        "torsion",
        "hold_shift",
        "contact_motion",
        "obstacles",
        "world",
        "stats",
    },
)
_HAND: _Fields = (
    {"urdf_xml", "joint_names", "fingertip_frames", "fingertip_radius"},
    {"collision_exclude", "mesh_sha256"},
)
_START: _Fields = ({"object_pose_xyzquat"}, {"q"})
_GOAL: _Fields = ({"object_pose_xyzquat"}, {"position_tol", "angle_tol"})
_SEGMENT: _Fields = ({"kind", "finger", "waypoints"}, set())
_WAYPOINT: _Fields = ({"object_pose_xyzquat", "q", "contacts"}, set())
_WAYPOINT_2: _Fields = ({"object_pose_xyzquat", "q", "contacts", "tip_contacts"}, set())
_OBSTACLE_EXTRA = ("pose_xyzquat", "name")
_OBJECT_EXTRA = ("mass",)  # a property of the object, not of its shape
_WORLD: _Fields = (set(), {"gravity"})

_POSE = "7 numbers [x, y, z, qx, qy, qz, qw]"


# ----------------------------------------------------------------- helpers
def _fail(path: str, what: str, value: Any) -> NoReturn:
    """Raise the error for field ``path``: ``PATH WHAT, got VALUE``."""
    raise PlanFileError(f"{path} {what}, got {shorten(value)}")


def _key(key: object) -> str:
    """A table key as it may appear in a one-line message."""
    text = str(key)
    return text if text.isprintable() and 0 < len(text) <= 40 else shorten(text, 40)


def _join(prefix: str, key: str) -> str:
    return f"{prefix}.{key}" if prefix else key


def _table(value: Any, path: str, fields: _Fields, what: str = "a table") -> Mapping[str, Any]:
    """``value`` as a mapping with every required field and no unknown one."""
    if not isinstance(value, Mapping):
        _fail(path or "the plan", f"must be {what}", value)
    required, optional = fields
    allowed = required | optional
    for key, item in value.items():
        if key not in allowed:
            raise PlanFileError(unknown_field(path, _key(key), item, allowed))
    for key in sorted(required):
        if key not in value:
            raise PlanFileError(f"missing field {_join(path, key)}")
    return value


def _is_number(x: Any) -> bool:
    return isinstance(x, numbers.Real) and not isinstance(x, bool)


def _finite(x: Any) -> bool:
    """A number within :data:`MAX_ABS_VALUE` (exact for ints of any size)."""
    if isinstance(x, numbers.Integral):
        return abs(int(x)) <= MAX_ABS_VALUE
    f = float(x)
    return math.isfinite(f) and abs(f) <= MAX_ABS_VALUE


def _number(value: Any, path: str, *, lo: float | None = None, lo_open: bool = False) -> float:
    """A finite number (not a bool, not a string), optionally ``>= lo`` (``> lo``)."""
    if not _is_number(value) or not _finite(value):
        _fail(path, f"must be a finite number (|x| <= {MAX_ABS_VALUE:g})", value)
    x = float(value)
    if lo is not None and (x <= lo if lo_open else x < lo):
        _fail(path, f"must be {'>' if lo_open else '>='} {lo:g}", value)
    return x


def _integer(value: Any, path: str, lo: int, hi: int) -> int:
    """An integer in ``[lo, hi]`` (a bool or a float such as 8.0 is not one)."""
    if not isinstance(value, numbers.Integral) or isinstance(value, bool):
        _fail(path, f"must be an integer in [{lo}, {hi}]", value)
    if not lo <= int(value) <= hi:
        _fail(path, f"must be in [{lo}, {hi}]", value)
    return int(value)


def _string(value: Any, path: str, max_chars: int = MAX_NAME_CHARS) -> str:
    """A non-empty string of at most ``max_chars`` characters."""
    if not isinstance(value, str) or not value:
        _fail(path, "must be a non-empty string", value)
    if len(value) > max_chars:
        _fail(path, f"must have at most {max_chars} characters ({len(value)} given)", value)
    return value


def _list(value: Any, path: str, lo: int, hi: int, what: str) -> Sequence[Any]:
    """A list (or tuple) of ``lo`` to ``hi`` entries; ``what`` names them."""
    if not isinstance(value, list | tuple):
        _fail(path, f"must be a list of {what}", value)
    if not lo <= len(value) <= hi:
        count = f"{lo} to {hi}" if hi > lo else str(lo)
        _fail(path, f"must list {count} {what} ({len(value)} given)", value)
    return value


def _vector(value: Any, path: str, n: int, what: str) -> None:
    """Exactly ``n`` finite numbers; ``what`` describes them in the message."""
    if not isinstance(value, list | tuple) or len(value) != n:
        given = f" ({len(value)} given)" if isinstance(value, list | tuple) else ""
        _fail(path, f"must be {what}{given}", value)
    # the common case, plain floats in range, in one pass (NaN fails the
    # comparison); anything else is judged number by number
    if all(type(x) is float and -MAX_ABS_VALUE <= x <= MAX_ABS_VALUE for x in value):
        return
    for i, x in enumerate(value):
        if not _is_number(x) or not _finite(x):
            _fail(f"{path}[{i}]", f"must be a finite number (|x| <= {MAX_ABS_VALUE:g})", x)


def _pose(value: Any, path: str) -> None:
    """A pose: 7 finite numbers whose quaternion has (nearly) unit norm."""
    _vector(value, path, 7, _POSE)
    norm = math.sqrt(sum(float(x) ** 2 for x in value[3:]))
    if abs(norm - 1.0) > QUAT_NORM_TOL:
        _fail(path, f"quaternion (XYZW) must have unit norm (it has {norm:.6g})", value)


def _names(value: Any, path: str, lo: int, hi: int, what: str) -> Sequence[str]:
    items = _list(value, path, lo, hi, what)
    for i, name in enumerate(items):
        _string(name, f"{path}[{i}]")
    return items


# -------------------------------------------------------------- the tables
def _hand(h: Any) -> tuple[int, int]:
    """Check ``hand``; return (number of joints, number of fingers)."""
    h = _table(h, "hand", _HAND)
    _string(h["urdf_xml"], "hand.urdf_xml", MAX_URDF_CHARS)
    joints = _names(h["joint_names"], "hand.joint_names", 1, MAX_JOINTS, "joint names")
    tips = _names(h["fingertip_frames"], "hand.fingertip_frames", 2, MAX_FINGERS, "frame names")
    r = _number(h["fingertip_radius"], "hand.fingertip_radius", lo=0.0, lo_open=True)
    if r > MAX_FINGERTIP_RADIUS:  # the rule scenarios and Hand follow
        _fail("hand.fingertip_radius", f"must be <= {MAX_FINGERTIP_RADIUS:g} m", r)
    excl = h.get("collision_exclude", [])
    pairs = _list(excl, "hand.collision_exclude", 0, MAX_EXCLUDE_PAIRS, "[link, link] pairs")
    for k, pair in enumerate(pairs):
        _names(pair, f"hand.collision_exclude[{k}]", 2, 2, "link names")
    _mesh_sha256(h.get("mesh_sha256", {}))
    return len(joints), len(tips)


def _mesh_sha256(table: Any) -> None:
    """``hand.mesh_sha256``: mesh URI -> 64 lower-case hex digits."""
    if not isinstance(table, Mapping) or len(table) > MAX_MESHES:
        _fail("hand.mesh_sha256", f"must be a table of at most {MAX_MESHES} mesh digests", table)
    for uri, digest in table.items():
        _string(uri, "hand.mesh_sha256 key", MAX_PATH_CHARS)
        if not (isinstance(digest, str) and re.fullmatch(r"[0-9a-f]{64}", digest)):
            _fail(f"hand.mesh_sha256[{uri!r}]", "must be a SHA-256 in 64 hex digits", digest)


def _shape(d: Any, path: str, base_dir: Path | None) -> None:
    """A shape table, checked by :func:`dexplan.model.objects.shape_from_dict`."""
    if isinstance(d, Mapping):  # numbers are bounded as everywhere in a plan
        for key, value in d.items():
            entries = value if isinstance(value, list | tuple) else [value]
            for i, x in enumerate(entries):
                if _is_number(x) and not _finite(x):
                    where = f"{path}.{_key(key)}" + (f"[{i}]" if entries is value else "")
                    _fail(where, f"must be a finite number (|x| <= {MAX_ABS_VALUE:g})", x)
    try:
        shape_from_dict(d, base_dir, field=path)
    except DexplanError as exc:  # InvalidInputError, MeshError: they name the field
        raise PlanFileError(str(exc)) from exc


def _obstacles(items: Any, base_dir: Path | None) -> None:
    items = _list(items, "obstacles", 0, MAX_OBSTACLES, "obstacle tables")
    for k, ob in enumerate(items):
        path = f"obstacles[{k}]"
        if not isinstance(ob, Mapping):
            _fail(path, "must be a table", ob)
        if "pose_xyzquat" not in ob:
            raise PlanFileError(f"missing field {path}.pose_xyzquat")
        _pose(ob["pose_xyzquat"], f"{path}.pose_xyzquat")
        if "name" in ob:
            _string(ob["name"], f"{path}.name")
        _shape({k2: v for k2, v in ob.items() if k2 not in _OBSTACLE_EXTRA}, path, base_dir)


def _q(value: Any, path: str, n_joints: int) -> None:
    _vector(value, path, n_joints, f"{n_joints} numbers, one per hand.joint_names entry")


def _contacts(value: Any, path: str, n_fingers: int) -> None:
    what = "entries (one per hand.fingertip_frames entry: [x, y, z] or null)"
    items = _list(value, path, n_fingers, n_fingers, what)
    for i, c in enumerate(items):
        if c is not None:
            _vector(c, f"{path}[{i}]", 3, "null or 3 numbers [x, y, z]")


def _tip_contacts(value: Any, contacts: Sequence[Any], path: str) -> None:
    """``tip_contacts``: like ``contacts``, null exactly where a contact is."""
    _contacts(value, path, len(contacts))
    for i, (t, c) in enumerate(zip(value, contacts, strict=True)):
        if (t is None) != (c is None):
            _fail(f"{path}[{i}]", "must be null exactly where contacts is", t)


def _segments(items: Any, n_joints: int, n_fingers: int, version: int) -> None:
    items = _list(items, "segments", 0, MAX_SEGMENTS, "segment tables")
    total = 0
    for si, seg in enumerate(items):
        path = f"segments[{si}]"
        seg = _table(seg, path, _SEGMENT)
        kind = seg["kind"]
        if not isinstance(kind, str) or kind not in SEGMENT_KINDS:
            _fail(f"{path}.kind", "must be 'transfer' or 'regrasp'", kind)
        finger = seg["finger"]
        if kind == "transfer" and finger is not None:
            _fail(f"{path}.finger", "must be null for a transfer", finger)
        if kind == "regrasp":
            _integer(finger, f"{path}.finger", 0, n_fingers - 1)
        wps = _list(seg["waypoints"], f"{path}.waypoints", 1, MAX_WAYPOINTS, "waypoint tables")
        total += len(wps)
        if total > MAX_WAYPOINTS:
            _fail(f"{path}.waypoints", f"bring the plan over {MAX_WAYPOINTS} waypoints", total)
        for wi, w in enumerate(wps):
            wpath = f"{path}.waypoints[{wi}]"
            w = _table(w, wpath, _WAYPOINT_2 if version == 2 else _WAYPOINT)
            _pose(w["object_pose_xyzquat"], f"{wpath}.object_pose_xyzquat")
            _q(w["q"], f"{wpath}.q", n_joints)
            _contacts(w["contacts"], f"{wpath}.contacts", n_fingers)
            if version == 2:
                _tip_contacts(w["tip_contacts"], w["contacts"], f"{wpath}.tip_contacts")


def validate_plan(doc: Any, base_dir: str | Path | None = None) -> None:
    """Check that ``doc`` is a well-formed ``dexplan-plan/2`` (or ``/1``) document.

    Args:
        doc: the parsed JSON document (or one built in memory).
        base_dir: folder relative mesh paths resolve against (the plan file's);
            None means the working directory.

    Raises:
        PlanFileError: the first problem found, naming the field path and the
            shortened value, e.g. ``segments[0].waypoints[3].object_pose_xyzquat
            must be 7 numbers [x, y, z, qx, qy, qz, qw] (6 given), got [...]``.

    """
    base = None if base_dir is None else Path(base_dir)
    if not isinstance(doc, Mapping):
        _fail("the plan", "must be a JSON object", doc)
    if doc.get("format") not in FORMATS:
        _fail("format", f"must be {' or '.join(map(repr, FORMATS))}", doc.get("format"))
    version = FORMATS.index(doc["format"]) + 1
    _table(doc, "", _TOP, "a JSON object")
    motion = doc.get("contact_motion", "fixed")
    if version == 1 and "contact_motion" in doc:
        _fail("contact_motion", f"needs format {FORMAT!r} (transfers of /1 are fixed)", motion)
    if not isinstance(motion, str) or motion not in CONTACT_MOTIONS:
        _fail("contact_motion", f"must be {' or '.join(map(repr, CONTACT_MOTIONS))}", motion)
    if "scenario" in doc and not isinstance(doc["scenario"], str):
        _fail("scenario", "must be a string", doc["scenario"])
    n_joints, n_fingers = _hand(doc["hand"])
    obj = doc["object"]
    if isinstance(obj, Mapping) and "mass" in obj:
        _number(obj["mass"], "object.mass", lo=0.0, lo_open=True)
        obj = {k: v for k, v in obj.items() if k not in _OBJECT_EXTRA}
    _shape(obj, "object", base)
    if "world" in doc:
        world = _table(doc["world"], "world", _WORLD)
        if "gravity" in world:
            _vector(world["gravity"], "world.gravity", 3, "3 numbers [gx, gy, gz] (m/s^2)")
    _number(doc["mu"], "mu", lo=0.0)
    if "hold_shift" in doc and _number(doc["hold_shift"], "hold_shift", lo=0.0) > MAX_HOLD_SHIFT:
        _fail("hold_shift", f"must be at most {MAX_HOLD_SHIFT:g} m", doc["hold_shift"])
    if "friction_edges" in doc:
        _integer(doc["friction_edges"], "friction_edges", MIN_FRICTION_EDGES, MAX_FRICTION_EDGES)
    model = doc.get("contact_model", "point")
    if not isinstance(model, str) or model not in CONTACT_MODELS:
        _fail("contact_model", "must be 'point' or 'soft'", model)
    torsion = _number(doc["torsion"], "torsion", lo=0.0) if "torsion" in doc else 0.0
    if model == "point" and torsion != 0.0:
        _fail("torsion", "must be 0 with point contacts (contact_model 'point')", doc["torsion"])
    if model == "soft" and not 0.0 < torsion <= MAX_TORSION:
        _fail(
            "torsion",
            f"must be in (0, {MAX_TORSION:g}] m with soft contacts (contact_model 'soft')",
            doc.get("torsion"),
        )
    _obstacles(doc.get("obstacles", []), base)

    start = _table(doc["start"], "start", _START)
    _pose(start["object_pose_xyzquat"], "start.object_pose_xyzquat")
    if start.get("q") is not None:
        _q(start["q"], "start.q", n_joints)
    goal = _table(doc["goal"], "goal", _GOAL)
    _pose(goal["object_pose_xyzquat"], "goal.object_pose_xyzquat")
    for key in ("position_tol", "angle_tol"):
        if key in goal:
            _number(goal[key], f"goal.{key}", lo=0.0, lo_open=True)

    _segments(doc["segments"], n_joints, n_fingers, version)
    if "stats" in doc and not isinstance(doc["stats"], Mapping):
        _fail("stats", "must be a table", doc["stats"])
