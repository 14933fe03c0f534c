"""Scenario files: the hand, the object, obstacles, start, goal and planner.

Scenarios are TOML, in metres and radians, poses in the world (= palm) frame
with quaternions XYZW. Every field is validated; a wrong one raises
:class:`~dexplan.exceptions.ScenarioError` naming the field and its value, and
unknown fields are rejected (a typo never silently falls back to a default).
The paper's experiment is embedded: :func:`default_scenario`.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from dexplan.exceptions import DexplanError, InvalidInputError, ScenarioError
from dexplan.typing import FloatArray

DEFAULT_SCENARIO = "paper_sphere"
SPACES = ("projected", "atlas", "tangent_bundle")


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
        object: object shape dict (``dexplan.objects.shape_from_dict`` schema).
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


# ---------------------------------------------------------------- field checks
def _table(doc: Mapping[str, Any], key: str, required: bool = True) -> Mapping[str, Any]:
    if key not in doc:
        if required:
            raise ScenarioError(f"missing table [{key}]")
        return {}
    val = doc[key]
    if not isinstance(val, Mapping):
        raise ScenarioError(f"{key} must be a table, got {val!r}")
    return val


def _only(table: Mapping[str, Any], prefix: str, allowed: set[str]) -> None:
    extra = sorted(set(table) - allowed)
    if extra:
        raise ScenarioError(
            f"unknown field {prefix}.{extra[0]} (= {table[extra[0]]!r}); allowed: {sorted(allowed)}"
        )


def _number(
    table: Mapping[str, Any],
    key: str,
    prefix: str,
    default: Any = None,
    *,
    lo: float | None = None,
    lo_open: bool = False,
) -> float:
    if key not in table:
        if default is None:
            raise ScenarioError(f"missing field {prefix}.{key}")
        return float(default)
    val = table[key]
    if isinstance(val, bool) or not isinstance(val, int | float) or not math.isfinite(val):
        raise ScenarioError(f"{prefix}.{key} must be a finite number, got {val!r}")
    if lo is not None and (val < lo or (lo_open and val == lo)):
        op = ">" if lo_open else ">="
        raise ScenarioError(f"{prefix}.{key} must be {op} {lo}, got {val!r}")
    return float(val)


def _vector(table: Mapping[str, Any], key: str, prefix: str, size: int | None) -> FloatArray:
    if key not in table:
        raise ScenarioError(f"missing field {prefix}.{key}")
    val = table[key]
    ok = isinstance(val, list) and all(
        isinstance(v, int | float) and not isinstance(v, bool) for v in val
    )
    if not ok or (size is not None and len(val) != size):
        want = f"a list of {size} numbers" if size else "a list of numbers"
        raise ScenarioError(f"{prefix}.{key} must be {want}, got {val!r}")
    arr = np.asarray(val, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ScenarioError(f"{prefix}.{key} must be finite, got {val!r}")
    return arr


def _pose(table: Mapping[str, Any], key: str, prefix: str) -> FloatArray:
    pose = _vector(table, key, prefix, 7)
    norm = float(np.linalg.norm(pose[3:]))
    if abs(norm - 1.0) > 1e-3:
        raise ScenarioError(
            f"{prefix}.{key} quaternion (XYZW) must have unit norm, got norm {norm:.6g}"
        )
    pose[3:] /= norm
    return pose


def _shape_fields(table: Mapping[str, Any], prefix: str, base_dir: Path) -> dict[str, Any]:
    from dexplan.objects import shape_from_dict

    shape = dict(table)
    shape.pop("pose_xyzquat", None)
    shape.pop("name", None)
    try:
        shape_from_dict(shape, base_dir)
    except DexplanError as exc:
        raise ScenarioError(f"{prefix}: {exc}") from exc
    return shape


# ---------------------------------------------------------------------- loading
def parse_scenario(doc: Mapping[str, Any], base_dir: Path, name: str = "scenario") -> Scenario:
    """Validate a parsed TOML document and build a :class:`Scenario`.

    Raises:
        ScenarioError: a missing, malformed or unknown field.
    """
    _only(
        doc,
        "scenario",
        {"name", "hand", "object", "contact", "obstacles", "start", "goal", "planner", "workspace"},
    )
    scen_name = doc.get("name", name)
    if not isinstance(scen_name, str):
        raise ScenarioError(f"name must be a string, got {scen_name!r}")

    h = _table(doc, "hand", required=False) or {"builtin": "paper"}
    _only(
        h, "hand", {"builtin", "urdf", "fingertip_frames", "fingertip_radius", "collision_exclude"}
    )
    if "urdf" in h:
        frames = h.get("fingertip_frames")
        if not isinstance(frames, list) or not all(isinstance(f, str) for f in frames):
            raise ScenarioError(f"hand.fingertip_frames must be a list of names, got {frames!r}")
        urdf = (base_dir / str(h["urdf"])).resolve()
        if not urdf.is_file():
            raise ScenarioError(f"hand.urdf file not found: {str(urdf)!r}")
        excl = h.get("collision_exclude", [])
        if not isinstance(excl, list) or not all(
            isinstance(p, list) and len(p) == 2 and all(isinstance(x, str) for x in p) for p in excl
        ):
            raise ScenarioError(
                f"hand.collision_exclude must be a list of [link, link] pairs, got {excl!r}"
            )
        hand = HandSpec(
            builtin=None,
            urdf=urdf,
            fingertip_frames=tuple(frames),
            fingertip_radius=_number(h, "fingertip_radius", "hand", lo=0.0, lo_open=True),
            collision_exclude=tuple((a, b) for a, b in excl),
        )
    else:
        builtin = h.get("builtin", "paper")
        if builtin not in ("paper", "allegro"):
            raise ScenarioError(f"hand.builtin must be 'paper' or 'allegro', got {builtin!r}")
        hand = HandSpec(builtin=builtin)

    obj = _shape_fields(_table(doc, "object"), "object", base_dir)

    c = _table(doc, "contact", required=False)
    _only(c, "contact", {"mu", "friction_edges", "fc_margin"})
    mu = _number(c, "mu", "contact", 0.8, lo=0.0)
    edges = c.get("friction_edges", 8)
    if isinstance(edges, bool) or not isinstance(edges, int) or edges < 3:
        raise ScenarioError(f"contact.friction_edges must be an integer >= 3, got {edges!r}")
    fc_margin = _number(c, "fc_margin", "contact", 0.005, lo=0.0)

    obstacles_raw = doc.get("obstacles", [])
    if not isinstance(obstacles_raw, list):
        raise ScenarioError(f"obstacles must be an array of tables, got {obstacles_raw!r}")
    obstacles = []
    for k, ob in enumerate(obstacles_raw):
        prefix = f"obstacles[{k}]"
        if not isinstance(ob, Mapping):
            raise ScenarioError(f"{prefix} must be a table, got {ob!r}")
        shape = _shape_fields(ob, prefix, base_dir)
        shape["pose_xyzquat"] = _pose(ob, "pose_xyzquat", prefix).tolist()
        shape["name"] = str(ob.get("name", f"obstacle{k}"))
        obstacles.append(shape)

    s = _table(doc, "start")
    _only(s, "start", {"object_pose_xyzquat", "q"})
    start = StartSpec(
        _pose(s, "object_pose_xyzquat", "start"),
        _vector(s, "q", "start", None) if "q" in s else None,
    )
    g = _table(doc, "goal")
    _only(g, "goal", {"object_pose_xyzquat", "position_tol", "angle_tol"})
    goal = GoalSpec(
        _pose(g, "object_pose_xyzquat", "goal"),
        _number(g, "position_tol", "goal", 0.005, lo=0.0, lo_open=True),
        _number(g, "angle_tol", "goal", 0.05, lo=0.0, lo_open=True),
    )

    p = _table(doc, "planner", required=False)
    _only(p, "planner", {"name", "time_limit", "seed", "params", "space"})
    pname = p.get("name", "PRM")
    if not isinstance(pname, str):
        raise ScenarioError(f"planner.name must be a string, got {pname!r}")
    seed = p.get("seed", 1)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ScenarioError(f"planner.seed must be a non-negative integer, got {seed!r}")
    params = p.get("params", {})
    if not isinstance(params, Mapping):
        raise ScenarioError(f"planner.params must be a table, got {params!r}")
    space = p.get("space", "projected")
    if space not in SPACES:
        raise ScenarioError(f"planner.space must be one of {list(SPACES)}, got {space!r}")
    planner = PlannerSpec(
        name=pname,
        time_limit=_number(p, "time_limit", "planner", 30.0, lo=0.0, lo_open=True),
        seed=seed,
        params=dict(params),
        space=space,
    )

    w = _table(doc, "workspace", required=False)
    _only(w, "workspace", {"half_extent"})
    half = _vector(w, "half_extent", "workspace", 3) if "half_extent" in w else np.full(3, 0.02)
    if np.any(half < 0):
        raise ScenarioError(f"workspace.half_extent must be >= 0, got {half.tolist()}")

    return Scenario(
        name=scen_name,
        hand=hand,
        object=obj,
        mu=mu,
        friction_edges=int(edges),
        obstacles=tuple(obstacles),
        start=start,
        goal=goal,
        planner=planner,
        workspace_half_extent=half,
        fc_margin=fc_margin,
        base_dir=base_dir,
    )


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario TOML file.

    Raises:
        ScenarioError: missing file, TOML syntax error or an invalid field.
    """
    path = Path(path)
    if not path.is_file():
        raise ScenarioError(f"scenario file not found: {str(path)!r}")
    try:
        doc = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ScenarioError(f"{path}: not valid TOML: {exc}") from exc
    try:
        return parse_scenario(doc, path.resolve().parent, path.stem)
    except InvalidInputError as exc:
        raise ScenarioError(f"{path}: {exc}") from exc


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
