"""Scenario files: the hand, the object, obstacles, start, goal and planner.

Scenarios are TOML, in metres and radians, poses in the world (= palm) frame
with quaternions XYZW. Every field is validated before any model is built; a
wrong one raises :class:`~dexplan.core.errors.ScenarioError` naming the field
and its (shortened) value, unknown fields are rejected in every table with a
"did you mean" hint (a typo never silently falls back to a default), and every
size is bounded by one of the limits below (``docs/scenario.md``).
The paper's experiment is embedded: :func:`default_scenario`.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from dexplan.core.errors import DexplanError, InvalidInputError, ScenarioError, one_line, shorten
from dexplan.core.files import file_sha256
from dexplan.core.typing import FloatArray
from dexplan.model.grasp import CONTACT_MODELS, MAX_FRICTION_EDGES, MAX_TORSION, MIN_FRICTION_EDGES
from dexplan.model.objects.factory import (
    ALL_SHAPE_FIELDS,
    SHAPE_FIELDS,
    SHAPE_KINDS,
    check_fields,
    field_key,
)

DEFAULT_SCENARIO = "paper_sphere"
SPACES = ("projected", "atlas", "tangent_bundle")

# ---------------------------------------------------------------------- limits
# Documented in docs/scenario.md ("Limits"); a value outside is bad input.
MAX_SCENARIO_BYTES = 1_000_000  # a scenario file is a few hundred bytes
MAX_POSITION = 10.0  # m: |x|, |y|, |z| of start, goal and obstacle positions
MAX_HALF_EXTENT = 1.0  # m: workspace.half_extent per axis
MAX_OBJECT_SIZE = 2.0  # m: object radius, length, box edge, mesh bounding diameter
MAX_OBJECT_MASS = 1000.0  # kg
MAX_GRAVITY = 1000.0  # m/s^2, each component of [world] gravity
MAX_OBSTACLE_SIZE = 2.0 * MAX_POSITION  # m: the same for an obstacle
MAX_MESH_SCALE = 1000.0  # object and obstacle mesh ``scale``
MAX_OBSTACLES = 256  # [[obstacles]] tables
MAX_MU = 10.0  # contact.mu (friction coefficient)
MAX_FC_MARGIN = 1.0  # contact.fc_margin (force-closure quality; Q is a unit-force measure)
MAX_POSITION_TOL = 1.0  # m: goal.position_tol
MAX_ANGLE_TOL = math.pi  # rad: goal.angle_tol
MAX_TIME_LIMIT = 86_400.0  # s: planner.time_limit (one day)
SEED_LIMIT = 2**31  # planner.seed < SEED_LIMIT (OMPL's RNG is seeded with 31-bit values)
MAX_JOINTS = 256  # start.q entries
MAX_JOINT_VALUE = 1000.0  # |start.q[i]| (rad or m; joint limits are the hand's)
MAX_FINGERS = 32  # hand.fingertip_frames entries
MAX_FINGERTIP_RADIUS = 0.5  # m: hand.fingertip_radius
MAX_COLLISION_EXCLUDE = 4096  # hand.collision_exclude pairs
MAX_URDF_BYTES = 50_000_000  # hand.urdf file size
MAX_NAME = 256  # characters of a name (scenario, obstacle, planner, frame, parameter)
MAX_PATH = 4096  # characters of a file name (hand.urdf; mesh paths likewise)
MAX_PLANNER_PARAMS = 64  # planner.params entries
MAX_PARAM_INT = 2**53  # |integer planner.params value| (exact as a double, as OMPL stores it)
MAX_PARAM_FLOAT = 1e12  # |float planner.params value|

# ----------------------------------------------------------------------- fields
# The fields each table accepts; the parser rejects any other, and
# docs/scenario.md documents every one (tests/test_scenario_docs.py checks it).
HAND_BUILTIN_FIELDS = frozenset({"builtin"})
HAND_URDF_FIELDS = frozenset({"urdf", "fingertip_frames", "fingertip_radius", "collision_exclude"})
OBSTACLE_OWN_FIELDS = frozenset({"name", "pose_xyzquat"})  # beside its shape fields
OBJECT_OWN_FIELDS = frozenset({"mass"})  # a property of the object, not of its shape
SCENARIO_FIELDS: Mapping[str, frozenset[str]] = {
    "": frozenset(
        {
            "name",
            "hand",
            "object",
            "contact",
            "obstacles",
            "start",
            "goal",
            "planner",
            "workspace",
            "world",
        }
    ),
    "hand": HAND_BUILTIN_FIELDS | HAND_URDF_FIELDS,  # builtin, or urdf and its fields
    "object": ALL_SHAPE_FIELDS | OBJECT_OWN_FIELDS,  # its shape kind's (SHAPE_FIELDS), mass
    "contact": frozenset({"mu", "friction_edges", "fc_margin", "model", "torsion"}),
    "obstacles": ALL_SHAPE_FIELDS | OBSTACLE_OWN_FIELDS,
    "start": frozenset({"object_pose_xyzquat", "q"}),
    "goal": frozenset({"object_pose_xyzquat", "position_tol", "angle_tol"}),
    "planner": frozenset({"name", "time_limit", "seed", "params", "space"}),
    "workspace": frozenset({"half_extent"}),
    "world": frozenset({"gravity"}),
}
"""Accepted fields per table (``""``: the top level; ``obstacles``: each ``[[obstacles]]``)."""


@dataclass(frozen=True)
class HandSpec:
    """Which hand: a builtin name, or a URDF file with its fingertip frames."""

    builtin: str | None = "paper"
    urdf: Path | None = None
    fingertip_frames: tuple[str, ...] = ()
    fingertip_radius: float | None = None
    collision_exclude: tuple[tuple[str, str], ...] = ()


@dataclass(frozen=True)
class StartSpec:
    """Start: an object pose, and optionally the hand joints (else a grasp is found)."""

    object_pose_xyzquat: FloatArray
    q: FloatArray | None = None


@dataclass(frozen=True)
class GoalSpec:
    """Goal region: an object pose with position (m) and angle (rad) tolerances."""

    object_pose_xyzquat: FloatArray
    position_tol: float = 0.005
    angle_tol: float = 0.05


@dataclass(frozen=True)
class PlannerSpec:
    """OMPL planner and run settings."""

    name: str = "PRM"
    time_limit: float = 30.0
    seed: int = 1
    params: Mapping[str, Any] = field(default_factory=dict)
    space: str = "projected"


@dataclass(frozen=True)
class Scenario:
    """A complete planning problem as read from a scenario file.

    Attributes:
        name: scenario name.
        hand: hand specification.
        object: object shape dict (``dexplan.model.objects.shape_from_dict`` schema).
        mu: friction coefficient.
        friction_edges: edges of the linearized friction cones.
        obstacles: obstacle dicts (shape fields plus ``pose_xyzquat``).
        start: start specification.
        goal: goal region.
        planner: planner settings.
        workspace_half_extent: (3,) box around the start position the object
            centre stays in (m).
        fc_margin: minimum force-closure quality of every (n-1) subgrasp.
        base_dir: folder of the scenario file (relative paths resolve there).
        contact_model: ``"point"`` (Coulomb friction, the paper) or ``"soft"``
            (soft finger: also torsional friction about the normal).
        torsion: soft-finger torsion coefficient (m), ``|tau_n| <= torsion f_n``,
            in (0, ``MAX_TORSION``] for soft contacts; 0 for point contacts.
        object_mass: ``[object] mass`` (kg), or None (executing a plan then
            assumes :data:`dexplan.execution.forces.DEFAULT_MASS`).
        gravity: ``[world] gravity`` (m/s^2, world frame), or None
            (:data:`dexplan.execution.forces.DEFAULT_GRAVITY`).
    """

    name: str
    hand: HandSpec
    object: Mapping[str, Any]
    mu: float
    friction_edges: int
    obstacles: tuple[Mapping[str, Any], ...]
    start: StartSpec
    goal: GoalSpec
    planner: PlannerSpec
    workspace_half_extent: FloatArray
    fc_margin: float
    base_dir: Path
    contact_model: str = "point"
    torsion: float = 0.0
    object_mass: float | None = None
    gravity: tuple[float, float, float] | None = None


# ---------------------------------------------------------------- field checks
def _fail(msg: str) -> NoReturn:
    raise ScenarioError(msg)


def _only(table: Mapping[str, Any], prefix: str, allowed: set[str] | frozenset[str]) -> None:
    try:
        check_fields(table, prefix, allowed)
    except InvalidInputError as exc:
        raise ScenarioError(str(exc)) from exc


def _where(prefix: str, key: str) -> str:
    return f"{prefix}.{key}" if prefix else key


def _table(doc: Mapping[str, Any], key: str, required: bool = True) -> Mapping[str, Any]:
    if key not in doc:
        if required:
            _fail(f"missing table [{key}]")
        return {}
    val = doc[key]
    if not isinstance(val, Mapping):
        _fail(f"{key} must be a table, got {shorten(val)}")
    return val


def _as_float(val: object) -> float | None:
    """A TOML number as a float (huge ints become +-inf); None for anything else."""
    if isinstance(val, bool) or not isinstance(val, int | float):
        return None
    try:
        return float(val)
    except OverflowError:
        return math.inf if val > 0 else -math.inf


def _number(
    table: Mapping[str, Any],
    key: str,
    prefix: str,
    default: float | None = None,
    *,
    lo: float,
    hi: float,
    lo_open: bool = False,
) -> float:
    """A finite number in ``[lo, hi]`` (``(lo, hi]`` with ``lo_open``)."""
    name = _where(prefix, key)
    if key not in table:
        if default is None:
            _fail(f"missing field {name}")
        return float(default)
    val = table[key]
    x = _as_float(val)
    if x is None or not math.isfinite(x):
        _fail(f"{name} must be a finite number, got {shorten(val)}")
    if x < lo or (lo_open and x == lo) or x > hi:
        _fail(f"{name} must be in {'(' if lo_open else '['}{lo:g}, {hi:g}], got {shorten(val)}")
    return x


def _integer(
    table: Mapping[str, Any], key: str, prefix: str, default: int, *, lo: int, hi: int
) -> int:
    """An integer in ``[lo, hi]``."""
    name = _where(prefix, key)
    val = table.get(key, default)
    if isinstance(val, bool) or not isinstance(val, int):
        _fail(f"{name} must be an integer in [{lo}, {hi}], got {shorten(val)}")
    if not lo <= val <= hi:
        _fail(f"{name} must be an integer in [{lo}, {hi}], got {shorten(val)}")
    return val


def _string(table: Mapping[str, Any], key: str, prefix: str, default: str | None = None) -> str:
    """A non-empty string of at most :data:`MAX_NAME` printable characters."""
    name = _where(prefix, key)
    if key not in table:
        if default is None:
            _fail(f"missing field {name}")
        return default
    val = table[key]
    if not isinstance(val, str) or not val or len(val) > MAX_NAME or not val.isprintable():
        _fail(
            f"{name} must be a non-empty string of at most {MAX_NAME} printable characters, "
            f"got {shorten(val)}"
        )
    return val


def _vector(
    table: Mapping[str, Any],
    key: str,
    prefix: str,
    size: int | None,
    *,
    max_len: int | None = None,
    max_abs: float | None = None,
) -> FloatArray:
    """A list of ``size`` (or 1 to ``max_len``) finite numbers, each ``|x| <= max_abs``."""
    name = _where(prefix, key)
    if key not in table:
        _fail(f"missing field {name}")
    val = table[key]
    want = f"a list of {size} numbers" if size else f"a list of 1 to {max_len} numbers"
    if not isinstance(val, list):
        _fail(f"{name} must be {want}, got {shorten(val)}")
    if (size is not None and len(val) != size) or (
        max_len is not None and not 1 <= len(val) <= max_len
    ):
        _fail(f"{name} must be {want}, got {len(val)} entries: {shorten(val)}")
    xs = [_as_float(v) for v in val]
    if any(x is None for x in xs):
        _fail(f"{name} must be {want}, got {shorten(val)}")
    arr = np.array(xs, dtype=float)
    if not np.all(np.isfinite(arr)):
        _fail(f"{name} must be finite, got {shorten(val)}")
    if max_abs is not None and np.any(np.abs(arr) > max_abs):
        _fail(f"{name} entries must be within +-{max_abs:g}, got {shorten(val)}")
    return arr


def _pose(table: Mapping[str, Any], key: str, prefix: str) -> FloatArray:
    """``[x, y, z, qx, qy, qz, qw]``: position within :data:`MAX_POSITION`, unit quaternion."""
    name = _where(prefix, key)
    pose = _vector(table, key, prefix, 7)
    if np.any(np.abs(pose[:3]) > MAX_POSITION):
        _fail(
            f"{name} position must be within +-{MAX_POSITION:g} m per axis, "
            f"got {shorten(table[key][:3])}"
        )
    with np.errstate(over="ignore"):  # a norm of inf is rejected below
        norm = float(np.linalg.norm(pose[3:]))
    if not math.isfinite(norm) or abs(norm - 1.0) > 1e-3:
        _fail(f"{name} quaternion (XYZW) must have unit norm, got norm {norm:.6g}")
    pose[3:] /= norm
    return pose


def _file(table: Mapping[str, Any], key: str, prefix: str, base_dir: Path) -> Path:
    """An existing regular file named by a string field, resolved against ``base_dir``."""
    name = _where(prefix, key)
    raw = table[key]
    if not isinstance(raw, str) or not raw or "\0" in raw or len(raw) > MAX_PATH:
        _fail(
            f"{name} must be a file name (a non-empty string of at most {MAX_PATH} "
            f"characters, no NUL), got {shorten(raw)}"
        )
    try:
        path = (base_dir / raw).resolve()
        ok = path.is_file()
    except (OSError, ValueError, RuntimeError) as exc:  # name too long, symlink loop
        _fail(f"{name}: cannot use {shorten(raw)}: {one_line(str(exc), 120)}")
    if not ok:
        _fail(f"{name} file not found: {shorten(str(path))}")
    return path


def _text_file(path: Path, name: str, max_bytes: int) -> None:
    """Check that ``path`` is a readable UTF-8 text file of at most ``max_bytes`` bytes."""
    try:
        size = path.stat().st_size
        if size > max_bytes:
            _fail(f"{name} file is {size} bytes, more than {max_bytes}: {shorten(str(path))}")
        data = path.read_bytes()
    except OSError as exc:
        _fail(f"{name}: cannot read {shorten(str(path))}: {one_line(exc.strerror or str(exc))}")
    try:
        data.decode("utf-8")
    except UnicodeDecodeError as exc:
        _fail(f"{name} is not UTF-8 text ({shorten(str(path))}): byte {exc.start} is invalid")
    if b"\0" in data:
        _fail(f"{name} is not a text file (it contains NUL bytes): {shorten(str(path))}")


def _shape_fields(
    table: Mapping[str, Any],
    prefix: str,
    base_dir: Path,
    *,
    own: frozenset[str] = frozenset(),
    max_size: float,
) -> dict[str, Any]:
    """The shape fields of ``table`` (its ``own`` fields removed), checked and bounded.

    Unknown fields are rejected against the shape kind's fields plus ``own``,
    so the hint and the allowed list are those of this table.
    """
    from dexplan.model.objects import shape_from_dict

    kind = table.get("shape")
    known = isinstance(kind, str) and kind in SHAPE_KINDS
    allowed = SHAPE_FIELDS[kind] if known else frozenset().union(*SHAPE_FIELDS.values())
    _only(table, prefix, allowed | own)
    shape = {k: v for k, v in table.items() if k not in own}
    scale = shape.get("scale")
    if kind == "mesh" and (x := _as_float(scale)) is not None and x > MAX_MESH_SCALE:
        _fail(f"{prefix}.scale must be <= {MAX_MESH_SCALE:g}, got {shorten(scale)}")
    try:
        built = shape_from_dict(shape, base_dir, field=prefix)
    except DexplanError as exc:
        raise ScenarioError(one_line(str(exc))) from exc
    for key in ("radius", "length"):
        if key in shape and shape[key] > max_size:
            _fail(f"{prefix}.{key} must be <= {max_size:g} m, got {shorten(shape[key])}")
    if "size" in shape and max(shape["size"]) > max_size:
        _fail(f"{prefix}.size edges must be <= {max_size:g} m, got {shorten(shape['size'])}")
    if kind == "mesh" and not 2.0 * built.bounding_radius <= max_size:
        _fail(
            f"{prefix}: the mesh is {2.0 * built.bounding_radius:.3g} m across (bounding "
            f"sphere, scale {shorten(scale if scale is not None else 1.0)}), more than "
            f"{max_size:g} m"
        )
    return shape


def _hand(h: Mapping[str, Any], base_dir: Path) -> HandSpec:
    if "urdf" not in h:
        for key, val in h.items():
            if key in HAND_URDF_FIELDS:
                _fail(
                    f"hand.{key} (= {shorten(val, 40)}) is only used with hand.urdf; "
                    "a builtin hand defines its own"
                )
        _only(h, "hand", HAND_BUILTIN_FIELDS)
        from dexplan.model.hand.builtin import BUILTIN_HANDS

        builtin = h.get("builtin", "paper")
        if not isinstance(builtin, str) or builtin not in BUILTIN_HANDS:
            _fail(f"hand.builtin must be one of {', '.join(BUILTIN_HANDS)}, got {shorten(builtin)}")
        return HandSpec(builtin=builtin)
    if "builtin" in h:
        _fail(
            f"hand.builtin (= {shorten(h['builtin'], 40)}) and hand.urdf "
            f"(= {shorten(h['urdf'], 40)}) exclude each other: give one"
        )
    _only(h, "hand", HAND_URDF_FIELDS)
    if "fingertip_frames" not in h:
        _fail("missing field hand.fingertip_frames (the URDF frames of the fingertip centres)")
    frames = h["fingertip_frames"]
    if not (
        isinstance(frames, list)
        and 1 <= len(frames) <= MAX_FINGERS
        and all(isinstance(f, str) and f and len(f) <= MAX_NAME for f in frames)
    ):
        _fail(
            f"hand.fingertip_frames must be a list of 1 to {MAX_FINGERS} frame names, "
            f"got {shorten(frames)}"
        )
    excl = h.get("collision_exclude", [])
    if not (
        isinstance(excl, list)
        and len(excl) <= MAX_COLLISION_EXCLUDE
        and all(
            isinstance(p, list)
            and len(p) == 2
            and all(isinstance(x, str) and x and len(x) <= MAX_NAME for x in p)
            for p in excl
        )
    ):
        _fail(
            f"hand.collision_exclude must be a list of at most {MAX_COLLISION_EXCLUDE} "
            f"[link, link] pairs, got {shorten(excl)}"
        )
    urdf = _file(h, "urdf", "hand", base_dir)
    _text_file(urdf, "hand.urdf", MAX_URDF_BYTES)
    return HandSpec(
        builtin=None,
        urdf=urdf,
        fingertip_frames=tuple(frames),
        fingertip_radius=_number(
            h, "fingertip_radius", "hand", lo=0.0, lo_open=True, hi=MAX_FINGERTIP_RADIUS
        ),
        collision_exclude=tuple((a, b) for a, b in excl),
    )


def _params(p: Mapping[str, Any]) -> dict[str, Any]:
    """``planner.params``: up to :data:`MAX_PLANNER_PARAMS` scalar values by name."""
    params = p.get("params", {})
    if not isinstance(params, Mapping):
        _fail(f"planner.params must be a table, got {shorten(params)}")
    if len(params) > MAX_PLANNER_PARAMS:
        _fail(f"planner.params has {len(params)} entries, more than {MAX_PLANNER_PARAMS}")
    for key, val in params.items():
        name = f"planner.params.{field_key(key)}"
        if not key or len(key) > MAX_NAME or not key.isprintable():
            _fail(f"{name}: parameter names must be 1 to {MAX_NAME} printable characters")
        if isinstance(val, bool):
            continue
        if isinstance(val, int):
            if abs(val) > MAX_PARAM_INT:
                _fail(f"{name} must be an integer within +-2**53, got {shorten(val)}")
        elif isinstance(val, float):
            if not math.isfinite(val) or abs(val) > MAX_PARAM_FLOAT:
                _fail(
                    f"{name} must be a finite number within +-{MAX_PARAM_FLOAT:g}, "
                    f"got {shorten(val)}"
                )
        elif isinstance(val, str):
            if len(val) > MAX_NAME or not val.isprintable():
                _fail(
                    f"{name} must be a string of at most {MAX_NAME} printable characters, "
                    f"got {shorten(val)}"
                )
        else:
            _fail(f"{name} must be a boolean, number or string, got {shorten(val)}")
    return dict(params)


# ---------------------------------------------------------------------- loading
def _contact_model(c: Mapping[str, Any]) -> tuple[str, float]:
    """``[contact] model`` and ``torsion`` (m): required in (0, MAX_TORSION] for soft."""
    model = c.get("model", "point")
    if not isinstance(model, str) or model not in CONTACT_MODELS:
        choices = " or ".join(f'"{m}"' for m in CONTACT_MODELS)
        _fail(f"contact.model must be {choices}, got {shorten(model)}")
    if model == "point":
        if "torsion" in c:
            _fail(
                'contact.torsion applies to model = "soft" only (point contacts transmit '
                f"no torsion), got torsion = {shorten(c['torsion'])}"
            )
        return model, 0.0
    if "torsion" not in c:
        _fail(
            'contact.model = "soft" needs contact.torsion, the torsional friction '
            f"coefficient in metres (|tau_n| <= torsion * f_n), in (0, {MAX_TORSION:g}]"
        )
    return model, _number(c, "torsion", "contact", lo=0.0, lo_open=True, hi=MAX_TORSION)


def _object(doc: Mapping[str, Any], base_dir: Path) -> tuple[dict[str, Any], float | None]:
    """``[object]``: its shape fields and ``mass`` (kg, or None)."""
    obj_table = _table(doc, "object")
    obj = _shape_fields(
        obj_table, "object", base_dir, own=OBJECT_OWN_FIELDS, max_size=MAX_OBJECT_SIZE
    )
    mass = (
        _number(obj_table, "mass", "object", lo=0.0, lo_open=True, hi=MAX_OBJECT_MASS)
        if "mass" in obj_table
        else None
    )
    return obj, mass


def _world(doc: Mapping[str, Any]) -> tuple[float, float, float] | None:
    """``[world] gravity`` (m/s^2), or None."""
    wt = _table(doc, "world", required=False)
    _only(wt, "world", SCENARIO_FIELDS["world"])
    if "gravity" not in wt:
        return None
    gx, gy, gz = (float(v) for v in _vector(wt, "gravity", "world", 3, max_abs=MAX_GRAVITY))
    return gx, gy, gz


def _contact(doc: Mapping[str, Any]) -> tuple[float, int, float, str, float]:
    """``[contact]``: ``mu``, ``friction_edges``, ``fc_margin``, ``model``, ``torsion``."""
    c = _table(doc, "contact", required=False)
    _only(c, "contact", SCENARIO_FIELDS["contact"])
    mu = _number(c, "mu", "contact", 0.8, lo=0.0, hi=MAX_MU)
    edges = _integer(
        c, "friction_edges", "contact", 8, lo=MIN_FRICTION_EDGES, hi=MAX_FRICTION_EDGES
    )
    fc_margin = _number(c, "fc_margin", "contact", 0.005, lo=0.0, hi=MAX_FC_MARGIN)
    model, torsion = _contact_model(c)
    return mu, edges, fc_margin, model, torsion


def _obstacles(doc: Mapping[str, Any], base_dir: Path) -> tuple[dict[str, Any], ...]:
    """``[[obstacles]]``: shape fields plus ``pose_xyzquat`` and ``name`` each."""
    obstacles_raw = doc.get("obstacles", [])
    if not isinstance(obstacles_raw, list):
        _fail(f"obstacles must be an array of tables, got {shorten(obstacles_raw)}")
    if len(obstacles_raw) > MAX_OBSTACLES:
        _fail(f"obstacles has {len(obstacles_raw)} entries, more than {MAX_OBSTACLES}")
    obstacles = []
    for k, ob in enumerate(obstacles_raw):
        prefix = f"obstacles[{k}]"
        if not isinstance(ob, Mapping):
            _fail(f"{prefix} must be a table, got {shorten(ob)}")
        shape = _shape_fields(
            ob,
            prefix,
            base_dir,
            own=OBSTACLE_OWN_FIELDS,
            max_size=MAX_OBSTACLE_SIZE,
        )
        shape["pose_xyzquat"] = _pose(ob, "pose_xyzquat", prefix).tolist()
        shape["name"] = _string(ob, "name", prefix, default=f"obstacle{k}")
        obstacles.append(shape)
    return tuple(obstacles)


def _start(doc: Mapping[str, Any]) -> StartSpec:
    """``[start]``: the object pose and optionally the joints ``q``."""
    s = _table(doc, "start")
    _only(s, "start", SCENARIO_FIELDS["start"])
    return StartSpec(
        _pose(s, "object_pose_xyzquat", "start"),
        _vector(s, "q", "start", None, max_len=MAX_JOINTS, max_abs=MAX_JOINT_VALUE)
        if "q" in s
        else None,
    )


def _goal(doc: Mapping[str, Any]) -> GoalSpec:
    """``[goal]``: the object pose and the tolerances of the goal region."""
    g = _table(doc, "goal")
    _only(g, "goal", SCENARIO_FIELDS["goal"])
    return GoalSpec(
        _pose(g, "object_pose_xyzquat", "goal"),
        _number(g, "position_tol", "goal", 0.005, lo=0.0, lo_open=True, hi=MAX_POSITION_TOL),
        _number(g, "angle_tol", "goal", 0.05, lo=0.0, lo_open=True, hi=MAX_ANGLE_TOL),
    )


def _planner(doc: Mapping[str, Any]) -> PlannerSpec:
    """``[planner]``: name, time limit, seed, parameters and constrained space."""
    p = _table(doc, "planner", required=False)
    _only(p, "planner", SCENARIO_FIELDS["planner"])
    space = p.get("space", "projected")
    if space not in SPACES:
        _fail(f"planner.space must be one of {', '.join(SPACES)}, got {shorten(space)}")
    return PlannerSpec(
        name=_string(p, "name", "planner", default="PRM"),
        time_limit=_number(
            p, "time_limit", "planner", 30.0, lo=0.0, lo_open=True, hi=MAX_TIME_LIMIT
        ),
        seed=_integer(p, "seed", "planner", 1, lo=0, hi=SEED_LIMIT - 1),
        params=_params(p),
        space=space,
    )


def _workspace(doc: Mapping[str, Any]) -> FloatArray:
    """``[workspace] half_extent`` (3,) (m), 0.02 per axis by default."""
    w = _table(doc, "workspace", required=False)
    _only(w, "workspace", SCENARIO_FIELDS["workspace"])
    half = np.full(3, 0.02)
    if "half_extent" in w:
        half = _vector(w, "half_extent", "workspace", 3)
        if np.any(half < 0) or np.any(half > MAX_HALF_EXTENT):
            _fail(
                f"workspace.half_extent entries must be in [0, {MAX_HALF_EXTENT:g}] m, "
                f"got {shorten(w['half_extent'])}"
            )
    return half


def parse_scenario(doc: Mapping[str, Any], base_dir: Path, name: str = "scenario") -> Scenario:
    """Validate a parsed TOML document and build a :class:`Scenario`.

    Only the scenario's own files are opened (the URDF, meshes); no model is
    built, so a bad field fails in milliseconds. The tables are read in a fixed
    order (hand, object, world, contact, obstacles, start, goal, planner,
    workspace), one parser each: the first bad field is the one reported.

    Raises:
        ScenarioError: a missing, malformed, out-of-range or unknown field.
    """
    _only(doc, "", SCENARIO_FIELDS[""])
    scen_name = _string(doc, "name", "", default=name[:MAX_NAME] or "scenario")
    hand = _hand(_table(doc, "hand", required=False) or {"builtin": "paper"}, base_dir)
    obj, mass = _object(doc, base_dir)
    gravity = _world(doc)
    mu, edges, fc_margin, model, torsion = _contact(doc)
    obstacles = _obstacles(doc, base_dir)
    start, goal = _start(doc), _goal(doc)
    planner = _planner(doc)
    half = _workspace(doc)
    return Scenario(
        name=scen_name,
        hand=hand,
        object=obj,
        mu=mu,
        friction_edges=edges,
        obstacles=obstacles,
        start=start,
        goal=goal,
        planner=planner,
        workspace_half_extent=half,
        fc_margin=fc_margin,
        base_dir=base_dir,
        contact_model=model,
        torsion=torsion,
        object_mass=mass,
        gravity=gravity,
    )


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario TOML file.

    Raises:
        ScenarioError: missing, oversized or unreadable file, TOML syntax error
            (including arrays or tables nested too deeply for the parser) or an
            invalid field.
    """
    path = Path(path)
    where = shorten(str(path))
    try:
        if not path.is_file():
            _fail(f"scenario file not found: {where}")
        size = path.stat().st_size
        if size > MAX_SCENARIO_BYTES:
            _fail(f"scenario file {where} is {size} bytes, more than {MAX_SCENARIO_BYTES}")
        data = path.read_bytes()
    except (OSError, ValueError) as exc:  # unreadable, name too long, NUL in the name
        raise ScenarioError(
            f"cannot read scenario file {where}: {one_line(str(exc), 120)}"
        ) from exc
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ScenarioError(
            f"{where}: not valid TOML: not UTF-8 text (byte {exc.start} is invalid)"
        ) from exc
    try:
        doc = tomllib.loads(text)
    except RecursionError as exc:
        raise ScenarioError(
            f"{where}: not valid TOML: arrays or tables nested too deeply{_line_of(text, _DEEP)}"
        ) from exc
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{where}: not valid TOML: {one_line(str(exc), 200)}") from exc
    except ValueError as exc:  # int(): more digits than Python converts
        raise ScenarioError(
            f"{where}: not valid TOML: an integer has too many digits{_line_of(text, _LONG_INT)}"
        ) from exc
    try:
        return parse_scenario(doc, path.resolve().parent, path.stem)
    except InvalidInputError as exc:
        raise ScenarioError(f"{where}: {one_line(str(exc))}") from exc


