"""Holds: the torque ratio of :mod:`dexplan.model.grasp.holds` and the effort limits it reads."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import Bounds, LinearConstraint, milp

from dexplan.core.errors import InvalidInputError, ModelError, ScenarioError
from dexplan.model.grasp import ratio_lp
from dexplan.model.grasp.grip_forces import ForceSettings, GripForceSolver
from dexplan.model.grasp.grip_program import (
    contact_torque_columns,
    grip_program,
    joint_effort_limits,
)
from dexplan.model.grasp.holds import HoldChecker
from dexplan.model.hand.hand import Hand
from dexplan.model.hand.urdf import with_effort_limits
from dexplan.model.objects.fingertip import fingertip_contact
from dexplan.planfile import hand_from_plan, read_plan
from dexplan.planfile.models import models_from_document


@pytest.fixture(scope="module")
def regrasp_holds(tmp_path_factory, paper_plan):
    """The paper plan's models and its regrasp holds: (q, pose, contacts), the free finger None."""
    doc = read_plan(paper_plan(2, tmp_path_factory.mktemp("holds")))
    m = models_from_document(doc, tmp_path_factory.getbasetemp(), hand=hand_from_plan(doc["hand"]))
    holds = []
    for seg in doc["segments"]:
        if seg["kind"] != "regrasp":
            continue
        w = seg["waypoints"][1]
        contacts = [None if c is None else np.asarray(c, dtype=float) for c in w["contacts"]]
        holds.append((np.asarray(w["q"]), np.asarray(w["object_pose_xyzquat"]), contacts))
    assert holds
    return m, holds


def _checker(m, *, mass=0.1, shift=0.0, hand=None, share=1.0) -> HoldChecker:
    return HoldChecker(
        hand or m.hand,
        m.obj,
        m.mu,
        m.friction_edges,
        m.contact_model,
        m.torsion,
        ForceSettings(mass=mass, min_normal_force=0.0),
        shift_m=shift,
        effort_share=share,
    )


def test_ratio_agrees_with_the_grip_force_feasibility_program(regrasp_holds) -> None:
    """ratio <= 1 exactly where GripForceSolver's own LP (torque rows, no margin) finds forces.

    Two formulations: the solver's feasibility program with the URDF's limits
    as bounds, and the shared-ratio program minimising the largest
    ``|tau_j| / effort_j``. Masses around the threshold make both answers occur.
    """
    m, holds = regrasp_holds
    answers = set()
    for mass in (0.1, 1.0, 3.0, 10.0):
        hc = _checker(m, mass=mass)
        gs = GripForceSolver(
            m.hand,
            m.obj,
            m.mu,
            m.friction_edges,
            m.contact_model,
            m.torsion,
            ForceSettings(mass=mass, min_normal_force=0.0),
        )
        for q, pose, contacts in holds:
            r = hc.ratio(q, pose, contacts)
            if abs(r - 1.0) < 1e-6:
                continue  # on the boundary, either answer is right
            assert (r <= 1.0) == gs.holds(q, pose, contacts), (mass, r)
            answers.add(r <= 1.0)
    assert answers == {True, False}


def test_ratio_scales_with_the_weight_and_the_limits(regrasp_holds) -> None:
    """With no least normal force the program is homogeneous: twice the mass, twice the ratio.

    Halving every effort limit (written into the URDF) doubles the ratio as well.
    """
    m, holds = regrasp_holds
    half = Hand(
        with_effort_limits(m.hand.urdf_xml, 0.5),
        m.hand.fingertip_frames,
        m.hand.fingertip_radius,
        collision_exclude=m.hand.collision_exclude,
    )
    assert np.allclose(half.model.effortLimit, 0.5)
    base, heavy, weak = _checker(m), _checker(m, mass=0.2), _checker(m, hand=half)
    for q, pose, contacts in holds:
        r = base.ratio(q, pose, contacts)
        assert 0.0 < r < math.inf
        assert heavy.ratio(q, pose, contacts) == pytest.approx(2 * r, rel=1e-5)
        assert weak.ratio(q, pose, contacts) == pytest.approx(2 * r, rel=1e-5)


