"""Every verify rule rejects its smallest breaking change, and only that (tests/verify_tampers.py).

The planner's tests trust ``dexplan verify`` as their oracle: here each rule
is shown to fire, at the segment and waypoint broken, on a plan from a real
run changed in the smallest way that breaks it, and the untouched plan passes.
"""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
from verify_tampers import TAMPERS

from dexplan.planfile import read_plan, verify_plan
from dexplan.planfile.verify import RULES


@pytest.fixture(scope="module")
def real_plan(paper_plan, tmp_path_factory: pytest.TempPathFactory) -> dict:
    """The builtin scenario's plan of seed 1 with fixed contacts (the session's shared run), parsed.

    The tampers break fixed-contact rules (``transfer_contact_drift``; a fixed plan
    called rolling breaks ``transfer_no_slip``).
    """
    doc = read_plan(paper_plan(1, tmp_path_factory.mktemp("tampers"), motion="fixed"))
    kinds = {s["kind"] for s in doc["segments"]}
    assert kinds == {"transfer", "regrasp"}, kinds  # the table needs both kinds
    return doc


def test_the_untouched_plan_passes(real_plan: dict) -> None:
    report = verify_plan(real_plan)
    assert report.ok, [str(v) for v in report.violations[:5]]


def test_every_rule_has_its_tampered_case() -> None:
    """A rule added to RULES without a row of tests/verify_tampers.py fails here."""
    assert sorted(set(RULES) - set(TAMPERS)) == [], "add the rule's case to tests/verify_tampers.py"
    assert sorted(set(TAMPERS) - set(RULES)) == []


@pytest.mark.parametrize("rule", list(RULES))
def test_verify_reports_exactly_the_broken_rule(real_plan: dict, rule: str) -> None:
    tamper = TAMPERS.get(rule)
    assert tamper is not None, f"rule {rule!r} has no tampered case in tests/verify_tampers.py"
    doc, expected = tamper.apply(copy.deepcopy(real_plan))
    assert any(r == rule for r, _, _ in expected)
    others = {r for r, _, _ in expected} - {rule}
    for other in others:  # a rule broken alongside is one the row explains
        assert other in tamper.also, f"{rule}: {other} breaks too, and the row does not say why"
    got = {(v.rule, v.segment, v.waypoint) for v in verify_plan(doc, Path(".")).violations}
    assert got == expected, (sorted(got - expected)[:5], sorted(expected - got)[:5])
