"""Malformed plan files: exit 2 and one line naming the field, for verify and show.

Every test goes through the command line in this process (``cli.run``) on a
file, so the whole path is covered: read (JSON, nesting, size), structure
(:mod:`dexplan.planfile.schema`), models (the URDF), rules (the verifier). The
valid plan is made by hand (no planning): a transfer turning the sphere by
0.09 rad, a regrasp of finger 0, and a transfer turning it on to 0.18 rad.
"""

from __future__ import annotations

import copy
import functools
import json
import math
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from cli_contract import assert_bad_input, run_cli
from hypothesis import event, given, settings
from hypothesis import strategies as st

from dexplan.core.pose import quat_from_axis_angle, transform_points
from dexplan.model.hand.hand import Hand
from dexplan.planfile import hand_table, read_plan, verify_plan
from dexplan.planfile import schema as plan_schema

RADIUS = 0.04
CENTER = np.array([0.0, 0.0, 0.1])
YAW_STEP = 0.03  # rad per transfer step: deleting a waypoint breaks the 0.05 rad step rule


# ------------------------------------------------------------- a valid plan
def _contact(az_deg: float, el_deg: float = -20.0) -> np.ndarray:
    az, el = math.radians(az_deg), math.radians(el_deg)
    return RADIUS * np.array(
        [math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)]
    )


def _pose(yaw: float) -> np.ndarray:
    return np.concatenate([CENTER, quat_from_axis_angle([0, 0, 1], yaw)])


def _reach(hand: Hand, q: np.ndarray, finger: int, pose: np.ndarray, p_obj: np.ndarray):
    res = hand.finger_ik(finger, transform_points(pose, p_obj[None])[0], q)
    assert res.success, (finger, res.residual)
    q = q.copy()
    q[hand.finger_q_index[finger]] = res.q_finger
    return q


def _grasp(hand: Hand, pose: np.ndarray, contacts: list, q: np.ndarray) -> np.ndarray:
    for i, c in enumerate(contacts):
        if c is not None:
            q = _reach(hand, q, i, pose, c * (1.0 + hand.fingertip_radius / RADIUS))
    return q


def _wp(pose: np.ndarray, q: np.ndarray, contacts: list) -> dict[str, Any]:
    return {
        "object_pose_xyzquat": [float(v) for v in pose],
        "q": [float(v) for v in q],
        "contacts": [None if c is None else [float(v) for v in c] for c in contacts],
    }


def _regrasp_finger0(
    hand: Hand, pose: np.ndarray, contacts: list, q: np.ndarray, start: dict[str, Any]
) -> tuple[list[dict[str, Any]], list, np.ndarray]:
    """Finger 0 lifts, moves 15 degrees round and lands (16 waypoints from ``start``).

    Returns:
        The waypoints, the contacts after landing and the last joint values.
    """
    regrasp = [start]
    free = [None, *contacts[1:]]
    for t in np.linspace(0.0, 1.0, 16)[1:-1]:  # lift finger 0, move 15 degrees round
        lift = 0.008 * math.sin(math.pi * t) + 0.001
        tip = _contact(45 + 15 * t) * (1.0 + (hand.fingertip_radius + lift) / RADIUS)
        q = _reach(hand, q, 0, pose, tip)
        regrasp.append(_wp(pose, q, free))
    landed = [_contact(60.0), *contacts[1:]]
    q = _grasp(hand, pose, [landed[0], None, None, None], q)
    regrasp.append(_wp(pose, q, landed))
    return regrasp, landed, q


def make_plan(hand: Hand) -> dict[str, Any]:
    """Transfer (4 waypoints), regrasp of finger 0 (16), transfer (4); verify passes."""
    contacts = [_contact(45 + 90 * k) for k in range(4)]
    q = hand.neutral.copy()
    first = []
    for k in range(4):
        pose = _pose(YAW_STEP * k)
        q = _grasp(hand, pose, contacts, q)
        first.append(_wp(pose, q, contacts))
    pose = _pose(3 * YAW_STEP)
    regrasp, landed, q = _regrasp_finger0(hand, pose, contacts, q, first[-1])
    second = [regrasp[-1]]
    for k in range(4, 7):
        pose = _pose(YAW_STEP * k)
        q = _grasp(hand, pose, landed, q)
        second.append(_wp(pose, q, landed))
    return _plan_document(hand, first, regrasp, second)


