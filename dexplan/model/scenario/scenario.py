"""Scenario files: the hand, the object, obstacles, start, goal and planner.

Scenarios are TOML, in metres and radians, poses in the world (= palm) frame
with quaternions XYZW. Every field is validated before any model is built; a
wrong one raises :class:`~dexplan.core.errors.ScenarioError` naming the field
and its (shortened) value, unknown fields are rejected in every table with a
"did you mean" hint (a typo never silently falls back to a default), and every
size is bounded by one of the limits of :mod:`.spec` (``docs/scenario.md``).
The paper's experiment is embedded: :func:`default_scenario`.
"""

from __future__ import annotations

import dataclasses
import math
import re
import tomllib
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import Any, cast

import numpy as np

from dexplan.core.errors import DexplanError, InvalidInputError, ScenarioError, one_line, shorten
from dexplan.core.typing import FloatArray
from dexplan.model.grasp import (
    CONTACT_MODELS,
    MAX_FRICTION_EDGES,
    MAX_TORSION,
    MIN_FRICTION_EDGES,
    ContactModel,
)
from dexplan.model.grasp.rolling import CONTACT_MOTIONS, ContactMotion
from dexplan.model.objects.factory import SHAPE_FIELDS, SHAPE_KINDS, field_key, shape_from_dict
from dexplan.model.objects.mesh import unit_scale_hint
from dexplan.model.scenario.fields import (
    as_float,
    fail,
    integer,
    number,
    pose,
    string,
    table,
    vector,
)

# The table checks keep the name ``_only`` here: tests/test_scenario_docs.py
# finds every table's unknown-field check by it, to hold the parser to SCENARIO_FIELDS.
from dexplan.model.scenario.fields import check_only as _only
from dexplan.model.scenario.hand_table import hand_spec
from dexplan.model.scenario.spec import (
    DEFAULT_SCENARIO,
    MAX_ANGLE_TOL,
    MAX_FC_MARGIN,
    MAX_GRAVITY,
    MAX_HALF_EXTENT,
    MAX_HOLD_SHIFT,
    MAX_JOINT_VALUE,
    MAX_JOINTS,
    MAX_MESH_SCALE,
    MAX_MU,
    MAX_NAME,
    MAX_OBJECT_MASS,
    MAX_OBJECT_SIZE,
    MAX_OBSTACLE_SIZE,
    MAX_OBSTACLES,
    MAX_PARAM_FLOAT,
    MAX_PARAM_INT,
    MAX_PLANNER_PARAMS,
    MAX_POSITION_TOL,
    MAX_SCENARIO_BYTES,
    MAX_TIME_LIMIT,
    OBJECT_OWN_FIELDS,
    OBSTACLE_OWN_FIELDS,
    SCENARIO_FIELDS,
    SEED_LIMIT,
    SPACES,
    GoalSpec,
    HandSpec,
    PlannerSpec,
    Scenario,
    Space,
    StartSpec,
)


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
    kind = table.get("shape")
    known = isinstance(kind, str) and kind in SHAPE_KINDS
    allowed = SHAPE_FIELDS[cast(str, kind)] if known else frozenset().union(*SHAPE_FIELDS.values())
    _only(table, prefix, allowed | own)
    shape = {k: v for k, v in table.items() if k not in own}
    scale = shape.get("scale")
    if kind == "mesh" and (x := as_float(scale)) is not None and x > MAX_MESH_SCALE:
        fail(f"{prefix}.scale must be <= {MAX_MESH_SCALE:g}, got {shorten(scale)}")
    try:
        built = shape_from_dict(shape, base_dir, field=prefix)
    except DexplanError as exc:
        raise ScenarioError(one_line(str(exc))) from exc
    for key in ("radius", "length"):
        if key in shape and shape[key] > max_size:
            fail(f"{prefix}.{key} must be <= {max_size:g} m, got {shorten(shape[key])}")
    if "size" in shape and max(shape["size"]) > max_size:
        fail(f"{prefix}.size edges must be <= {max_size:g} m, got {shorten(shape['size'])}")
    if kind == "mesh" and not 2.0 * built.bounding_radius <= max_size:
        across, s = 2.0 * built.bounding_radius, as_float(scale) or 1.0
        fail(
            f"{prefix}: the mesh is {across:.3g} m across (bounding sphere, scale "
            f"{shorten(scale if scale is not None else 1.0)}), more than {max_size:g} m"
            f"{unit_scale_hint(across, s, max_size)}"
        )
    return shape