def test_an_effort_share_is_a_ratio_against_that_share_of_the_limits(regrasp_holds) -> None:
    """With ``effort_share`` s the ratio is the full-limit ratio over s, so a hold that
    needs 0.9 of the limits holds at s = 1 and not at s = 0.8 (the planner's headroom)."""
    m, holds = regrasp_holds
    full, headroom = _checker(m), _checker(m, share=0.8)
    for q, pose, contacts in holds:
        r = full.ratio(q, pose, contacts)
        assert headroom.ratio(q, pose, contacts) == pytest.approx(r / 0.8, rel=1e-6)
    # a weight that makes one hold need 0.9 of the limits
    q, pose, contacts = holds[0]
    mass = 0.1 * 0.9 / full.ratio(q, pose, contacts)
    assert _checker(m, mass=mass).holds(q, pose, contacts)
    assert not _checker(m, mass=mass, share=0.8).holds(q, pose, contacts)


@pytest.mark.parametrize("share", [0.0, -0.5, 1.5, math.nan])
def test_bad_effort_share_is_refused(regrasp_holds, share) -> None:
    m, _ = regrasp_holds
    with pytest.raises(InvalidInputError, match="effort share"):
        _checker(m, share=share)


def test_shifted_contacts_never_need_less_than_the_nominal_ones(regrasp_holds) -> None:
    """The shifted sets are added to the nominal one: the robust ratio is at least the nominal.

    A shift of 1 cm on the 4 cm ball needs strictly more somewhere.
    """
    m, holds = regrasp_holds
    nominal, robust, wide = _checker(m), _checker(m, shift=0.002), _checker(m, shift=0.01)
    more = 0
    for q, pose, contacts in holds:
        r0 = nominal.ratio(q, pose, contacts)
        r2, r10 = robust.ratio(q, pose, contacts), wide.ratio(q, pose, contacts)
        assert r2 >= r0 - 1e-9 and r10 >= r0 - 1e-9
        more += r10 > r0 * 1.01
    assert more > 0


def test_no_contact_holds_nothing_and_a_massless_object_is_held_by_none(regrasp_holds) -> None:
    m, holds = regrasp_holds
    q, pose, contacts = holds[0]
    assert _checker(m).ratio(q, pose, [None] * len(contacts)) == math.inf
    assert _checker(m, mass=0.0).ratio(q, pose, [None] * len(contacts)) == 0.0


@pytest.mark.parametrize("shift", [-0.001, 0.5, math.nan])
def test_bad_shift_is_refused(regrasp_holds, shift) -> None:
    m, _ = regrasp_holds
    with pytest.raises(InvalidInputError, match="hold shift"):
        _checker(m, shift=shift)


def test_effort_limits_by_joint_name_and_their_errors() -> None:
    hand = Hand.builtin("paper", effort_limits={"f0_mcp": 0.25})
    assert hand.model.effortLimit[hand.joint_names.index("f0_mcp")] == pytest.approx(0.25)
    assert 'effort="0.25"' in hand.urdf_xml  # a plan carries the limit in its URDF
    with pytest.raises(ModelError, match=r"no actuated joint 'f0_mpc'.*did you mean 'f0_mcp'"):
        Hand.builtin("paper", effort_limits={"f0_mpc": 0.25})
    with pytest.raises(ModelError, match="must be a finite number"):
        Hand.builtin("paper", effort_limits=-1.0)


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("effort_limits = 0", r"hand.effort_limits must be in \(0, 10000\]"),
        ('effort_limits = "strong"', "hand.effort_limits must be a finite number"),
        ("effort_limits = { f0_mcp = -2 }", r"hand.effort_limits.f0_mcp must be in"),
    ],
)
def test_scenario_effort_limits_are_validated(tmp_path, line, message) -> None:
    from dexplan.model.scenario import load_scenario

    path = tmp_path / "s.toml"
    path.write_text(
        f'[hand]\nbuiltin = "paper"\n{line}\n[object]\nshape = "sphere"\nradius = 0.04\n'
        "[start]\nobject_pose_xyzquat = [0, 0, 0.1, 0, 0, 0, 1]\n"
        "[goal]\nobject_pose_xyzquat = [0, 0, 0.1, 0, 0, 0, 1]\n"
    )
    with pytest.raises(ScenarioError, match=message):
        load_scenario(path)


