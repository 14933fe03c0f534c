"""docs/scenario.md documents every field the scenario parser accepts, under its table."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from dexplan.model.grasp import CONTACT_MODELS
from dexplan.model.hand.builtin import BUILTIN_HANDS
from dexplan.model.objects.factory import SHAPE_FIELDS, SHAPE_KINDS
from dexplan.model.scenario import OBSTACLE_OWN_FIELDS, SCENARIO_FIELDS, SPACES
from dexplan.planning.ompl import available_planners

DOC = Path(__file__).resolve().parent.parent / "docs" / "scenario.md"

HEADINGS = {
    "": "Top level",
    "hand": "`[hand]`",
    "object": "`[object]`",
    "contact": "`[contact]`",
    "obstacles": "`[[obstacles]]`",
    "start": "`[start]`",
    "goal": "`[goal]`",
    "planner": "`[planner]`",
    "workspace": "`[workspace]`",
    "world": "`[world]`",
}


def section(heading: str) -> str:
    """The text under ``### heading`` up to the next heading."""
    text = DOC.read_text()
    m = re.search(rf"^### {re.escape(heading)}\n(.*?)(?=^#)", text, re.M | re.S)
    assert m, f"docs/scenario.md has no section '### {heading}'"
    return m[1]


def rows(text: str) -> dict[str, list[str]]:
    """Table rows keyed by their first cell's `field`: the remaining cells."""
    out = {}
    for line in text.splitlines():
        m = re.match(r"^\| `([a-z_0-9]+)` \|(.*)\|$", line)
        if m:
            out[m[1]] = [c.strip() for c in m[2].split(" | ")]
    return out


def test_every_table_has_a_section() -> None:
    assert set(HEADINGS) == set(SCENARIO_FIELDS)


@pytest.mark.parametrize("table", [t for t in SCENARIO_FIELDS if t != "obstacles"])
def test_each_field_is_a_row_of_its_table(table: str) -> None:
    documented = rows(section(HEADINGS[table]))
    assert set(documented) == set(SCENARIO_FIELDS[table]), (
        f"[{table}]: undocumented {sorted(SCENARIO_FIELDS[table] - set(documented))}, "
        f"documented but not accepted {sorted(set(documented) - SCENARIO_FIELDS[table])}"
    )


def test_obstacles_fields() -> None:
    text = section(HEADINGS["obstacles"])
    assert set(rows(text)) == set(OBSTACLE_OWN_FIELDS)
    for name in SCENARIO_FIELDS["obstacles"]:  # the shape fields are named in the text
        assert f"`{name}`" in text, name


def test_object_rows_name_the_shape_kinds_of_each_field() -> None:
    documented = rows(section(HEADINGS["object"]))
    for kind, fields in SHAPE_FIELDS.items():
        for name in fields - {"shape"}:
            assert f"`{kind}`" in documented[name][0], (kind, name)
    for name, cells in documented.items():
        if name != "shape":
            kinds = set(re.findall(r"`([a-z]+)`", cells[0]))
            assert kinds == {k for k in SHAPE_KINDS if name in SHAPE_FIELDS[k]}, name
    assert all(f"`{kind}`" in documented["shape"][-2] for kind in SHAPE_KINDS)


def test_choices_are_listed() -> None:
    hand = rows(section(HEADINGS["hand"]))["builtin"]
    assert all(f'"{name}"' in " ".join(hand) for name in BUILTIN_HANDS)
    model = rows(section(HEADINGS["contact"]))["model"]
    assert all(f'"{name}"' in " ".join(model) for name in CONTACT_MODELS)
    planner = rows(section(HEADINGS["planner"]))
    assert all(f'"{name}"' in " ".join(planner["space"]) for name in SPACES)
    assert all(f"`{name}`" in " ".join(planner["name"]) for name in available_planners())


def test_the_parser_checks_tables_against_the_field_table() -> None:
    # a new table or field must go through SCENARIO_FIELDS (and so into the docs):
    # every unknown-field check of a named table takes its fields from there
    import ast

    import dexplan.model.scenario.scenario

    tree = ast.parse(Path(dexplan.model.scenario.scenario.__file__).read_text())
    calls = [
        node
        for node in ast.walk(tree)
        if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "_only"
    ]
    tables = [c for c in calls if isinstance(c.args[1], ast.Constant)]
    assert {c.args[1].value for c in tables} == set(SCENARIO_FIELDS) - {"object", "obstacles"}
    for call in tables:
        allowed = call.args[2]
        assert not isinstance(allowed, ast.Set | ast.Call), (
            f"line {call.lineno}: _only({call.args[1].value!r}, ...) lists its fields inline; "
            "put them in SCENARIO_FIELDS"
        )