def _hand(h: Mapping[str, Any], base_dir: Path) -> HandSpec:
    """``[hand]``: a builtin hand, or a URDF or MJCF file (:mod:`.hand_table`)."""
    _only(h, "hand", SCENARIO_FIELDS["hand"])
    return hand_spec(h, base_dir)


def _params(p: Mapping[str, Any]) -> dict[str, Any]:
    """``planner.params``: up to :data:`MAX_PLANNER_PARAMS` scalar values by name."""
    params = p.get("params", {})
    if not isinstance(params, Mapping):
        fail(f"planner.params must be a table, got {shorten(params)}")
    if len(params) > MAX_PLANNER_PARAMS:
        fail(f"planner.params has {len(params)} entries, more than {MAX_PLANNER_PARAMS}")
    for key, val in params.items():
        name = f"planner.params.{field_key(key)}"
        if not key or len(key) > MAX_NAME or not key.isprintable():
            fail(f"{name}: parameter names must be 1 to {MAX_NAME} printable characters")
        if isinstance(val, bool):
            continue
        if isinstance(val, int):
            if abs(val) > MAX_PARAM_INT:
                fail(f"{name} must be an integer within +-2**53, got {shorten(val)}")
        elif isinstance(val, float):
            if not math.isfinite(val) or abs(val) > MAX_PARAM_FLOAT:
                fail(
                    f"{name} must be a finite number within +-{MAX_PARAM_FLOAT:g}, "
                    f"got {shorten(val)}"
                )
        elif isinstance(val, str):
            if len(val) > MAX_NAME or not val.isprintable():
                fail(
                    f"{name} must be a string of at most {MAX_NAME} printable characters, "
                    f"got {shorten(val)}"
                )
        else:
            fail(f"{name} must be a boolean, number or string, got {shorten(val)}")
    return dict(params)


# ---------------------------------------------------------------------- loading
def _contact_model(c: Mapping[str, Any]) -> tuple[ContactModel, float]:
    """``[contact] model`` and ``torsion`` (m): required in (0, MAX_TORSION] for soft."""
    model = c.get("model", "point")
    if not isinstance(model, str) or model not in CONTACT_MODELS:
        choices = " or ".join(f'"{m}"' for m in CONTACT_MODELS)
        fail(f"contact.model must be {choices}, got {shorten(model)}")
    if model == "point":
        if "torsion" in c:
            fail(
                'contact.torsion applies to model = "soft" only (point contacts transmit '
                f"no torsion), got torsion = {shorten(c['torsion'])}"
            )
        return ContactModel.POINT, 0.0
    if "torsion" not in c:
        fail(
            'contact.model = "soft" needs contact.torsion, the torsional friction '
            f"coefficient in metres (|tau_n| <= torsion * f_n), in (0, {MAX_TORSION:g}]"
        )
    torsion = number(c, "torsion", "contact", lo=0.0, lo_open=True, hi=MAX_TORSION)
    return ContactModel.SOFT, torsion


def _object(doc: Mapping[str, Any], base_dir: Path) -> tuple[dict[str, Any], float | None]:
    """``[object]``: its shape fields and ``mass`` (kg, or None)."""
    obj_table = table(doc, "object")
    obj = _shape_fields(
        obj_table, "object", base_dir, own=OBJECT_OWN_FIELDS, max_size=MAX_OBJECT_SIZE
    )
    mass = (
        number(obj_table, "mass", "object", lo=0.0, lo_open=True, hi=MAX_OBJECT_MASS)
        if "mass" in obj_table
        else None
    )
    return obj, mass


def _world(doc: Mapping[str, Any]) -> tuple[float, float, float] | None:
    """``[world] gravity`` (m/s^2), or None."""
    wt = table(doc, "world", required=False)
    _only(wt, "world", SCENARIO_FIELDS["world"])
    if "gravity" not in wt:
        return None
    gx, gy, gz = (float(v) for v in vector(wt, "gravity", "world", 3, max_abs=MAX_GRAVITY))
    return gx, gy, gz