_DEEP = re.compile(r"(?:[\[{]\s*){32}")  # 32 arrays or tables opened in a row
_LONG_INT = re.compile(r"[0-9][0-9_]{1000,}")


def _line_of(text: str, pattern: re.Pattern[str]) -> str:
    """`` (line N)`` of the first match of ``pattern`` in ``text``, or ``""``."""
    m = pattern.search(text)
    return f" (line {text.count(chr(10), 0, m.start()) + 1})" if m else ""


def builtin_scenario_path(name: str = DEFAULT_SCENARIO) -> Path:
    """Path of a scenario shipped with dexplan (``dexplan/data/scenarios``)."""
    root = resources.files("dexplan").joinpath("data/scenarios")
    path = Path(str(root.joinpath(f"{name}.toml")))
    if not path.is_file():
        names = sorted(p.stem for p in Path(str(root)).glob("*.toml"))
        raise ScenarioError(f"no builtin scenario {name!r}; builtin scenarios: {names}")
    return path


def default_scenario() -> Scenario:
    """The paper's experiment: 4 x 3-DOF hand turning a sphere 180 degrees about z."""
    return load_scenario(builtin_scenario_path(DEFAULT_SCENARIO))


# ------------------------------------------------------------------ identity
#: Fields of a scenario that name or place it without changing its problem.
COSMETIC_FIELDS = ("name", "base_dir")


