"""Malformed scenario files through ``dexplan plan``: exit 2, one line naming the field.

Each measured defect has its test with the exact example; a property test
mutates ``scenarios/paper_sphere.toml`` (always into a malformed scenario) and
checks the bad-input contract of :mod:`cli_contract`. Validation happens
before any model is built: :func:`no_planning` makes building one a failure.
"""

from __future__ import annotations

import math
import re
import tomllib
from pathlib import Path
from typing import Any

import pytest
from cli_contract import assert_bad_input, run_cli
from hypothesis import given, settings
from hypothesis import strategies as st

from dexplan.core.errors import ScenarioError
from dexplan.model.grasp import MAX_FRICTION_EDGES, MIN_FRICTION_EDGES
from dexplan.model.objects import SHAPE_KINDS
from dexplan.model.scenario import (
    MAX_HALF_EXTENT,
    MAX_JOINTS,
    MAX_POSITION,
    MAX_SCENARIO_BYTES,
    MAX_TIME_LIMIT,
    SEED_LIMIT,
    load_scenario,
)

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "paper_sphere.toml"
PAPER_TEXT = PAPER.read_text()
BASE: dict[str, Any] = tomllib.loads(PAPER_TEXT)


# ------------------------------------------------------------------ a tiny TOML writer
class Raw(str):
    """TOML text written as it is (a 5000-digit integer, 20000 nested arrays, a date)."""


_BARE = re.compile(r"[A-Za-z0-9_-]+")


def _toml_str(s: str) -> str:
    out = []
    for ch in s:
        if ch in '"\\':
            out.append("\\" + ch)
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _toml_key(k: str) -> str:
    return k if _BARE.fullmatch(k) else _toml_str(k)


def _toml_value(v: Any) -> str:
    if isinstance(v, Raw):
        return str(v)
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return _toml_str(v)
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_toml_key(k)} = {_toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(v)


def dumps(doc: dict[str, Any]) -> str:
    """TOML for a scenario-like document: scalars, then ``[tables]`` and ``[[arrays]]``."""
    head, tables = [], []
    for k, v in doc.items():
        if isinstance(v, dict) and not isinstance(v, Raw):
            tables.append((f"[{_toml_key(k)}]", [v]))
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            tables.append((f"[[{_toml_key(k)}]]", v))
        else:
            head.append(f"{_toml_key(k)} = {_toml_value(v)}")
    lines = head
    for header, items in tables:
        for item in items:
            lines.append(header)
            lines.extend(f"{_toml_key(k)} = {_toml_value(x)}" for k, x in item.items())
    return "\n".join(lines) + "\n"


def test_toml_writer_round_trips() -> None:
    assert tomllib.loads(dumps(BASE)) == BASE
    odd = {"a\nb": [1.5, -2, True, 'x"\\\t'], "t": {"p": {"q": [[1], []]}, "n": float("inf")}}
    assert tomllib.loads(dumps(odd)) == odd


# ------------------------------------------------------------------------ helpers
@pytest.fixture
def no_planning(monkeypatch: pytest.MonkeyPatch) -> None:
    """Building a model or planning fails loudly: bad input must be caught before."""
    import dexplan.planning.context as context
    import dexplan.planning.planner as planner

    def refuse(*_a: object, **_k: object) -> None:
        raise AssertionError("a malformed scenario reached model building")

    monkeypatch.setattr(context, "build_context", refuse)
    monkeypatch.setattr(context, "build_hand", refuse)
    monkeypatch.setattr(planner, "plan", refuse)


def _plan_text(capfd, tmp_path: Path, text: str | bytes, names: list[str]) -> str:
    path = tmp_path / "s.toml"
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text)
    out = tmp_path / "p.json"
    code, _, err = run_cli(capfd, "plan", str(path), "-o", str(out))
    return assert_bad_input(code, err, names=names, outputs=[out])


def _edit(old: str, new: str) -> str:
    assert old in PAPER_TEXT, old
    return PAPER_TEXT.replace(old, new, 1)


def _line(text: str) -> int:
    return PAPER_TEXT[: PAPER_TEXT.index(text)].count("\n") + 1