def _contact(doc: Mapping[str, Any]) -> tuple[float, int, float, ContactModel, float]:
    """``[contact]``: ``mu``, ``friction_edges``, ``fc_margin``, ``model``, ``torsion``.

    ``hold_shift`` and ``hold_effort_share`` are read by :func:`_holds`.
    """
    c = table(doc, "contact", required=False)
    _only(c, "contact", SCENARIO_FIELDS["contact"])
    mu = number(c, "mu", "contact", 0.8, lo=0.0, hi=MAX_MU)
    edges = integer(c, "friction_edges", "contact", 8, lo=MIN_FRICTION_EDGES, hi=MAX_FRICTION_EDGES)
    fc_margin = number(c, "fc_margin", "contact", 0.005, lo=0.0, hi=MAX_FC_MARGIN)
    model, torsion = _contact_model(c)
    return mu, edges, fc_margin, model, torsion


def _holds(doc: Mapping[str, Any]) -> tuple[float, float]:
    """``[contact] hold_shift`` (m) and ``hold_effort_share``: how holds are checked.

    ``hold_shift``: how far each contact is moved when a hold is checked;
    ``hold_effort_share``: the share of the effort limits the planner's holds may use.
    """
    c = table(doc, "contact", required=False)
    shift = number(c, "hold_shift", "contact", 0.002, lo=0.0, hi=MAX_HOLD_SHIFT)
    share = number(c, "hold_effort_share", "contact", 1.0, lo=0.0, hi=1.0, lo_open=True)
    return shift, share


def _contact_motion(doc: Mapping[str, Any]) -> ContactMotion:
    """``[contact] motion``: how transfers move the contacts (``fixed`` or ``rolling``)."""
    c = table(doc, "contact", required=False)
    motion = c.get("motion", ContactMotion.FIXED.value)
    if not isinstance(motion, str) or motion not in CONTACT_MOTIONS:
        choices = " or ".join(f'"{m}"' for m in CONTACT_MOTIONS)
        fail(f"contact.motion must be {choices}, got {shorten(motion)}")
    return ContactMotion(motion)


def _obstacles(doc: Mapping[str, Any], base_dir: Path) -> tuple[dict[str, Any], ...]:
    """``[[obstacles]]``: shape fields plus ``pose_xyzquat`` and ``name`` each."""
    obstacles_raw = doc.get("obstacles", [])
    if not isinstance(obstacles_raw, list):
        fail(f"obstacles must be an array of tables, got {shorten(obstacles_raw)}")
    if len(obstacles_raw) > MAX_OBSTACLES:
        fail(f"obstacles has {len(obstacles_raw)} entries, more than {MAX_OBSTACLES}")
    obstacles = []
    for k, ob in enumerate(obstacles_raw):
        prefix = f"obstacles[{k}]"
        if not isinstance(ob, Mapping):
            fail(f"{prefix} must be a table, got {shorten(ob)}")
        shape = _shape_fields(
            ob,
            prefix,
            base_dir,
            own=OBSTACLE_OWN_FIELDS,
            max_size=MAX_OBSTACLE_SIZE,
        )
        shape["pose_xyzquat"] = pose(ob, "pose_xyzquat", prefix).tolist()
        shape["name"] = string(ob, "name", prefix, default=f"obstacle{k}")
        obstacles.append(shape)
    return tuple(obstacles)


def _start(doc: Mapping[str, Any]) -> StartSpec:
    """``[start]``: the object pose and optionally the joints ``q``."""
    s = table(doc, "start")
    _only(s, "start", SCENARIO_FIELDS["start"])
    return StartSpec(
        pose(s, "object_pose_xyzquat", "start"),
        vector(s, "q", "start", None, max_len=MAX_JOINTS, max_abs=MAX_JOINT_VALUE)
        if "q" in s
        else None,
    )


def _goal(doc: Mapping[str, Any]) -> GoalSpec:
    """``[goal]``: the object pose and the tolerances of the goal region."""
    g = table(doc, "goal")
    _only(g, "goal", SCENARIO_FIELDS["goal"])
    return GoalSpec(
        pose(g, "object_pose_xyzquat", "goal"),
        number(g, "position_tol", "goal", 0.005, lo=0.0, lo_open=True, hi=MAX_POSITION_TOL),
        number(g, "angle_tol", "goal", 0.05, lo=0.0, lo_open=True, hi=MAX_ANGLE_TOL),
    )


