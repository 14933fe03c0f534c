"""Grip forces (dexplan.execution.forces): inside the cones, balancing the weight, J^T f torques."""

import copy

import numpy as np
import pinocchio as pin
import pytest

from dexplan.execution.forces import plan_waypoint_forces
from dexplan.model.grasp.grip_forces import ForceSettings, GripForceError
from dexplan.planfile import hand_from_plan, read_plan


@pytest.fixture(scope="module")
def planned(tmp_path_factory, paper_plan):
    doc = read_plan(paper_plan(2, tmp_path_factory.mktemp("forces")))
    return doc, hand_from_plan(doc["hand"])


def _rot(pose):
    return pin.Quaternion(pose[6], pose[3], pose[4], pose[5]).normalized().toRotationMatrix()


def test_forces_in_cones_and_balance_independently(planned) -> None:
    doc, hand = planned
    st = ForceSettings(mass=0.1)
    forces = plan_waypoint_forces(doc, st, hand=hand)
    mu = doc["mu"]
    g = np.array(st.gravity)
    for seg, rows in zip(doc["segments"], forces, strict=True):
        for w, gf in zip(seg["waypoints"], rows, strict=True):
            pose = np.asarray(w["object_pose_xyzquat"])
            R = _rot(pose)
            total_f = st.mass * g.copy()
            total_t = np.zeros(3)
            for i, c in enumerate(w["contacts"]):
                f = gf.forces[i]
                if not gf.loaded[i]:
                    assert np.allclose(f, 0.0)
                    continue
                c = np.asarray(c)
                n_in = -c / np.linalg.norm(c)  # a sphere centred at the object origin
                fn = f @ n_in
                ft = np.linalg.norm(f - fn * n_in)
                assert fn >= st.min_normal_force - 1e-7
                assert ft <= mu * fn + 1e-7
                fw = R @ f
                total_f += fw
                total_t += np.cross(R @ c, fw)
            assert np.allclose(total_f, 0.0, atol=1e-6)
            assert np.allclose(total_t, 0.0, atol=1e-6)
            if seg["kind"] == "regrasp":
                assert not gf.loaded[seg["finger"]]


def test_joint_torques_are_jacobian_transpose(planned) -> None:
    doc, hand = planned
    gf = plan_waypoint_forces(doc, hand=hand)[0][0]
    w = doc["segments"][0]["waypoints"][0]
    q = np.asarray(w["q"])
    pose = np.asarray(w["object_pose_xyzquat"])
    R = _rot(pose)
    # independent: finite differences of the work of the forces (virtual work)
    eps = 1e-6
    tau = np.zeros(hand.nq)
    for j in range(hand.nq):
        dq = np.zeros(hand.nq)
        dq[j] = eps
        for i in range(hand.n_fingers):
            if not gf.loaded[i]:
                continue
            fid = hand.tip_frame_ids[i]
            # displacement of the contact point as a point of the fingertip body
            p_c = pose[:3] + R @ gf.contacts[i]
            pin.framesForwardKinematics(hand.model, hand.data, q)
            M0 = hand.data.oMf[fid].copy()
            pin.framesForwardKinematics(hand.model, hand.data, q + dq)
            M1 = hand.data.oMf[fid]
            local = M0.actInv(p_c)
            disp = M1.act(local) - p_c
            tau[j] += gf.forces_world[i] @ disp / eps
    assert np.allclose(gf.joint_torques, tau, atol=1e-5)


def test_no_gravity_only_squeeze(planned) -> None:
    doc, hand = planned
    st = ForceSettings(gravity=(0.0, 0.0, 0.0))
    gf = plan_waypoint_forces(doc, st, hand=hand)[0][0]
    assert np.allclose(gf.residual, 0.0, atol=1e-6)


def test_not_force_closure_names_the_waypoint(planned) -> None:
    doc, hand = planned
    bad = copy.deepcopy(doc)
    w = bad["segments"][0]["waypoints"][1]
    held = [i for i, c in enumerate(w["contacts"]) if c is not None]
    for i in held[1:]:
        w["contacts"][i] = None  # one finger cannot hold the weight
    with pytest.raises(GripForceError, match="segment 0, waypoint 1"):
        plan_waypoint_forces(bad, hand=hand)


