"""The verifier's rule names live in one table, which the docs and the checker follow."""

import ast
import re
from pathlib import Path

import pytest

import dexplan.planfile.verify as plan_verify
from dexplan.planfile import RULES as REEXPORTED
from dexplan.planfile.verify import RULES

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "plan_format.md"


def _emitted() -> dict[str, int]:
    """Rule name -> number of ``.add(seg, wp, RULE, message)`` calls in the verifier."""
    tree = ast.parse(Path(plan_verify.__file__).read_text())
    out: dict[str, int] = {}
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr == "add"
        ):
            rule = node.args[-2]  # add(seg, wp, RULE, message) or add(*where, RULE, message)
            assert isinstance(rule, ast.Constant) and isinstance(rule.value, str), (
                f"line {node.lineno}: the rule of a violation must be a literal name of RULES"
            )
            out[rule.value] = out.get(rule.value, 0) + 1
    return out


def test_every_emitted_rule_is_in_the_table_and_every_rule_is_emitted() -> None:
    emitted = _emitted()
    assert set(emitted) <= set(RULES), sorted(set(emitted) - set(RULES))
    assert set(RULES) <= set(emitted), sorted(set(RULES) - set(emitted))
    assert REEXPORTED is RULES


def test_docs_table_is_the_rule_table() -> None:
    text = DOC.read_text()
    section = text[text.index("## What `dexplan verify PLAN` checks") :]
    rows = re.findall(r"^\| `(\w+)` \| (.*) \|$", section, flags=re.M)
    assert dict(rows) == RULES
    assert [name for name, _ in rows] == list(RULES)  # same order, each once


def test_descriptions_are_one_line() -> None:
    for name, text in RULES.items():
        assert text and "\n" not in text and "|" not in text, name


def test_a_violation_needs_a_name_from_the_table() -> None:
    chk = plan_verify._Checker.__new__(plan_verify._Checker)
    chk.violations = []
    chk.add(0, 1, "collision", "link_1 touches object")
    assert [v.rule for v in chk.violations] == ["collision"]
    with pytest.raises(ValueError, match="unknown verification rule"):
        chk.add(0, 1, "colision", "typo")
