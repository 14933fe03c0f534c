"""Object-pose feedback of the replay (dexplan.execution.replay.control): targets, tip slip."""

import copy

import numpy as np
import pinocchio as pin
import pytest

from dexplan.execution.replay.control import ObjectFeedback, planned_tip_slip, pose_se3
from dexplan.execution.trajectory import build_trajectory
from dexplan.planfile import hand_from_plan, read_plan


@pytest.fixture(scope="module")
def planned(tmp_path_factory, paper_plan):
    """paper_sphere seed 1 with fixed contacts (the rigid tips' slide is their gap)."""
    doc = read_plan(paper_plan(1, tmp_path_factory.mktemp("control"), motion="fixed"))
    return doc, hand_from_plan(doc["hand"])


@pytest.fixture(scope="module")
def rolled(tmp_path_factory, paper_plan):
    """paper_sphere seed 1 as shipped: rolling contacts."""
    doc = read_plan(paper_plan(1, tmp_path_factory.mktemp("control_rolling")))
    assert doc["contact_motion"] == "rolling"
    return doc, hand_from_plan(doc["hand"])


def _first_transfer(doc):
    d = copy.deepcopy(doc)
    d["segments"] = [next(s for s in d["segments"] if s["kind"] == "transfer")]
    return d


def test_pose_se3_is_xyzw() -> None:
    M = pose_se3(np.array([0.1, 0.2, 0.3, 0.0, 0.0, np.sin(0.25), np.cos(0.25)]))
    assert np.allclose(M.translation, [0.1, 0.2, 0.3])
    assert np.allclose(pin.log3(M.rotation), [0.0, 0.0, 0.5])


def test_on_plan_the_targets_are_the_plan(planned) -> None:
    doc, hand = planned
    traj = build_trajectory(_first_transfer(doc), hand=hand)
    fb = ObjectFeedback(hand, traj)
    k = traj.t.size // 2
    out = fb.targets(k, traj.q[k], traj.q[k], traj.object_pose[k], traj.object_pose[k])
    assert np.allclose(out, traj.q[k], atol=1e-9)


def test_a_lagging_object_moves_the_holding_tips_ahead(planned) -> None:
    """The object measured 2 mm behind the plan: every holding tip is aimed 2 mm ahead."""
    doc, hand = planned
    traj = build_trajectory(_first_transfer(doc), hand=hand)
    fb = ObjectFeedback(hand, traj)
    k = traj.t.size // 2
    lag = traj.object_pose[k].copy()
    lag[0] -= 0.002
    out = fb.targets(k, traj.q[k], traj.q[k], traj.object_pose[k], lag)
    shift = hand.fingertip_positions(out) - hand.fingertip_positions(traj.q[k])
    assert fb.holding[k].all()
    assert np.allclose(shift, [0.002, 0.0, 0.0], atol=3e-4)


def test_transfers_ask_the_rigid_tips_to_slide(planned) -> None:
    """The open-loop gap: turning the object with contacts fixed slides the tips by mm."""
    doc, hand = planned
    slip = planned_tip_slip(doc, hand)
    n_transfers = sum(s["kind"] == "transfer" for s in doc["segments"])
    assert slip.shape == (n_transfers, hand.n_fingers)
    assert (slip >= 0).all() and slip.max() > 0.003
    still = copy.deepcopy(_first_transfer(doc))
    w0 = still["segments"][0]["waypoints"][0]
    for w in still["segments"][0]["waypoints"]:
        w["q"], w["object_pose_xyzquat"] = list(w0["q"]), list(w0["object_pose_xyzquat"])
    assert np.allclose(planned_tip_slip(still, hand), 0.0)


def test_a_free_tip_is_kept_off_the_object_until_it_lands(planned) -> None:
    from dexplan.execution.forces import solver_from_plan
    from dexplan.execution.replay.control import CLEARANCE, LAND_TIME
    from dexplan.model.grasp.grip_forces import ForceSettings

    doc, hand = planned
    traj = build_trajectory(_first_transfer(doc), hand=hand)
    fb = ObjectFeedback(hand, traj, solver_from_plan(doc, ForceSettings(), hand))
    radius = float(doc["object"]["radius"]) + hand.fingertip_radius
    grazing = np.array([radius + 0.0001, 0.0, 0.0])
    assert np.allclose(fb._clear(grazing, 10.0), [radius + CLEARANCE, 0.0, 0.0])
    assert np.allclose(fb._clear(grazing, LAND_TIME / 8), grazing)
    far = np.array([0.0, radius + 0.01, 0.0])
    assert np.allclose(fb._clear(far, 10.0), far)


def test_next_hold_times() -> None:
    from dexplan.execution.replay.control import _next_hold_times

    t = np.array([0.0, 1.0, 2.0, 3.0])
    holding = np.array([[True, False], [False, False], [False, True], [True, False]])
    out = _next_hold_times(t, holding)
    assert np.array_equal(out[:, 0], [0.0, 3.0, 3.0, 3.0])
    assert np.array_equal(out[:, 1], [2.0, 2.0, 2.0, np.inf])


def test_a_rolling_plan_holds_with_its_planned_joints_corrected(rolled) -> None:
    """Rolling contacts: the planned joints roll the tips; the feedback only adds the correction.

    On the plan the targets are the plan; with the object 2 mm behind, every
    holding tip is aimed 2 mm ahead; with the fingers off their planned joints
    but the object on the plan, the targets stay the planned joints (they
    carry the planned rolling), where the fixed-contact feedback carries the
    measured tips instead.
    """
    doc, hand = rolled
    traj = build_trajectory(_first_transfer(doc), hand=hand)
    k = traj.t.size // 2
    q, pose = traj.q[k], traj.object_pose[k]
    fb = ObjectFeedback(hand, traj, rolling=True)
    assert fb.holding[k].all()
    assert np.allclose(fb.targets(k, q, q, pose, pose), q, atol=1e-9)
    lag = pose.copy()
    lag[0] -= 0.002
    out = fb.targets(k, q, q, pose, lag)
    shift = hand.fingertip_positions(out) - hand.fingertip_positions(q)
    assert np.allclose(shift, [0.002, 0.0, 0.0], atol=3e-4)
    off = q + 0.02
    assert np.allclose(fb.targets(k, q, off, pose, pose), q, atol=1e-9)
    fixed = ObjectFeedback(hand, traj, rolling=False)
    assert not np.allclose(fixed.targets(k, q, off, pose, pose), q, atol=1e-3)