POSE = "object_pose_xyzquat = [0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0]"
GOAL = "object_pose_xyzquat = [0.0, 0.0, 0.1, 0.0, 0.0, 1.0, 0.0]"
TABLE = "pose_xyzquat = [0.0, 0.0, -0.02, 0.0, 0.0, 0.0, 1.0]"


# ------------------------------------------------------------- unknown fields
@pytest.mark.usefixtures("no_planning")
def test_radiuss_is_an_unknown_field_with_a_hint(capfd, tmp_path: Path) -> None:
    line = _plan_text(
        capfd, tmp_path, _edit("radius = 0.04", "radiuss = 0.05"), ["object.radiuss", "radius"]
    )
    assert "did you mean 'radius'?" in line and "0.05" in line


@pytest.mark.usefixtures("no_planning")
def test_raduis_is_not_reported_as_radius_missing(capfd, tmp_path: Path) -> None:
    line = _plan_text(
        capfd, tmp_path, _edit("radius = 0.04", "raduis = 0.04"), ["object.raduis", "'radius'"]
    )
    assert "missing" not in line


OBSTACLE = 'shape = "box"\nsize = [0.3, 0.3, 0.01]\n' + TABLE


@pytest.mark.usefixtures("no_planning")
@pytest.mark.parametrize(
    ("old", "new", "names"),
    [
        ('name = "paper_sphere"', 'name = "p"\nnmae = "q"', ["nmae", "'name'"]),
        ("[hand]", "[hand]\nbuiltn = 'paper'", ["hand.builtn", "'builtin'"]),
        ("[hand]", "[hand]\nfingertip_radius = 0.01", ["hand.fingertip_radius", "hand.urdf"]),
        ("friction_edges = 8", "friction_edge = 8", ["contact.friction_edge", "'friction_edges'"]),
        ("[start]", "[start]\nqq = [0.0]", ["start.qq"]),
        ("position_tol = 0.005", "position_tolerance = 0.005", ["goal.position_tolerance"]),
        ("seed = 1", "seed = 1\ntimelimit = 3.0", ["planner.timelimit", "'time_limit'"]),
        ("seed = 1", "seed = 1\n[workspace]\nhalf_extents = [0.1, 0.1, 0.1]", ["half_extents"]),
        ("seed = 1", "seed = 1\n[plannr]\nname = 'PRM'", ["plannr", "'planner'"]),
        (TABLE, TABLE + "\nnmae = 'table'", ["obstacles[0].nmae", "'name'"]),
        (TABLE, TABLE + "\nsizee = [1.0, 1.0, 1.0]", ["obstacles[0].sizee", "'size'"]),
        (TABLE, "pose_xyzquatt = [0.0, 0.0, -0.02, 0.0, 0.0, 0.0, 1.0]", ["pose_xyzquatt"]),
        (TABLE, TABLE + "\nradius = 0.1", ["obstacles[0].radius", "name, pose_xyzquat, shape"]),
        (OBSTACLE, "shape = 'sphere'\nradius = 0.1\nsize = [1.0]\n" + TABLE, ["[0].size"]),
        (
            OBSTACLE,
            "shape = 'cylinder'\nradius = 0.1\nlenght = 0.1\n" + TABLE,
            ["obstacles[0].lenght", "'length'"],
        ),
        (OBSTACLE, "shape = 'capsule'\nradius = 0.1\nlength = 0.1\nradiu = 2\n" + TABLE, ["radiu"]),
        ('shape = "sphere"\nradius = 0.04', "shap = 'sphere'\nradius = 0.04", ["object.shap"]),
        (
            'shape = "sphere"\nradius = 0.04',
            "shape = 'box'\nsize = [0.1, 0.1, 0.1]\nrad = 1",
            ["rad"],
        ),
        ("radius = 0.04", 'radius = 0.04\n"a\\nb" = 1', ["'a\\nb'"]),
    ],
)
def test_unknown_fields_in_every_table(capfd, tmp_path: Path, old, new, names) -> None:
    line = _plan_text(capfd, tmp_path, _edit(old, new), names)
    assert "unknown field" in line or "only used with" in line