def _plan_document(
    hand: Hand, first: list[dict], regrasp: list[dict], second: list[dict]
) -> dict[str, Any]:
    """The plan file of the three segments (sphere, one table obstacle, tight goal)."""
    doc = {
        "format": "dexplan-plan/1",
        "scenario": "schema_test",
        "hand": hand_table(hand),
        "object": {"shape": "sphere", "radius": RADIUS},
        "mu": 0.8,
        "friction_edges": 8,
        "contact_model": "point",
        "torsion": 0.0,
        "obstacles": [
            {
                "shape": "box",
                "size": [0.3, 0.3, 0.01],
                "pose_xyzquat": [0, 0, -0.02, 0, 0, 0, 1],
                "name": "table",
            }
        ],
        "start": {"object_pose_xyzquat": first[0]["object_pose_xyzquat"], "q": first[0]["q"]},
        # tighter than the defaults (5 mm, 0.05 rad): one step short of the goal fails
        "goal": {
            "object_pose_xyzquat": second[-1]["object_pose_xyzquat"],
            "position_tol": 0.001,
            "angle_tol": 0.01,
        },
        "segments": [
            {"kind": "transfer", "finger": None, "waypoints": first},
            {"kind": "regrasp", "finger": 0, "waypoints": regrasp},
            {"kind": "transfer", "finger": None, "waypoints": second},
        ],
        "stats": {
            "planner": "by hand",
            "seed": 0,
            "time_s": 0.0,
            "validity": {"checked": 3, "rejected": {"bounds": 0}},
            "sampler": [1, 2.5, None, "x"],
        },
    }
    return json.loads(json.dumps(doc))  # no shared waypoint dicts


@functools.cache
def valid_plan() -> dict[str, Any]:
    """The valid plan, made once (hypothesis tests call this: no fixture in their reports)."""
    doc = make_plan(Hand.builtin("paper"))
    report = verify_plan(doc)
    assert report.ok, [str(v) for v in report.violations]
    return doc


@pytest.fixture(scope="module")
def base_plan() -> dict[str, Any]:
    return valid_plan()


@pytest.fixture()
def plan(base_plan: dict[str, Any]) -> dict[str, Any]:
    return copy.deepcopy(base_plan)


def write(path: Path, doc: Any) -> Path:
    """Write ``doc`` as JSON, NaN and Infinity included (as Python's json reads them)."""
    path.write_text(json.dumps(doc, allow_nan=True))
    return path


def verify(capfd, path: Path) -> tuple[int, str, str]:
    return run_cli(capfd, "verify", path)


def show(capfd, path: Path) -> tuple[int, str, str, Path]:
    out = path.with_name("out.rrd")
    code, stdout, err = run_cli(capfd, "show", path, "--save", out)
    return code, stdout, err, out


def bad(capfd, tmp_path: Path, doc: Any, *names: str, show_too: bool = True) -> str:
    """Assert both verify and show reject ``doc`` naming ``names``; return verify's line."""
    path = write(tmp_path / "plan.json", doc)
    code, _, err = verify(capfd, path)
    line = assert_bad_input(code, err, names=names)
    if show_too:
        code, _, err, out = show(capfd, path)
        assert_bad_input(code, err, names=names, outputs=[out])
    return line


# ----------------------------------------------------------- the baseline
def test_valid_plan_verifies_and_shows(capfd, tmp_path: Path, plan: dict) -> None:
    path = write(tmp_path / "plan.json", plan)
    code, out, err = verify(capfd, path)
    assert code == 0 and out.startswith("OK: 3 segments, 24 waypoints"), (out, err)
    code, _, err, rrd = show(capfd, path)
    assert code == 0 and rrd.is_file(), err