def _planner(doc: Mapping[str, Any]) -> PlannerSpec:
    """``[planner]``: name, time limit, seed, parameters and constrained space."""
    p = table(doc, "planner", required=False)
    _only(p, "planner", SCENARIO_FIELDS["planner"])
    space = p.get("space", "projected")
    if space not in SPACES:
        fail(f"planner.space must be one of {', '.join(SPACES)}, got {shorten(space)}")
    return PlannerSpec(
        name=string(p, "name", "planner", default="PRM"),
        time_limit=number(
            p, "time_limit", "planner", 30.0, lo=0.0, lo_open=True, hi=MAX_TIME_LIMIT
        ),
        seed=integer(p, "seed", "planner", 1, lo=0, hi=SEED_LIMIT - 1),
        params=_params(p),
        space=Space(space),
    )


def _workspace(doc: Mapping[str, Any]) -> FloatArray:
    """``[workspace] half_extent`` (3,) (m), 0.02 per axis by default."""
    w = table(doc, "workspace", required=False)
    _only(w, "workspace", SCENARIO_FIELDS["workspace"])
    half = np.full(3, 0.02)
    if "half_extent" in w:
        half = vector(w, "half_extent", "workspace", 3)
        if np.any(half < 0) or np.any(half > MAX_HALF_EXTENT):
            fail(
                f"workspace.half_extent entries must be in [0, {MAX_HALF_EXTENT:g}] m, "
                f"got {shorten(w['half_extent'])}"
            )
    return half


def _plain(value: object) -> object:
    """An array, tuple or NumPy scalar as the list or number a TOML document would hold."""
    if isinstance(value, np.ndarray | tuple | list):
        return [_plain(v) for v in (value.tolist() if isinstance(value, np.ndarray) else value)]
    return value.item() if isinstance(value, np.generic) else value


def checked_scenario(scenario: Scenario) -> Scenario:
    """``scenario`` with its start, goal and workspace checked as a scenario file's are.

    For scenarios made or changed in Python, such as
    ``dataclasses.replace(goal, object_pose_xyzquat=[0, 0, 0.1, 0, 0, 1, 0])``:
    lists, tuples and NumPy arrays all become arrays, and what the parser
    refuses (a quaternion that is not unit, a wrong length, a non-finite
    number, a tolerance out of range) is refused with the parser's
    one-line message, before any planning.

    Raises:
        ScenarioError: a start, goal or workspace field the parser would refuse.
        InvalidInputError: not a :class:`Scenario`.
    """
    if not isinstance(scenario, Scenario):
        raise InvalidInputError(f"scenario must be a Scenario, got {shorten(scenario)}")
    start, goal = scenario.start, scenario.goal
    doc: dict[str, Any] = {
        "start": {"object_pose_xyzquat": _plain(start.object_pose_xyzquat)},
        "goal": {
            "object_pose_xyzquat": _plain(goal.object_pose_xyzquat),
            "position_tol": _plain(goal.position_tol),
            "angle_tol": _plain(goal.angle_tol),
        },
        "workspace": {"half_extent": _plain(scenario.workspace_half_extent)},
    }
    if start.q is not None:
        doc["start"]["q"] = _plain(start.q)
    return dataclasses.replace(
        scenario, start=_start(doc), goal=_goal(doc), workspace_half_extent=_workspace(doc)
    )


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
    scen_name = string(doc, "name", "", default=name[:MAX_NAME] or "scenario")
    hand = _hand(table(doc, "hand", required=False) or {"builtin": "paper"}, base_dir)
    obj, mass = _object(doc, base_dir)
    gravity = _world(doc)
    mu, edges, fc_margin, model, torsion = _contact(doc)
    hold_shift, hold_effort_share = _holds(doc)
    motion = _contact_motion(doc)
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
        hold_shift=hold_shift,
        hold_effort_share=hold_effort_share,
        contact_motion=motion,
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
            fail(f"scenario file not found: {where}")
        size = path.stat().st_size
        if size > MAX_SCENARIO_BYTES:
            fail(f"scenario file {where} is {size} bytes, more than {MAX_SCENARIO_BYTES}")
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