def _json_value(value: Any) -> Any:
    """JSON-ready view of scenario fields (arrays as lists, paths as strings)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _json_value(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, Mapping):
        return {str(k): _json_value(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_value(v) for v in value]
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    return value


def _digest_or_mark(path: Path) -> str:
    try:
        return file_sha256(path)
    except OSError:
        return f"unreadable:{path}"


def scenario_description(scenario: Scenario, *, models_only: bool = False) -> dict[str, Any]:
    """The fields that decide what a scenario plans, as plain JSON values.

    The one scenario identity: benchmark runs are keyed by it, and roadmaps
    (``models_only``) are tied to it. Cosmetic fields are left out (the
    scenario's name and folder, obstacle names), and so are the planner
    name, seed and time limit (a sweep sets them); files the scenario refers
    to (URDF, meshes) enter by their SHA-256. The contact model and torsion
    enter when the model is not the default ``point``.

    Args:
        scenario: the scenario.
        models_only: only the models a GSn roadmap depends on (hand, object,
            obstacles, friction, contact model and margin), not the query
            (start, goal, workspace, planner parameters).
    """
    doc = _json_value(scenario)
    for key in COSMETIC_FIELDS:
        doc.pop(key, None)
    for ob in doc["obstacles"]:
        ob.pop("name", None)
    if doc.get("contact_model", "point") == "point":
        doc.pop("contact_model", None)
        doc.pop("torsion", None)
    doc["planner"] = {k: v for k, v in doc["planner"].items() if k in ("params", "space")}
    if scenario.hand.urdf is not None:
        doc["hand"]["urdf"] = _digest_or_mark(Path(scenario.base_dir) / scenario.hand.urdf)
    for shape in [doc["object"], *doc["obstacles"]]:
        if isinstance(shape, dict) and "path" in shape:
            shape["path_sha256"] = _digest_or_mark(Path(scenario.base_dir) / str(shape["path"]))
    if models_only:
        for key in ("start", "goal", "planner", "workspace_half_extent"):
            doc.pop(key, None)
    return doc


def scenario_hash(scenario: Scenario, *, models_only: bool = False) -> str:
    """Short content hash (16 hex digits) of :func:`scenario_description`."""
    text = json.dumps(scenario_description(scenario, models_only=models_only), sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]