def test_forces_kept_within_the_joints_effort_limits(planned) -> None:
    doc, hand = planned
    effort = np.asarray(hand.model.effortLimit)
    assert np.allclose(effort, 1.0)  # paper_hand.urdf: effort="1"
    forces = plan_waypoint_forces(doc, ForceSettings(mass=0.1), hand=hand)
    worst = max(float(np.max(np.abs(gf.joint_torques))) for rows in forces for gf in rows)
    assert worst <= 1.0 + 1e-6
    # a weight no grasp holds within 1 N m: no forces, never forces beyond the limits
    with pytest.raises(GripForceError, match="beyond the hand's effort limits"):
        plan_waypoint_forces(doc, ForceSettings(mass=3.0), hand=hand)


@pytest.mark.parametrize("mass", [0.1, 1.0, 3.0, 30.0])
def test_holds_exactly_where_the_forces_stay_within_the_effort_limits(planned, mass) -> None:
    """``holds`` (the feasibility program) agrees with ``solve``.

    At every regrasp's first lifted waypoint (the other fingers hold the
    object for the whole regrasp), the linear program says the fingers hold
    the weight within 1 N m exactly where ``solve`` finds forces, and those
    need at most 1 N m (``solve`` never relaxes a limit).
    """
    from dexplan.execution.forces import solver_from_plan

    doc, hand = planned
    solver = solver_from_plan(doc, ForceSettings(mass=mass), hand, ".")
    answers = []
    for seg in doc["segments"]:
        if seg["kind"] != "regrasp":
            continue
        w = seg["waypoints"][1]
        contacts = [None if c is None else np.asarray(c, dtype=float) for c in w["contacts"]]
        assert contacts[seg["finger"]] is None
        q, pose = np.asarray(w["q"]), np.asarray(w["object_pose_xyzquat"])
        held = solver.holds(q, pose, contacts)
        try:
            gf = solver.solve(q, pose, contacts)
        except GripForceError as exc:
            assert not held, exc  # solve finds no forces within the limits only where none exist
        else:
            assert held and float(np.max(np.abs(gf.joint_torques))) <= 1.0 + 1e-6
        answers.append(held)
    assert answers
    if mass == 0.1:
        assert all(answers)  # the planner let these fingers go: the others hold 0.1 kg
    if mass == 30.0:
        assert not any(answers)  # no 3-finger hold carries 30 kg within 1 N m


def test_forces_push_along_the_normals_the_verifier_reads_at_box_edges(tmp_path) -> None:
    """A fingertip on a box edge pushes inside the cone about the edge-to-fingertip direction.

    The verifier reads an edge contact's normal from the fingertip centre
    (``fingertip_contact``); the closest point of the edge point itself names
    one face's normal instead, and forces in that face's cone are outside the
    edge contact's cone (the planner's hold check then judged holding grasps
    unable to hold the object at all). box_tilt90 seed 11 lands fingers on edges
    (seeds 1-8 load no edge contact; the test fails if the chosen seed stops doing so).
    """
    from dexplan.cli import main as cli
    from dexplan.model.objects.fingertip import fingertip_contact
    from dexplan.model.scenario import builtin_scenario_path
    from dexplan.planfile import models_from_document

    path = tmp_path / "plan.json"
    scenario = builtin_scenario_path("suite/box_tilt90")
    assert (
        cli.run(
            ["plan", str(scenario), "--seed", "11", "--time-limit", "300", "-q", "-o", str(path)]
        )
        == 0
    )
    doc = read_plan(path)
    hand = hand_from_plan(doc["hand"])
    obj = models_from_document(doc).obj
    half = np.asarray(doc["object"]["size"]) / 2
    forces = plan_waypoint_forces(doc, ForceSettings(mass=0.1), hand=hand)
    mu, r = doc["mu"], hand.fingertip_radius
    on_edges = 0
    for seg, rows in zip(doc["segments"], forces, strict=True):
        for w, gf in zip(seg["waypoints"], rows, strict=True):
            pose = np.asarray(w["object_pose_xyzquat"])
            R = _rot(pose)
            tips = (hand.fingertip_positions(np.asarray(w["q"])) - pose[:3]) @ R
            for i, c in enumerate(w["contacts"]):
                if not gf.loaded[i]:
                    continue
                _, n_out, _ = fingertip_contact(obj, np.asarray(c), tips[i], r)
                f = gf.forces[i]
                fn = -f @ n_out
                assert fn > 0 and np.linalg.norm(f + fn * n_out) <= mu * fn + 1e-7
                on_edges += int(np.sum(np.isclose(np.abs(c), half, atol=1e-6)) >= 2)
    assert on_edges > 0
