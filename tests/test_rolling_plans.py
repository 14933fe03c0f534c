"""Plans with rolling fingertips: planned, written as dexplan-plan/2, verified, and the
no-slip and tip-contact rules proven to reject what they must."""

from __future__ import annotations

import copy
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

import dexplan
from dexplan.model.grasp.rolling import ContactMotion
from dexplan.model.scenario.scenario import load_scenario
from dexplan.planfile.rules import NO_SLIP_ABS, NO_SLIP_REL
from dexplan.planfile.verify import verify_plan

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"


@pytest.fixture(scope="module")
def rolling_doc() -> dict:
    scen = load_scenario(SCENARIOS / "paper_sphere.toml")
    scen = dataclasses.replace(scen, contact_motion=ContactMotion.ROLLING)
    plan = dexplan.plan(scen, seed=1, quality="none", time_limit=120.0)
    assert plan.solved, plan.status  # solved means the verifier accepted it
    return plan.to_document(".")


def _transfers(doc: dict) -> list[dict]:
    return [s for s in doc["segments"] if s["kind"] == "transfer"]


def test_a_rolling_plan_is_format_2_and_verified(rolling_doc: dict) -> None:
    assert rolling_doc["format"] == "dexplan-plan/2"
    assert rolling_doc["contact_motion"] == "rolling"
    report = verify_plan(rolling_doc)
    assert report.ok, [str(v) for v in report.violations[:5]]
    r = rolling_doc["hand"]["fingertip_radius"]
    for seg in rolling_doc["segments"]:
        for w in seg["waypoints"]:
            for c, t in zip(w["contacts"], w["tip_contacts"], strict=True):
                assert (c is None) == (t is None)
                if t is not None:
                    assert abs(np.linalg.norm(t) - r) < 1e-3  # on the tip sphere


def test_contacts_roll_over_the_object_during_transfers(rolling_doc: dict) -> None:
    moved = []
    for seg in _transfers(rolling_doc):
        a, b = seg["waypoints"][0], seg["waypoints"][-1]
        for ca, cb in zip(a["contacts"], b["contacts"], strict=True):
            moved.append(np.linalg.norm(np.subtract(cb, ca)))
    assert max(moved) > 2e-3  # millimetres of rolling on the object, not a fixed contact


def test_a_fixed_contact_plan_called_rolling_slips(rolling_doc: dict, paper_plan, tmp_path) -> None:
    """The fixed-contact plan slides its fingertips: claimed rolling, only no-slip breaks."""
    doc = json.loads(paper_plan(1, tmp_path, motion="fixed").read_text())
    assert doc["contact_motion"] == "fixed" and verify_plan(doc).ok
    doc["contact_motion"] = "rolling"
    report = verify_plan(doc)
    assert {v.rule for v in report.violations} == {"transfer_no_slip"}
    first = next(i for i, s in enumerate(doc["segments"]) if s["kind"] == "transfer")
    assert any(v.segment == first for v in report.violations)
    assert "slips" in report.violations[0].message


def test_a_rolling_plan_called_fixed_drifts(rolling_doc: dict) -> None:
    doc = copy.deepcopy(rolling_doc)
    doc["contact_motion"] = "fixed"
    assert {v.rule for v in verify_plan(doc).violations} == {"transfer_contact_drift"}


def test_a_moved_tip_contact_is_reported_where_it_is(rolling_doc: dict) -> None:
    doc = copy.deepcopy(rolling_doc)
    si = next(i for i, s in enumerate(doc["segments"]) if s["kind"] == "transfer")
    w = doc["segments"][si]["waypoints"][3]
    f = next(i for i, t in enumerate(w["tip_contacts"]) if t is not None)
    w["tip_contacts"][f] = list(np.add(w["tip_contacts"][f], [0.002, 0.0, 0.0]))
    report = verify_plan(doc)
    assert [(v.rule, v.segment, v.waypoint) for v in report.violations] == [("tip_contact", si, 3)]


def test_the_no_slip_tolerance_is_the_documented_one(rolling_doc: dict) -> None:
    """The planner's rolling paths agree far inside the tolerance the rule states."""
    from dexplan.planfile.document import segments_from_dicts
    from dexplan.planfile.models import hand_from_plan
    from dexplan.planfile.tip_contacts import contact_path_lengths

    hand = hand_from_plan(rolling_doc["hand"])
    for seg in segments_from_dicts(rolling_doc["segments"]):
        if seg.kind != "transfer":
            continue
        for _, on_tip, on_obj in contact_path_lengths(hand, seg):
            assert abs(on_tip - on_obj) <= 0.5 * (NO_SLIP_REL * on_obj + NO_SLIP_ABS)


def test_a_format_1_plan_still_verifies(paper_plan, tmp_path) -> None:
    doc = json.loads(paper_plan(1, tmp_path, motion="fixed").read_text())
    doc["format"] = "dexplan-plan/1"
    del doc["contact_motion"]
    for seg in doc["segments"]:
        for w in seg["waypoints"]:
            del w["tip_contacts"]
    assert verify_plan(doc).ok


def test_scenario_motion_is_validated(tmp_path) -> None:
    text = (SCENARIOS / "paper_sphere.toml").read_text()
    bad = tmp_path / "bad.toml"
    assert 'motion = "rolling"' in text
    bad.write_text(text.replace('motion = "rolling"', 'motion = "sliding"'))
    with pytest.raises(dexplan.DexplanError, match=r'contact\.motion must be "fixed" or "rolling"'):
        load_scenario(bad)


def test_the_same_seed_gives_the_same_rolling_plan(rolling_doc: dict) -> None:
    scen = load_scenario(SCENARIOS / "paper_sphere.toml")
    scen = dataclasses.replace(scen, contact_motion=ContactMotion.ROLLING)
    again = dexplan.plan(scen, seed=1, quality="none", time_limit=120.0).to_document(".")
    assert again["segments"] == rolling_doc["segments"]