def test_planner_fields_are_accepted(capfd, tmp_path: Path, plan: dict) -> None:
    plan["contact_model"] = "soft"
    plan["torsion"] = 0.002
    plan["stats"] = {"anything": [{"nested": {"deep": [1, None, "x"]}}], "n": 1e300}
    del plan["hand"]["collision_exclude"], plan["obstacles"][0]["name"], plan["start"]["q"]
    del plan["friction_edges"], plan["scenario"]
    code, out, err = verify(capfd, write(tmp_path / "plan.json", plan))
    assert code == 0, (out, err)


# ----------------------------------------------------- the defects, one each
def test_six_entry_pose_in_a_transfer_waypoint(capfd, tmp_path: Path, plan: dict) -> None:
    plan["segments"][0]["waypoints"][3]["object_pose_xyzquat"] = [0, 0, 0.1, 0, 0, 1]
    bad(capfd, tmp_path, plan, "segments[0].waypoints[3].object_pose_xyzquat", "6 given")


def test_regrasp_last_waypoint_with_three_contacts(capfd, tmp_path: Path, plan: dict) -> None:
    seg = plan["segments"][1]
    last = len(seg["waypoints"]) - 1
    del seg["waypoints"][last]["contacts"][3]
    bad(capfd, tmp_path, plan, f"segments[1].waypoints[{last}].contacts", "3 given")


def test_no_goal_pose(capfd, tmp_path: Path, plan: dict) -> None:
    del plan["goal"]["object_pose_xyzquat"]
    bad(capfd, tmp_path, plan, "missing field goal.object_pose_xyzquat")


@pytest.mark.parametrize(
    ("key", "value"),
    [("start", [0, 0, 0.1, 0, 0, 0, 1]), ("goal", "anywhere"), ("obstacles", {"shape": "box"})],
)
def test_start_goal_obstacles_of_the_wrong_type(
    capfd, tmp_path: Path, plan: dict, key: str, value: Any
) -> None:
    plan[key] = value
    bad(capfd, tmp_path, plan, f"{key} must be a", "got ")


def test_hand_is_a_string(capfd, tmp_path: Path, plan: dict) -> None:
    plan["hand"] = "paper"
    bad(capfd, tmp_path, plan, "hand must be a table, got 'paper'")


@pytest.mark.parametrize("where", ["top", "stats"])
def test_deeply_nested_arrays(capfd, tmp_path: Path, plan: dict, where: str) -> None:
    deep = "[" * 100_000 + "]" * 100_000
    text = (
        deep
        if where == "top"
        else json.dumps(plan).replace('"stats": {', f'"stats": {{"a": {deep}, ')
    )
    path = tmp_path / "plan.json"
    path.write_text(text)
    for args in (("verify", path), ("show", path, "--save", tmp_path / "out.rrd")):
        code, _, err = run_cli(capfd, *args)
        assert_bad_input(code, err, names=["nested too deeply"], outputs=[tmp_path / "out.rrd"])


@pytest.mark.parametrize("edges", [2**62, 100_000, 2, 0, -8])
def test_friction_edges_out_of_range(capfd, tmp_path: Path, plan: dict, edges: int) -> None:
    plan["friction_edges"] = edges
    line = bad(capfd, tmp_path, plan, "friction_edges", str(edges), show_too=edges == 2**62)
    assert f"[{plan_schema.MIN_FRICTION_EDGES}, {plan_schema.MAX_FRICTION_EDGES}]" in line


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("position_tol", math.nan),
        ("angle_tol", math.nan),
        ("position_tol", math.inf),
        ("angle_tol", 0.0),
        ("position_tol", -0.001),
        ("object_pose_xyzquat", [math.nan] * 7),
        ("object_pose_xyzquat", [0, 0, 0.1, 0, 0, math.nan, 1]),
    ],
)
def test_cut_plan_with_a_non_finite_goal_is_malformed(
    capfd, tmp_path: Path, plan: dict, field: str, value: Any
) -> None:
    """These passed silently: NaN compares false, so "farther than the tolerance" never held."""
    del plan["segments"][1:]
    plan["goal"][field] = value
    bad(capfd, tmp_path, plan, f"goal.{field}", show_too=False)