def test_verify_reports_the_holds_and_rejects_a_weight_the_joints_cannot_carry(
    tmp_path_factory, paper_plan
) -> None:
    """The ``holds`` rule: the plan's own weight passes, fifty times it does not.

    The verifier also reports the worst torque ratio (at most 1 when the plan
    passes) and the weakest hold (a force-closure quality above 0).
    """
    import copy

    from dexplan.planfile import verify_plan

    path = paper_plan(2, tmp_path_factory.mktemp("holds_verify"))
    doc = read_plan(path)
    report = verify_plan(doc, path.parent)
    assert report.ok, [str(v) for v in report.violations]
    assert report.worst_torque_ratio is not None and 0.0 < report.worst_torque_ratio <= 1.0
    assert report.weakest_hold is not None and report.weakest_hold > 0.0
    heavy = copy.deepcopy(doc)
    heavy["object"]["mass"] = 5.0
    bad = verify_plan(heavy, path.parent)
    assert {v.rule for v in bad.violations} == {"holds"}
    assert bad.worst_torque_ratio > 10 * report.worst_torque_ratio  # the load grows 50-fold
    assert any("effort limits" in str(v) and "kg" in str(v) for v in bad.violations)


def test_the_scenario_effort_share_reaches_the_planners_holds(tmp_path) -> None:
    """``[contact] hold_effort_share`` is what the local planners' holds use; default 1."""
    from dexplan.model.objects import shape_from_dict
    from dexplan.model.scenario import builtin_scenario_path, load_scenario
    from dexplan.planning.context import build_hand, hold_checker, validity_settings

    text = builtin_scenario_path("paper_sphere").read_text()
    assert "hold_effort_share" not in text
    shared = tmp_path / "shared.toml"
    shared.write_text(text.replace("[contact]", "[contact]\nhold_effort_share = 0.7", 1))
    for path, share in ((builtin_scenario_path("paper_sphere"), 1.0), (shared, 0.7)):
        scen = load_scenario(path)
        hand = build_hand(scen)
        obj = shape_from_dict(dict(scen.object), scen.base_dir)
        hc = hold_checker(scen, hand, obj, validity_settings(scen, hand.n_fingers))
        assert hc.effort_share == share


def _reference_ratio(hc: HoldChecker, q, pose, contacts) -> float:
    """A hold's ratio at its stated contacts, built from the public pieces and solved by milp.

    An independent reading of the module's program: the contact normals as
    the verifier reads them, grip_program's rows, contact_torque_columns'
    torques of the limited joints of the loaded fingers, ``min t``.
    """
    hand, model = hc.hand, hc.hand.model
    R = pin.Quaternion(pose[6], pose[3], pose[4], pose[5]).normalized().toRotationMatrix()
    loaded = [i for i, c in enumerate(contacts) if c is not None]
    P = np.array([contacts[i] for i in loaded], dtype=float)
    tips = (hand.fingertip_positions(q) - pose[:3]) @ R
    N = np.array(
        [
            -fingertip_contact(hc.obj, P[c], tips[i], hand.fingertip_radius)[1]
            for c, i in enumerate(loaded)
        ]
    )
    w = hc.forces.wrench_world()
    prog = grip_program(
        P,
        N,
        np.concatenate([R.T @ w[:3], R.T @ w[3:]]),
        mu_eff=hc.mu,
        torsion_eff=hc.torsion if hc.soft else None,
        L=hc.L,
        edges=hc.edges,
        min_normal_force=hc.forces.min_normal_force,
        torque=None,
    )
    data = model.createData()
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    r = 4 if hc.soft else 3
    T = np.zeros((model.nv, len(loaded) * r))
    for c, i in enumerate(loaded):
        fid = hand.tip_frame_ids[i]
        J = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
        d = pose[:3] + R @ P[c] - data.oMf[fid].translation
        T[:, c * r : (c + 1) * r] = contact_torque_columns(J, d, R, N[c], hc.L if hc.soft else None)
    effort = joint_effort_limits(model)
    held = np.concatenate([hand.finger_q_index[i] for i in loaded])
    joints = [j for j in held if not np.isnan(effort[j])]
    Tj, e = T[joints], effort[joints]
    m = T.shape[1]
    A = np.block([[prog.A, np.zeros((len(prog.A), 1))], [Tj, -e[:, None]], [-Tj, -e[:, None]]])
    lo = np.concatenate([prog.lo, np.full(2 * len(e), -np.inf)])
    hi = np.concatenate([prog.hi, np.zeros(2 * len(e))])
    res = milp(
        np.r_[np.zeros(m), 1.0],
        constraints=LinearConstraint(A, lo, hi),
        bounds=Bounds(np.r_[np.full(m, -np.inf), 0.0], np.full(m + 1, np.inf)),
    )
    return math.inf if res.status != 0 else float(res.x[-1])