def test_unknown_mesh_field(capfd, tmp_path: Path) -> None:
    from dexplan.model.objects import BUILTIN_MESH_DIR

    mesh = "shape = 'mesh'\npath = '%s'\nscale = 0.5\nsha = 'ab'" % (BUILTIN_MESH_DIR / "cup.obj")
    _plan_text(capfd, tmp_path, _edit('shape = "sphere"\nradius = 0.04', mesh), ["object.sha"])


# ---------------------------------------------------------------- TOML itself
@pytest.mark.usefixtures("no_planning")
def test_deeply_nested_arrays(capfd, tmp_path: Path) -> None:
    deep = "[" * 100_000 + "]" * 100_000
    line = _plan_text(capfd, tmp_path, _edit("radius = 0.04", f"radius = {deep}"), ["nested"])
    assert f"nested too deeply (line {_line('radius = 0.04')})" in line


@pytest.mark.usefixtures("no_planning")
@pytest.mark.parametrize(
    ("text", "names"),
    [
        (
            _edit("seed = 1", "seed = " + "7" * 5000),
            [f"too many digits (line {_line('seed = 1')})"],
        ),
        (PAPER_TEXT.encode("utf-8") + b"\n# \xff\xfe\n", ["not UTF-8"]),
        ("name = [unclosed", ["not valid TOML"]),
        ("x" * (MAX_SCENARIO_BYTES + 1), [str(MAX_SCENARIO_BYTES)]),
    ],
)
def test_bad_toml_files(capfd, tmp_path: Path, text, names) -> None:
    _plan_text(capfd, tmp_path, text, names)


def test_missing_scenario_file_names_shortened(capfd, tmp_path: Path) -> None:
    long = tmp_path / ("n" * 300 + ".toml")
    out = tmp_path / "p.json"
    code, _, err = run_cli(capfd, "plan", str(long), "-o", str(out))
    assert_bad_input(code, err, names=["scenario file"], outputs=[out])


# ---------------------------------------------------------------------- limits
@pytest.mark.usefixtures("no_planning")
@pytest.mark.parametrize(
    "value",
    [2**62, 100_000, MAX_FRICTION_EDGES + 1, MIN_FRICTION_EDGES - 1, "8", 8.0, "true"],
)
def test_friction_edges_bounded(capfd, tmp_path: Path, value) -> None:
    text = _edit("friction_edges = 8", f"friction_edges = {_toml_value(value)}")
    line = _plan_text(capfd, tmp_path, text, ["contact.friction_edges", "[3, 64]"])
    if isinstance(value, int):
        assert str(value) in line