def test_cut_plan_misses_the_goal(capfd, tmp_path: Path, plan: dict) -> None:
    del plan["segments"][1:]
    code, out, err = verify(capfd, write(tmp_path / "plan.json", plan))
    assert code == 1 and not err.strip(), err
    assert "segment 0, waypoint 3: goal: object ends" in out and out.rstrip().endswith("violations")


@pytest.mark.parametrize(
    ("mutate", "names"),
    [
        (lambda d: d.update(mu="0.8"), ["mu must be a finite number", "'0.8'"]),
        (lambda d: d.update(mu=True), ["mu must be a finite number", "True"]),
        (lambda d: d.update(mu=-0.1), ["mu must be >= 0"]),
        (lambda d: d.update(friction_edges=8.7), ["friction_edges must be an integer", "8.7"]),
        (lambda d: d.update(friction_edges=8.0), ["friction_edges must be an integer", "8.0"]),
        (lambda d: d.update(friction_edges=True), ["friction_edges must be an integer"]),
        (lambda d: d["segments"][1].update(finger=True), ["segments[1].finger", "True"]),
        (lambda d: d["segments"][1].update(finger=4), ["segments[1].finger", "[0, 3]"]),
        (lambda d: d["segments"][1].update(finger=None), ["segments[1].finger", "None"]),
        (lambda d: d["segments"][0].update(finger=0), ["segments[0].finger must be null"]),
        (lambda d: d["segments"][0].update(kind=1), ["segments[0].kind", "got 1"]),
        (lambda d: d["segments"][0].update(kind="twist"), ["segments[0].kind", "'twist'"]),
        (
            lambda d: d["segments"][2]["waypoints"][1]["q"].__setitem__(4, "0.1"),
            ["segments[2].waypoints[1].q[4] must be a finite number", "'0.1'"],
        ),
        (
            lambda d: d["segments"][0]["waypoints"][2]["contacts"].__setitem__(1, [0.0, 0.04]),
            ["segments[0].waypoints[2].contacts[1] must be null or 3 numbers", "2 given"],
        ),
        (
            lambda d: d["segments"][0]["waypoints"][2]["contacts"].__setitem__(1, "touch"),
            ["segments[0].waypoints[2].contacts[1]", "'touch'"],
        ),
        (
            lambda d: d["segments"][0]["waypoints"][2]["contacts"].__setitem__(1, True),
            ["segments[0].waypoints[2].contacts[1]", "True"],
        ),
        (lambda d: d.update(contact_model="rigid"), ["contact_model", "'rigid'"]),
        (lambda d: d.update(torsion=-0.001), ["torsion must be >= 0"]),
        (lambda d: d.update(torsion=math.inf), ["torsion must be a finite number"]),
        (lambda d: d.update(scenario=3), ["scenario must be a string"]),
        (lambda d: d.update(stats=[1, 2]), ["stats must be a table"]),
        (lambda d: d["hand"].update(fingertip_radius=0), ["hand.fingertip_radius must be > 0"]),
        (lambda d: d["hand"]["joint_names"].reverse(), ["hand.joint_names must be the URDF"]),
        (lambda d: d["hand"]["fingertip_frames"].__setitem__(2, "f2_pip_x"), ["hand: "]),
        (lambda d: d["obstacles"][0].pop("pose_xyzquat"), ["obstacles[0].pose_xyzquat"]),
        (lambda d: d["obstacles"][0].update(size=[0.3, 0.3]), ["obstacles[0].size"]),
        (lambda d: d["object"].update(radius="big"), ["object.radius"]),
        (
            lambda d: d.update(format="dexplan-plan/3"),
            ["format must be 'dexplan-plan/1' or 'dexplan-plan/2'"],
        ),
        (lambda d: d.update(contact_motion="rolling"), ["contact_motion needs format"]),
        (lambda d: d.update(mu=10**400), ["mu must be a finite number"]),
        (
            lambda d: d["segments"][1]["waypoints"][0].update(object_pose_xyzquat=[0] * 7),
            ["segments[1].waypoints[0].object_pose_xyzquat quaternion", "unit norm"],
        ),
        (lambda d: d["segments"][1].update(waypoints=[]), ["segments[1].waypoints", "0 given"]),
    ],
)
def test_wrong_types_and_values(
    capfd, tmp_path: Path, plan: dict, mutate: Callable[[dict], None], names: list[str]
) -> None:
    mutate(plan)
    bad(capfd, tmp_path, plan, *names, show_too=False)