@pytest.mark.parametrize(
    ("model", "torsion", "mu"), [("point", 0.0, None), ("soft", 0.005, None), ("soft", 0.005, 0.0)]
)
def test_ratio_is_the_optimum_of_an_independent_program(regrasp_holds, model, torsion, mu) -> None:
    """The stated contacts' ratio equals a program built from the public pieces (point,
    soft and frictionless soft contacts), and a transfer's ratios in one pass equal
    the holds' own ratios: warm starts change the path to the optimum, not the optimum."""
    m, holds = regrasp_holds
    hc = HoldChecker(
        m.hand,
        m.obj,
        m.mu if mu is None else mu,
        m.friction_edges,
        model,
        torsion,
        ForceSettings(mass=0.1, min_normal_force=0.1),
    )
    alone = [hc.ratio(q, pose, contacts, shifted=False) for q, pose, contacts in holds]
    for (q, pose, contacts), r in zip(holds, alone, strict=True):
        assert r == pytest.approx(_reference_ratio(hc, q, pose, contacts), rel=1e-9, abs=1e-12)
    assert np.isfinite(alone).all() or mu == 0.0
    np.testing.assert_allclose(hc.stated_ratios(holds), alone, rtol=1e-9, atol=1e-12)


def test_ratio_programs_without_scipys_highs_module_give_the_same_ratios(
    regrasp_holds, monkeypatch
) -> None:
    """Without SciPy's HiGHS module (private to SciPy) each program goes to milp: same ratios."""
    m, holds = regrasp_holds
    hc = _checker(m, shift=0.002)
    direct = [hc.ratio(q, pose, contacts) for q, pose, contacts in holds]
    monkeypatch.setattr(ratio_lp, "_CORE", None)
    hc = _checker(m, shift=0.002)
    fallback = [hc.ratio(q, pose, contacts) for q, pose, contacts in holds]
    np.testing.assert_allclose(fallback, direct, rtol=1e-9)


def test_a_transfers_ratios_built_together_are_each_holds_own(
    regrasp_holds, paper_plan, tmp_path
) -> None:
    """A transfer's holds (the same loaded fingers) are built and solved in one pass: each
    ratio is the hold's own, with or without the caller's normals (and holds of different
    fingers, mixed in, are each their own too)."""
    m, regrasps = regrasp_holds
    doc = read_plan(paper_plan(2, tmp_path))
    seg = next(s for s in doc["segments"] if s["kind"] == "transfer")
    holds = [
        (
            np.asarray(w["q"]),
            np.asarray(w["object_pose_xyzquat"]),
            [None if c is None else np.asarray(c, dtype=float) for c in w["contacts"]],
        )
        for w in seg["waypoints"]
    ]
    hc = _checker(m, mass=0.5)
    alone = [hc.ratio(q, pose, contacts, shifted=False) for q, pose, contacts in holds]
    assert all(0.0 < r < math.inf for r in alone)
    np.testing.assert_allclose(hc.stated_ratios(holds), alone, rtol=1e-9)
    normals = []
    for q, pose, contacts in holds:
        R = pin.Quaternion(pose[6], pose[3], pose[4], pose[5]).normalized().toRotationMatrix()
        tips = (m.hand.fingertip_positions(q) - pose[:3]) @ R
        r = m.hand.fingertip_radius
        normals.append(
            np.array([-fingertip_contact(m.obj, c, tips[i], r)[1] for i, c in enumerate(contacts)])
        )
    np.testing.assert_allclose(hc.stated_ratios(holds, normals), alone, rtol=1e-9)
    mixed = holds[:3] + regrasps
    expected = [hc.ratio(q, pose, contacts, shifted=False) for q, pose, contacts in mixed]
    np.testing.assert_allclose(hc.stated_ratios(mixed), expected, rtol=1e-9)