@pytest.mark.usefixtures("no_planning")
@pytest.mark.parametrize(
    ("old", "new", "names"),
    [
        (GOAL, GOAL.replace("[0.0,", "[1e300,"), ["goal.object_pose_xyzquat", "1e+300"]),
        (POSE, POSE.replace("0.1,", "10.5,"), ["start.object_pose_xyzquat", "10.5"]),
        (TABLE, TABLE.replace("-0.02", "-1e30"), ["obstacles[0].pose_xyzquat", "-1e+30"]),
        (GOAL, GOAL.replace("1.0, 0.0]", "0.0, 0.0]"), ["goal.object_pose_xyzquat", "norm 0"]),
        ("seed = 1", "seed = 1\n[workspace]\nhalf_extent = [1e308, 0.1, 0.1]", ["half_extent"]),
        ("seed = 1", "seed = 1\n[workspace]\nhalf_extent = [1.5, 0.1, 0.1]", ["1.5"]),
        ("seed = 1", "seed = 1\n[workspace]\nhalf_extent = [-0.1, 0.1, 0.1]", ["half_extent"]),
        ("position_tol = 0.005", "position_tol = 0.0", ["goal.position_tol", "0.0"]),
        ("position_tol = 0.005", "position_tol = nan", ["goal.position_tol", "nan"]),
        ("position_tol = 0.005", "position_tol = 1e300", ["goal.position_tol", "1e+300"]),
        ("angle_tol = 0.05", "angle_tol = 4.0", ["goal.angle_tol", "4.0"]),
        ("angle_tol = 0.05", "angle_tol = -inf", ["goal.angle_tol", "-inf"]),
        ("time_limit = 30.0", "time_limit = 1e300", ["planner.time_limit", "1e+300"]),
        ("time_limit = 30.0", f"time_limit = {MAX_TIME_LIMIT + 1}", ["planner.time_limit"]),
        ("seed = 1", f"seed = {SEED_LIMIT}", ["planner.seed", str(SEED_LIMIT)]),
        ("seed = 1", "seed = -1", ["planner.seed", "-1"]),
        ("seed = 1", "seed = 1.5", ["planner.seed", "1.5"]),
        ("mu = 0.8", "mu = 1e300", ["contact.mu", "1e+300"]),
        ("mu = 0.8", "mu = 0.8\nfc_margin = 5.0", ["contact.fc_margin", "5.0"]),
        ("mu = 0.8", "mu = 0.8\nhold_effort_share = 0.0", ["contact.hold_effort_share", "0.0"]),
        ("mu = 0.8", "mu = 0.8\nhold_effort_share = 1.2", ["contact.hold_effort_share", "1.2"]),
        ("radius = 0.04", "radius = 3.0", ["object.radius", "3.0"]),
        ("radius = 0.04", "radius = 1e400", ["object.radius", "inf"]),
        ("radius = 0.04", "radius = " + "9" * 400, ["object.radius", "999"]),
        ("size = [0.3, 0.3, 0.01]", "size = [0.3, 1e300, 0.01]", ["obstacles[0].size", "1e+300"]),
        ('shape = "sphere"\nradius = 0.04', "shape = 'box'\nsize = [1, 3, 1]", ["object.size"]),
        (
            POSE,
            POSE + f"\nq = {[0.0] * (MAX_JOINTS + 1)}",
            ["start.q", f"{MAX_JOINTS + 1} entries"],
        ),
        (POSE, POSE + "\nq = [0.0, nan]", ["start.q", "nan"]),
        (POSE, POSE + "\nq = []", ["start.q", "0 entries"]),
        (POSE, POSE + "\nq = [0.0, 1e300]", ["start.q", "1e+300"]),
        ('name = "PRM"', 'name = ""', ["planner.name", "''"]),
        ('name = "PRM"', "name = 3", ["planner.name", "3"]),
        ('name = "PRM"', 'name = "PRM\\n"', ["planner.name", "'PRM\\n'"]),
        ("seed = 1", "seed = 1\nparams = { range = [0.1] }", ["planner.params.range", "[0.1]"]),
        ("seed = 1", "seed = 1\nparams = { range = nan }", ["planner.params.range", "nan"]),
        ("seed = 1", "seed = 1\nparams = { range = { a = 1 } }", ["planner.params.range"]),
        ("seed = 1", "seed = 1\nparams = 3", ["planner.params", "3"]),
        ("seed = 1", "seed = 1\nspace = 'curved'", ["planner.space", "'curved'"]),
        ('name = "paper_sphere"', 'name = ""', ["name", "''"]),
        (TABLE, TABLE + "\nname = 3", ["obstacles[0].name", "3"]),
    ],
)
def test_limits(capfd, tmp_path: Path, old: str, new: str, names: list[str]) -> None:
    _plan_text(capfd, tmp_path, _edit(old, new), names)


def test_limits_accept_their_bounds(tmp_path: Path) -> None:
    text = _edit("seed = 1", f"seed = {SEED_LIMIT - 1}\n[workspace]\nhalf_extent = [1.0, 0, 1]")
    text = text.replace("friction_edges = 8", f"friction_edges = {MAX_FRICTION_EDGES}")
    text = text.replace("0.0, 0.0, 0.1, 0.0, 0.0, 1.0", f"{MAX_POSITION}, 0.0, 0.1, 0.0, 0.0, 1.0")
    (tmp_path / "s.toml").write_text(text)
    s = load_scenario(tmp_path / "s.toml")
    assert s.planner.seed == SEED_LIMIT - 1 and s.friction_edges == MAX_FRICTION_EDGES
    assert s.workspace_half_extent.tolist() == [MAX_HALF_EXTENT, 0.0, 1.0]