@pytest.mark.parametrize(
    ("table", "key", "hint"),
    [
        ((), "friction_edge", "friction_edges"),
        (("hand",), "fingertip_radiuss", "fingertip_radius"),
        (("goal",), "angle_toll", "angle_tol"),
        (("start",), "qq", "q"),
        (("segments", 1), "fingers", "finger"),
        (("segments", 0, "waypoints", 2), "contact", "contacts"),
        (("segments", 0, "waypoints", 2), "velocity", None),
    ],
)
def test_unknown_fields_are_rejected(
    capfd, tmp_path: Path, plan: dict, table: tuple, key: str, hint: str | None
) -> None:
    node: Any = plan
    for k in table:
        node = node[k]
    node[key] = 1
    where = _dotted((*table, key))
    line = bad(capfd, tmp_path, plan, f"unknown field {where} (= 1)", show_too=False)
    assert (f"did you mean {hint!r}?" in line) == (hint is not None), line


@pytest.mark.parametrize(
    "path",
    [
        ("start", "object_pose_xyzquat", 2),
        ("start", "q", 0),
        ("segments", 0, "waypoints", 1, "object_pose_xyzquat", 0),
        ("segments", 1, "waypoints", 5, "q", 3),
        ("segments", 2, "waypoints", 2, "contacts", 1, 2),
        ("obstacles", 0, "pose_xyzquat", 2),
        ("hand", "fingertip_radius"),
    ],
)
@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_non_finite_numbers_anywhere(
    capfd, tmp_path: Path, plan: dict, path: tuple, value: float
) -> None:
    """``show --save`` recorded NaN poses and joints: it now validates as verify does."""
    _set(plan, path, value)
    bad(capfd, tmp_path, plan, _dotted(path), "must be a finite number")


def test_show_with_a_string_mu(capfd, tmp_path: Path, plan: dict) -> None:
    plan["mu"] = "high"
    bad(capfd, tmp_path, plan, "mu must be a finite number", "'high'")


def test_five_million_entry_q_gives_a_short_message(capfd, tmp_path: Path, plan: dict) -> None:
    plan["segments"][0]["waypoints"][1]["q"] = "__Q__"
    text = json.dumps(plan).replace('"__Q__"', "[" + "0.0, " * (5_000_000 - 1) + "0.0]")
    path = tmp_path / "plan.json"
    path.write_text(text)
    code, _, err = verify(capfd, path)
    line = assert_bad_input(code, err, names=["segments[0].waypoints[1].q", "5000000 given"])
    assert len(line) < 300, line


def test_size_limits(capfd, tmp_path: Path, plan: dict, monkeypatch: pytest.MonkeyPatch) -> None:
    """The limits are module constants; lowered here so the test needs no huge file."""
    path = write(tmp_path / "plan.json", plan)
    monkeypatch.setattr(plan_schema, "MAX_WAYPOINTS", 20)
    code, _, err = verify(capfd, path)
    assert_bad_input(code, err, names=["segments[2].waypoints", "over 20 waypoints"])
    monkeypatch.setattr(plan_schema, "MAX_WAYPOINTS", 10)
    code, _, err = verify(capfd, path)
    assert_bad_input(code, err, names=["segments[1].waypoints must list 1 to 10"])
    monkeypatch.undo()
    monkeypatch.setattr(plan_schema, "MAX_PLAN_BYTES", 1000)
    code, _, err = verify(capfd, path)
    assert_bad_input(code, err, names=["bytes, more than a plan may have (1000)"])
    assert plan_schema.MAX_JOINTS < 5_000_000 and plan_schema.MAX_FINGERS <= plan_schema.MAX_JOINTS


def test_huge_integer_literal_is_not_json_we_read(capfd, tmp_path: Path, plan: dict) -> None:
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(plan).replace('"mu": 0.8', '"mu": ' + "9" * 5000))
    code, _, err = verify(capfd, path)
    assert_bad_input(code, err, names=["not valid JSON", "digits"])