# ------------------------------------------------------------------------ URDF
URDF_HAND = """[hand]
urdf = "hand.urdf"
fingertip_frames = ["tip"]
fingertip_radius = 0.01
"""


@pytest.mark.usefixtures("no_planning")
@pytest.mark.parametrize(
    ("content", "names"),
    [
        (b"\x89PNG\r\n\x1a\n\x00\x00\xff\xfe binary", ["hand.urdf", "not UTF-8"]),
        ("<robot name='h\u00e9'/>".encode("latin-1"), ["hand.urdf", "not UTF-8"]),
        (b"<robot name='h'>\x00</robot>", ["hand.urdf", "NUL"]),
    ],
)
def test_binary_or_non_utf8_urdf(capfd, tmp_path: Path, content: bytes, names) -> None:
    (tmp_path / "hand.urdf").write_bytes(content)
    _plan_text(capfd, tmp_path, _edit('[hand]\nbuiltin = "paper"\n', URDF_HAND), names)


@pytest.mark.usefixtures("no_planning")
@pytest.mark.parametrize(
    ("urdf", "names"),
    [
        ('"missing.urdf"', ["hand.urdf", "not found", "missing.urdf"]),
        ('"."', ["hand.urdf", "not found"]),
        ('"a\\u0000b.urdf"', ["hand.urdf", "NUL"]),
        ("3", ["hand.urdf", "3"]),
        ('""', ["hand.urdf", "''"]),
        ('"' + "d/" * 3000 + 'x.urdf"', ["hand.urdf"]),
        ('"' + "n" * 3000 + '.urdf"', ["hand.urdf"]),
    ],
)
def test_bad_urdf_names(capfd, tmp_path: Path, urdf: str, names) -> None:
    text = _edit('[hand]\nbuiltin = "paper"\n', URDF_HAND.replace('"hand.urdf"', urdf))
    _plan_text(capfd, tmp_path, text, names)


@pytest.mark.usefixtures("no_planning")
@pytest.mark.parametrize(
    ("extra", "names"),
    [
        ("fingertip_frames = 'tip'", ["hand.fingertip_frames"]),
        ("fingertip_frames = []", ["hand.fingertip_frames"]),
        ("fingertip_radius = 0.0", ["hand.fingertip_radius"]),
        ("fingertip_radius = 1e300", ["hand.fingertip_radius"]),
        ("collision_exclude = [['a']]", ["hand.collision_exclude"]),
        ("builtin = 'paper'", ["hand.builtin", "hand.urdf"]),
    ],
)
def test_bad_urdf_hand_fields(capfd, tmp_path: Path, extra: str, names) -> None:
    (tmp_path / "hand.urdf").write_text("<robot name='h'/>")
    key = extra.split(" = ")[0]
    lines = [ln for ln in URDF_HAND.splitlines() if not ln.startswith(key)]
    hand = "\n".join([*lines, extra]) + "\n"
    _plan_text(capfd, tmp_path, _edit('[hand]\nbuiltin = "paper"\n', hand), names)


# ------------------------------------------------------------------ wrong types
@pytest.mark.usefixtures("no_planning")
@pytest.mark.parametrize(
    ("doc_edit", "names"),
    [
        ({"object": "sphere"}, ["object must be a table", "'sphere'"]),
        ({"start": 3}, ["start must be a table", "3"]),
        ({"obstacles": "x"}, ["obstacles must be an array of tables", "'x'"]),
        ({"goal": []}, ["goal must be a table", "[]"]),
        ({"hand": 3}, ["hand must be a table"]),
        ({"contact": [1]}, ["contact must be a table"]),
        ({"planner": "PRM"}, ["planner must be a table"]),
        ({"obstacles": [3]}, ["obstacles[0] must be a table", "3"]),
        ({"obstacles": {"shape": "box"}}, ["obstacles must be an array of tables"]),
        ({"name": 3}, ["name must be a non-empty string", "3"]),
        ({"obstacles": [{}] * 300}, ["obstacles has 300 entries"]),
    ],
)
def test_wrong_types_name_the_field(capfd, tmp_path: Path, doc_edit: dict, names) -> None:
    _plan_text(capfd, tmp_path, dumps({**BASE, **doc_edit}), names)


def test_library_raises_scenario_error(tmp_path: Path) -> None:
    (tmp_path / "s.toml").write_text(_edit("radius = 0.04", "radiuss = 0.05"))
    with pytest.raises(ScenarioError, match=r"unknown field object\.radiuss"):
        load_scenario(tmp_path / "s.toml")


# -------------------------------------------------------------- property test
def _deep(depth: int) -> Any:
    """``depth`` nested arrays: a Python list when TOML parses it, else raw text."""
    if depth > 100:
        return Raw("[" * depth + "1" + "]" * depth)
    v: Any = 1
    for _ in range(depth):
        v = [v]
    return v


NESTED = st.sampled_from([2, 40, 20_000]).map(_deep)
HUGE = st.sampled_from([2**62, 10**30, -(10**30), 10**4000, Raw("9" * 5000)])
NON_FINITE = st.sampled_from([math.nan, math.inf, -math.inf, 1e300, -1e300, 1e308])
WRONG_TYPE = st.sampled_from(["x", "", True, False, [], [1.0], {}, {"a": 1}, Raw("1979-05-27")])

NUM_BAD = st.one_of(WRONG_TYPE, NON_FINITE, HUGE, NESTED, st.just(-1))
STR_BAD = st.one_of(
    st.sampled_from([3, 1.5, math.nan, True, [], ["paper"], {}, "", "x" * 300, "a\tb"]), NESTED
)
FIELD_BAD: dict[str, st.SearchStrategy[Any]] = {
    "contact.friction_edges": st.sampled_from([2, 65, 100_000, 3.0, 8.5]),
    "planner.seed": st.sampled_from([SEED_LIMIT, 2**40, 1.5, 1.0]),
    "goal.position_tol": st.sampled_from([0, 0.0, 2.0]),
    "goal.angle_tol": st.sampled_from([0, 0.0, 4.0]),
    "planner.time_limit": st.sampled_from([0, 0.0, MAX_TIME_LIMIT + 1, 1e6]),
    "contact.mu": st.sampled_from([10.5, 100]),
    "object.radius": st.sampled_from([0, 0.0, 2.5, 1e3]),
    "hand.builtin": st.sampled_from(["shadow", "Paper"]),
    "object.shape": st.sampled_from(["torus", "Sphere", "box", "mesh"]),
    "obstacles[0].shape": st.sampled_from(["torus", "sphere", "cylinder", "mesh"]),
    "planner.name": st.sampled_from(["", "\n"]),
    "name": st.sampled_from(["", "a\nb"]),
}