def test_in_memory_documents_are_validated(plan: dict) -> None:
    from dexplan.core.errors import PlanFileError

    plan["segments"][0]["waypoints"][0]["q"][0] = math.nan
    with pytest.raises(PlanFileError, match=r"segments\[0\]\.waypoints\[0\]\.q\[0\]"):
        verify_plan(plan)
    with pytest.raises(PlanFileError, match="must be a JSON object"):
        verify_plan([])  # type: ignore[arg-type]


def test_read_plan_returns_the_document(tmp_path: Path, plan: dict) -> None:
    assert read_plan(write(tmp_path / "p.json", plan)) == plan


# ------------------------------------------------------ mutation property
# A site is a path into the document; each mutation is classified before it
# runs: MALFORMED (exit 2, the line names the site or the list holding it),
# RULE (exit 1: still well formed, breaks a rule), HARMLESS (exit 0), or
# RULE_OR_HARMLESS (an interior regrasp waypoint dropped: steps may still fit).
MALFORMED, RULE, HARMLESS, RULE_OR_HARMLESS = "malformed", "rule", "harmless", "rule_or_harmless"

#: Values no field of the format accepts (stats aside): wrong types, non-finite,
#: huge, nested, long.
BAD_VALUES: list[Any] = [
    "x",
    "",
    True,
    False,
    {"a": 1},
    [],
    [[[[[[[[[[1.0]]]]]]]]]],
    math.nan,
    math.inf,
    -math.inf,
    10**30,
    -(2**62),
    1e300,
    [0.0] * 5000,
]
UNKNOWN_KEYS = ["extra", "contact", "Q", "kind_", "q_"]

#: Optional fields: deleting one leaves the plan as good as before.
OPTIONAL = {
    ("scenario",),
    ("friction_edges",),
    ("contact_model",),
    ("torsion",),
    ("obstacles",),
    ("stats",),
    ("hand", "collision_exclude"),
    ("start", "q"),
    ("goal", "position_tol"),
    ("goal", "angle_tol"),
    ("obstacles", 0, "name"),
}


def _dotted(path: tuple) -> str:
    out = ""
    for k in path:
        out += f"[{k}]" if isinstance(k, int) else (f".{k}" if out else str(k))
    return out


def _get(doc: Any, path: tuple) -> Any:
    for k in path:
        doc = doc[k]
    return doc


def _set(doc: Any, path: tuple, value: Any) -> None:
    _get(doc, path[:-1])[path[-1]] = value