LEAVES: dict[tuple, str] = {  # path -> kind
    ("name",): "str",
    ("hand", "builtin"): "str",
    ("object", "shape"): "str",
    ("object", "radius"): "num",
    ("contact", "mu"): "num",
    ("contact", "friction_edges"): "num",
    ("obstacles", 0, "shape"): "str",
    ("obstacles", 0, "size"): "vec",
    ("obstacles", 0, "pose_xyzquat"): "pose",
    ("start", "object_pose_xyzquat"): "pose",
    ("goal", "object_pose_xyzquat"): "pose",
    ("goal", "position_tol"): "num",
    ("goal", "angle_tol"): "num",
    ("planner", "name"): "str",
    ("planner", "time_limit"): "num",
    ("planner", "seed"): "num",
}
OPTIONAL: dict[tuple, st.SearchStrategy[Any]] = {  # fields absent from the file, bad values
    ("contact", "fc_margin"): st.one_of(NUM_BAD, st.just(1.5)),
    ("planner", "space"): st.one_of(STR_BAD, st.just("curved")),
    ("planner", "params"): st.one_of(
        st.sampled_from([3, "x", [], {"range": [1]}, {"range": math.nan}, {"": 1}]),
        st.builds(lambda v: {"range": v}, st.one_of(NESTED, HUGE, st.just({"a": 1}))),
    ),
    ("start", "q"): st.one_of(
        st.sampled_from(["x", 3, [], [0.0] * (MAX_JOINTS + 1), [[0.0]]]),
        st.builds(lambda v: [0.0, v], st.one_of(WRONG_TYPE, NON_FINITE, HUGE, NESTED)),
    ),
    ("workspace", "half_extent"): st.one_of(
        st.sampled_from([[0.1, 0.1], [1.5, 0.1, 0.1], [-0.1, 0.1, 0.1], "x"]),
        st.builds(lambda v: [0.1, v, 0.1], st.one_of(WRONG_TYPE, NON_FINITE, HUGE, NESTED)),
    ),
    ("obstacles", 0, "name"): STR_BAD,
}
REQUIRED = [
    ("object",),
    ("object", "shape"),
    ("object", "radius"),
    ("obstacles", 0, "shape"),
    ("obstacles", 0, "size"),
    ("obstacles", 0, "pose_xyzquat"),
    ("start",),
    ("start", "object_pose_xyzquat"),
    ("goal",),
    ("goal", "object_pose_xyzquat"),
]
TABLES: dict[tuple, frozenset[str]] = {  # path -> every field the table accepts
    (): frozenset(
        ["name", "hand", "object", "contact", "obstacles", "start", "goal", "planner", "workspace"]
    ),
    ("hand",): frozenset(
        ["builtin", "urdf", "fingertip_frames", "fingertip_radius", "collision_exclude"]
    ),
    ("object",): frozenset(["shape", "radius"]),
    ("contact",): frozenset(["mu", "friction_edges", "fc_margin"]),
    ("obstacles", 0): frozenset(["shape", "size", "name", "pose_xyzquat"]),
    ("start",): frozenset(["object_pose_xyzquat", "q"]),
    ("goal",): frozenset(["object_pose_xyzquat", "position_tol", "angle_tol"]),
    ("planner",): frozenset(["name", "time_limit", "seed", "params", "space"]),
}
TABLE_PATHS = [
    ("hand",),
    ("object",),
    ("contact",),
    ("obstacles",),
    ("obstacles", 0),
    ("start",),
    ("goal",),
    ("planner",),
]
SCALARS = st.sampled_from([3, "x", 1.5, True, math.nan, [1], "", Raw("1979-05-27")])


def _dotted(path: tuple) -> str:
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else p)
    return out