def _sites(node: Any, path: tuple = ()) -> Iterator[tuple]:
    yield path
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _sites(v, (*path, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _sites(v, (*path, i))


def _in_stats(path: tuple) -> bool:
    return len(path) > 1 and path[0] == "stats"


def _is_waypoints(path: tuple) -> bool:
    return len(path) == 3 and path[0] == "segments" and path[2] == "waypoints"


def _drop_from_list(doc: dict, path: tuple, index: int) -> str:
    """Class of deleting entry ``index`` of the list at ``path``."""
    if _in_stats((*path, index)) or path == ("obstacles",):
        return HARMLESS
    if path == ("segments",):
        return RULE  # start, continuity or goal
    if _is_waypoints(path):
        wps = _get(doc, path)
        if len(wps) == 1:
            return MALFORMED
        kind = doc["segments"][path[1]]["kind"]
        ends = index in (0, len(wps) - 1)
        return RULE if ends or kind == "transfer" else RULE_OR_HARMLESS
    return MALFORMED  # fixed-length lists: poses, q, contacts, sizes, joints, fingers


def classify(doc: dict, op: str, path: tuple, arg: Any) -> str:
    """What mutating ``doc`` at ``path`` must give, decided before running it."""
    parent = _get(doc, path[:-1]) if path else None
    if op == "delete":
        if isinstance(parent, list):
            return _drop_from_list(doc, path[:-1], path[-1])
        if _in_stats(path) or path in OPTIONAL:
            return HARMLESS
        return MALFORMED
    if op == "truncate":  # keep the first ``arg`` entries
        node = _get(doc, path)
        if _in_stats((*path, 0)) or path in {("obstacles",), ("hand", "collision_exclude")}:
            return HARMLESS
        if path == ("segments",):
            return RULE  # no segments, or the goal is not reached
        if _is_waypoints(path):
            # the last waypoint goes: continuity breaks, or the goal is a step away
            return MALFORMED if arg == 0 else RULE
        return HARMLESS if arg == len(node) else MALFORMED
    if op == "add_key":
        return HARMLESS if _in_stats((*path, "x")) else MALFORMED
    # replace
    if _in_stats(path) or (path == ("stats",) and isinstance(arg, dict)):
        return HARMLESS
    if arg == []:
        if path == ("segments",):
            return RULE  # "the plan has no segments"
        if path in {("obstacles",), ("hand", "collision_exclude")}:
            return HARMLESS
    if isinstance(arg, str) and arg and path in {("scenario",), ("obstacles", 0, "name")}:
        return HARMLESS
    if arg is None:
        if path == ("start", "q"):
            return HARMLESS
        if len(path) == 6 and path[4] == "contacts":
            return HARMLESS if _get(doc, path) is None else RULE
        if (
            len(path) == 3
            and path[2] == "finger"
            and doc["segments"][path[1]]["kind"] == "transfer"
        ):
            return HARMLESS
    if arg == "" and path == ("scenario",):
        return HARMLESS
    return MALFORMED


def _named(line: str, op: str, path: tuple, arg: Any) -> bool:
    """The line names the site, or the list or table holding it (the hand for its models)."""
    if op == "add_key":
        return f"unknown field {_dotted((*path, arg))} " in line
    if path and path[0] == "hand" and "hand" in line:
        return True  # joint names and frames are judged against the URDF: "hand..."
    prefixes = [_dotted(path[:k]) for k in range(len(path), 0, -1)]
    need = prefixes[:2] if len(path) > 1 else prefixes
    return any(p in line for p in need)


@st.composite
def mutations(draw: st.DrawFn, doc: dict) -> tuple[str, tuple, Any]:
    groups = _SITES.setdefault(id(doc), _site_groups(doc))
    pattern = draw(st.sampled_from(sorted(groups)))  # each kind of field equally often
    path = draw(st.sampled_from(groups[pattern]))
    node = _get(doc, path)
    ops = ["delete", "replace"] if path else []
    if isinstance(node, list) and node:
        ops.append("truncate")
    if isinstance(node, dict):
        ops.append("add_key")
    op = draw(st.sampled_from(ops))
    if op == "replace":
        arg = draw(st.sampled_from([*BAD_VALUES, None]))
    elif op == "truncate":
        arg = draw(st.integers(0, len(node) - 1))
    elif op == "add_key":
        arg = draw(st.sampled_from(UNKNOWN_KEYS))
    else:
        arg = None
    return op, path, arg


_SITES: dict[int, Any] = {}  # per document: site groups, well-formed mutations


def _site_groups(doc: dict) -> dict[str, list[tuple]]:
    """Sites by pattern (indices as ``*``): ``segments[*].waypoints[*].q[*]`` is one."""
    groups: dict[str, list[tuple]] = {}
    for path in _sites(doc):
        pattern = "".join("[*]" if isinstance(k, int) else f".{k}" for k in path)
        groups.setdefault(pattern, []).append(path)
    return groups


def apply(doc: dict, op: str, path: tuple, arg: Any) -> dict:
    doc = copy.deepcopy(doc)
    if op == "delete":
        del _get(doc, path[:-1])[path[-1]]
    elif op == "replace":
        _set(doc, path, copy.deepcopy(arg))
    elif op == "truncate":
        del _get(doc, path)[arg:]
    else:
        _get(doc, path)[arg] = 1
    return doc


def check_mutation(capfd, tmp_path: Path, base: dict, mutation: tuple, *, via: str) -> str:
    """Run one mutated plan through ``dexplan verify`` or ``show --save``; check its class."""
    op, path, arg = mutation
    expected = classify(base, op, path, arg)
    doc = apply(base, op, path, arg)
    file = write(tmp_path / "plan.json", doc)
    out_rrd = tmp_path / "out.rrd"
    out_rrd.unlink(missing_ok=True)
    if via == "verify":
        code, out, err = verify(capfd, file)
    else:
        code, out, err = run_cli(capfd, "show", file, "--save", out_rrd)
    what = f"{op} {_dotted(path)} {str(arg)[:40]}: expected {expected}"
    event(f"{via}: {op} -> {expected}")
    assert "Traceback" not in err and "internal error" not in err, (what, err[:2000])
    if expected == MALFORMED:
        line = assert_bad_input(code, err, outputs=[out_rrd])
        assert _named(line, op, path, arg), (what, line)
        return expected
    assert not err.strip(), (what, err[:2000])
    if via == "show":  # show draws any well-formed plan, rules broken or not
        assert code == 0 and out_rrd.is_file(), (what, code, out[-2000:])
        return expected
    want = {HARMLESS: {0}, RULE: {1}, RULE_OR_HARMLESS: {0, 1}}[expected]
    assert code in want, (what, code, out[-2000:])
    assert out.rstrip().splitlines()[-1].startswith("OK" if code == 0 else "FAILED"), out
    return expected


@given(data=st.data())
def test_mutated_plans_verify(capfd, tmp_path: Path, data: st.DataObject) -> None:
    mutation = data.draw(mutations(valid_plan()), label="mutation")
    check_mutation(capfd, tmp_path, valid_plan(), mutation, via="verify")


@given(data=st.data())
def test_mutated_plans_show(capfd, tmp_path: Path, data: st.DataObject) -> None:
    mutation = data.draw(mutations(valid_plan()), label="mutation")
    check_mutation(capfd, tmp_path, valid_plan(), mutation, via="show")


def _well_formed_mutations(doc: dict) -> list[tuple[str, tuple, Any]]:
    """Every mutation of ``doc`` (from a small value set) that leaves it well formed."""
    out = []
    for path in _sites(doc):
        node = _get(doc, path)
        cands: list[tuple[str, tuple, Any]] = [("delete", path, None)] if path else []
        cands += [("replace", path, v) for v in (None, "x", {"a": 1}, []) if path]
        if isinstance(node, list):
            cands += [("truncate", path, k) for k in range(len(node))]
        if isinstance(node, dict):
            cands.append(("add_key", path, "extra"))
        out += [m for m in cands if classify(doc, *m) != MALFORMED]
    return out


@given(data=st.data())
def test_well_formed_mutations_verify(capfd, tmp_path: Path, data: st.DataObject) -> None:
    """Still well formed: exit 1 exactly when a rule breaks, 0 when harmless."""
    base = valid_plan()
    cands = _SITES.setdefault(-id(base), _well_formed_mutations(base))
    mutation = data.draw(st.sampled_from(cands), label="mutation")
    check_mutation(capfd, tmp_path, base, mutation, via="verify")


@pytest.mark.slow
@settings(max_examples=2000)
@given(data=st.data())
def test_mutated_plans_verify_thorough(capfd, tmp_path: Path, data: st.DataObject) -> None:
    mutation = data.draw(mutations(valid_plan()), label="mutation")
    check_mutation(capfd, tmp_path, valid_plan(), mutation, via="verify")


@pytest.mark.slow
@settings(max_examples=500)
@given(data=st.data())
def test_mutated_plans_show_thorough(capfd, tmp_path: Path, data: st.DataObject) -> None:
    mutation = data.draw(mutations(valid_plan()), label="mutation")
    check_mutation(capfd, tmp_path, valid_plan(), mutation, via="show")


@pytest.mark.slow
@settings(max_examples=500)
@given(data=st.data())
def test_well_formed_mutations_verify_thorough(capfd, tmp_path: Path, data: st.DataObject) -> None:
    base = valid_plan()
    cands = _SITES.setdefault(-id(base), _well_formed_mutations(base))
    mutation = data.draw(st.sampled_from(cands), label="mutation")
    check_mutation(capfd, tmp_path, base, mutation, via="verify")