def _copy(v: Any) -> Any:
    if isinstance(v, dict):
        return {k: _copy(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_copy(x) for x in v]
    return v


def _container(doc: dict, path: tuple) -> Any:
    node: Any = doc
    for p in path[:-1]:
        if isinstance(p, str) and p not in node:
            node[p] = {}
        node = node[p]
    return node


def _get(doc: dict, path: tuple) -> Any:
    node: Any = doc
    for p in path:
        node = node[p]
    return node


def _names_for(value: Any, field: str) -> list[str]:
    """What the error must contain: the field, unless TOML itself cannot parse the value."""
    if isinstance(value, Raw) and value.startswith("[" * 100):
        return ["nested too deeply"]
    if isinstance(value, Raw) and value.startswith("9" * 4500):
        return ["too many digits"]
    if isinstance(value, list | dict):  # a deep list inside a value
        text = _toml_value(value)
        if "[" * 100 in text:
            return ["nested too deeply"]
        if "9" * 4500 in text:
            return ["too many digits"]
    return [field]


def _near_miss(draw: st.DrawFn, key: str, allowed: frozenset[str]) -> str:
    op = draw(st.sampled_from(["delete", "double", "swap", "replace", "append", "upper"]))
    i = draw(st.integers(0, len(key) - 1))
    c = draw(st.sampled_from("abcdefghijklmnopqrstuvwxyz_"))
    new = {
        "delete": key[:i] + key[i + 1 :],
        "double": key[:i] + key[i] + key[i:],
        "swap": key[:i] + key[i + 1 : i + 2] + key[i] + key[i + 2 :],
        "replace": key[:i] + c + key[i + 1 :],
        "append": key + c,
        "upper": key[:i] + key[i].upper() + key[i + 1 :],
    }[op]
    return new if new and new not in allowed else key + "_x"


@st.composite
def malformed_scenario(draw: st.DrawFn) -> tuple[str, list[str]]:
    """(TOML text of a malformed paper_sphere scenario, strings its error must contain)."""
    doc = _copy(BASE)
    kind = draw(st.sampled_from(["drop", "unknown", "leaf", "element", "optional", "table"]))
    if kind == "drop":
        path = draw(st.sampled_from(REQUIRED))
        del _container(doc, path)[path[-1]]
        return dumps(doc), [_dotted(path)]
    if kind == "unknown":
        path = draw(st.sampled_from(sorted(TABLES, key=str)))
        table = _get(doc, path)
        source = draw(st.sampled_from(sorted(table)))
        key = _near_miss(draw, source, TABLES[path])
        table[key] = _copy(table[source])
        return dumps(doc), [_dotted((*path, key))]
    if kind == "leaf":
        path = draw(st.sampled_from(sorted(LEAVES, key=str)))
        leaf = LEAVES[path]
        bad = {"num": NUM_BAD, "str": STR_BAD}.get(leaf, st.one_of(WRONG_TYPE, NON_FINITE, HUGE))
        field = _dotted(path)
        if field in FIELD_BAD:
            bad = st.one_of(bad, FIELD_BAD[field])
        if leaf in ("vec", "pose"):
            n = 3 if leaf == "vec" else 7
            bad = st.one_of(bad, NESTED, st.sampled_from([[1.0] * (n - 1), [1.0] * (n + 1)]))
            bad = st.one_of(bad, st.sampled_from([["x"] * n, [[1.0]] * n, [True] * n]))
        value = draw(bad)
        _container(doc, path)[path[-1]] = value
        if path[-1] == "shape" and value in SHAPE_KINDS:  # the other fields are then wrong
            field = _dotted(path[:-1]) + "."
        return dumps(doc), _names_for(value, field)
    if kind == "element":
        path = draw(st.sampled_from([p for p, k in LEAVES.items() if k in ("vec", "pose")]))
        vec = _container(doc, path)[path[-1]]
        i = draw(st.integers(0, len(vec) - 1))
        extra = [-1.0, 0.0] if LEAVES[path] == "vec" else []  # sizes are > 0
        if LEAVES[path] == "pose" and i < 3:
            extra = [MAX_POSITION + 0.5, -MAX_POSITION - 0.5]
        elif LEAVES[path] == "pose":
            extra = [vec[i] + 0.5, vec[i] - 0.5]  # breaks the unit norm
        value = draw(st.one_of(WRONG_TYPE, NON_FINITE, HUGE, NESTED, st.sampled_from(extra)))
        vec[i] = value
        return dumps(doc), _names_for(value, _dotted(path))
    if kind == "optional":
        path = draw(st.sampled_from(sorted(OPTIONAL, key=str)))
        value = draw(OPTIONAL[path])
        _container(doc, path)[path[-1]] = value
        return dumps(doc), _names_for(value, _dotted(path))
    path = draw(st.sampled_from(TABLE_PATHS))
    empty = st.just([]) if path != ("obstacles",) else SCALARS  # no obstacles is valid
    value = draw(st.one_of(SCALARS, NESTED, empty))
    _container(doc, path)[path[-1]] = value
    return dumps(doc), _names_for(value, _dotted(path))


def _check(capfd, tmp_path: Path, case: tuple[str, list[str]]) -> None:
    text, names = case
    _plan_text(capfd, tmp_path, text, names)


@pytest.mark.usefixtures("no_planning")
@given(case=malformed_scenario())
def test_mutated_scenarios_are_bad_input(capfd, tmp_path: Path, case) -> None:
    _check(capfd, tmp_path, case)


@pytest.mark.slow
@pytest.mark.usefixtures("no_planning")
@settings(max_examples=2000)
@given(case=malformed_scenario())
def test_mutated_scenarios_are_bad_input_thorough(capfd, tmp_path: Path, case) -> None:
    _check(capfd, tmp_path, case)
