"""Contact models: the soft-finger force closure against independent references.

The references rebuild the soft-finger generators of docs/force_closure.md (the point
pyramid edges of ``test_grasp.ref_edges`` plus ``[n, (p x n + s torsion n) / L]``)
and judge them with scipy's qhull, as ``tests/test_grasp.py`` does for point
contacts; the exact sets (round Coulomb cone, elliptic soft-finger set) are
sampled densely and judged the same way. Then the model is followed through the
scenario, the planning context, the plan file, ``verify`` and the CLI.
"""

import copy
import math
from pathlib import Path

import numpy as np
import pytest
from cli_contract import assert_bad_input, run_cli
from test_grasp import (
    TETRA,
    hull_epsilon,
    lp_quality,
    random_grasp,
    ref_edges,
    sphere,
    torque_scale,
)

from dexplan.core.errors import InvalidInputError, PlanFileError, ScenarioError
from dexplan.model.grasp import (
    MAX_TORSION,
    ForceClosure,
    contact_wrenches,
    exact_force_closure,
    force_closure_quality,
    is_force_closure,
    min_contacts,
    min_subgrasp_quality,
    soft_finger_facets,
)
from dexplan.model.scenario import builtin_scenario_path, load_scenario
from dexplan.planfile import build_plan_document, read_plan, verify_plan, write_plan
from dexplan.planfile.schema import validate_plan
from dexplan.planning.context import build_context, build_hand
from dexplan.planning.gsn.validity import ValiditySettings, let_go_problem
from dexplan.planning.planner import plan

EDGES = 8
SCENARIOS = builtin_scenario_path().parent
SOFT = SCENARIOS / "three_finger_sphere.toml"
POINT = SCENARIOS / "three_finger_sphere_point.toml"


# ---------------------------------------------------------------------------
# Independent references
# ---------------------------------------------------------------------------


def ref_soft_wrenches(points, normals, mu, edges, torsion, ts):
    """Soft generators from the definition: point edges, then (n, +-torsion)."""
    w = []
    for p, n, fs in zip(points, normals, ref_edges(normals, mu, edges), strict=True):
        n = n / np.linalg.norm(n)
        for f in fs:
            w.append(np.concatenate([f, np.cross(p, f) / ts]))
        for s in (1.0, -1.0):
            w.append(np.concatenate([n, (np.cross(p, n) + s * torsion * n) / ts]))
    return np.array(w)


def basis(n):
    """Any orthonormal tangent pair of ``n`` (not the model's: a rotated pyramid)."""
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t1 = np.cross(n, a)
    t1 /= np.linalg.norm(t1)
    return t1, np.cross(n, t1)


def ellipse_samples(points, normals, mu, torsion, ts, n_az, lats, twist=0.0):
    """Wrenches of points on the boundary of the exact contact sets (f_n = 1).

    ``torsion = 0``: the round Coulomb cone; else the elliptic soft-finger set
    ``|f_t|^2 / mu^2 + tau^2 / torsion^2 = f_n^2`` at latitudes ``lats`` (rad).
    The azimuths start at ``twist`` in an arbitrary tangent basis.
    """
    w = []
    for p, n in zip(points, normals, strict=True):
        n = n / np.linalg.norm(n)
        t1, t2 = basis(n)
        for lat in lats:
            for k in range(n_az):
                th = twist + 2 * math.pi * k / n_az
                f = n + mu * math.cos(lat) * (math.cos(th) * t1 + math.sin(th) * t2)
                tau = torsion * math.sin(lat)
                w.append(np.concatenate([f, (np.cross(p, f) + tau * n) / ts]))
        if torsion > 0:
            for s in (1.0, -1.0):
                w.append(np.concatenate([n, (np.cross(p, n) + s * torsion * n) / ts]))
    return np.array(w)


def soft_grasp(rng, k=None):
    p, n, mu = random_grasp(rng, k=int(rng.integers(2, 6)) if k is None else k)
    torsion = float(rng.uniform(0.001, MAX_TORSION))
    return p, n, mu, torsion


def soft_bound(k, mu):
    """Q <= sqrt(6 k (1 + mu^2)) eps, as for point contacts."""
    return math.sqrt(6 * k * (1 + mu * mu))


# ---------------------------------------------------------------------------
# Soft model against the hull of its generators
# ---------------------------------------------------------------------------


def test_soft_wrenches_are_the_design_generators() -> None:
    rng = np.random.default_rng(20)
    for _ in range(20):
        p, n, mu, torsion = soft_grasp(rng)
        ts = torque_scale(p)
        ours = contact_wrenches(p, n, mu, EDGES, ts, contact_model="soft", torsion=torsion)
        np.testing.assert_allclose(
            ours, ref_soft_wrenches(p, n, mu, EDGES, torsion, ts), atol=1e-12
        )
        if mu == 0.0:
            continue
        # every generator x = (f, tau / L) is in the facets' cone, on its boundary
        rows = soft_finger_facets(n, mu, torsion, EDGES, ts)
        for c, u in enumerate(ref_edges(n, mu, EDGES)):
            nc = n[c] / np.linalg.norm(n[c])
            x = np.vstack(
                [np.hstack([u, np.zeros((EDGES, 1))]), [[*nc, torsion / ts], [*nc, -torsion / ts]]]
            )
            a_x = rows[c] @ x.T  # (2 E facets, E + 2 generators)
            assert a_x.max() <= 1e-12
            np.testing.assert_allclose(a_x.max(axis=0), 0.0, atol=1e-12)


def test_soft_agrees_with_hull_reference_on_1000_random_grasps() -> None:
    rng = np.random.default_rng(21)
    n_fc = n_not = n_skip = n_two = 0
    for _ in range(1000):
        p, n, mu, torsion = soft_grasp(rng)
        ts = torque_scale(p)
        kw = {"edges": EDGES, "torque_scale": ts, "contact_model": "soft", "torsion": torsion}
        signed = hull_epsilon(ref_soft_wrenches(p, n, mu, EDGES, torsion, ts))
        q = force_closure_quality(p, n, mu, **kw)
        assert q >= 0.0
        assert (q > 0) == is_force_closure(p, n, mu, **kw)
        if signed < -1e-9:
            assert q == 0.0, (p, n, mu, torsion, q)
            n_not += 1
        elif signed > 1e-3:
            t = torsion / ts
            assert q > 0.0, (p, n, mu, torsion, signed)
            # eps / sqrt(1 + t^2) <= Q <= sqrt(6 k (1 + mu^2)) eps
            assert signed / math.sqrt(1 + t * t) <= q * (1 + 1e-6)
            assert q <= soft_bound(len(p), mu) * signed * (1 + 1e-6)
            n_fc += 1
            n_two += len(p) == 2
        else:
            n_skip += 1
    assert n_fc >= 250 and n_not >= 250, (n_fc, n_not, n_skip)
    assert n_two >= 5  # two soft contacts can be force closure
    assert n_skip <= 50


def test_soft_bounds_against_the_12_direction_lp() -> None:
    """q / sqrt(1 + t^2) <= Q <= sqrt(k (1 + mu^2)) q and q / sqrt(6) <= eps <= q."""
    rng = np.random.default_rng(22)
    checked = 0
    while checked < 60:
        p, n, _ = random_grasp(rng, k=int(rng.integers(2, 6)), mu=float(rng.uniform(0.2, 1.5)))
        mu = float(rng.uniform(0.2, 1.5))
        torsion = float(rng.uniform(0.001, MAX_TORSION))
        ts = torque_scale(p)
        q_ours = force_closure_quality(
            p, n, mu, edges=EDGES, torque_scale=ts, contact_model="soft", torsion=torsion
        )
        if q_ours == 0.0:
            continue
        w = ref_soft_wrenches(p, n, mu, EDGES, torsion, ts)
        q_lp, eps = lp_quality(w), hull_epsilon(w)
        t = torsion / ts
        assert q_lp / math.sqrt(1 + t * t) * (1 - 1e-6) <= q_ours
        assert q_ours <= math.sqrt(len(p) * (1 + mu * mu)) * q_lp * (1 + 1e-6)
        assert q_lp / math.sqrt(6) * (1 - 1e-6) <= eps <= q_lp * (1 + 1e-6)
        checked += 1


def test_soft_is_never_below_point_and_point_is_unchanged() -> None:
    """The point cone is the soft cone's face sigma = 0: Q(soft) >= Q(point)."""
    rng = np.random.default_rng(23)
    exact = ForceClosure(solver="nnls")  # deterministic: no OSQP warm starts
    for _ in range(200):
        p, n, mu, torsion = soft_grasp(rng, k=int(rng.integers(3, 6)))
        ts = torque_scale(p)
        q_point = exact.quality(p, n, mu, torque_scale=ts)
        assert q_point == exact.quality(p, n, mu, torque_scale=ts, contact_model="point")
        q_soft = exact.quality(p, n, mu, torque_scale=ts, contact_model="soft", torsion=torsion)
        assert q_point <= q_soft * (1 + 1e-6) + 1e-12


def test_two_opposed_soft_contacts_are_force_closure_only_thanks_to_torsion() -> None:
    p, n = sphere([[0, 0, 1], [0, 0, -1]])
    soft = {"torque_scale": 0.04, "contact_model": "soft", "torsion": 0.005}
    assert force_closure_quality(p, n, 0.8, **soft) > 0.05
    assert is_force_closure(p, n, 0.8, **soft)
    assert exact_force_closure(p, n, 0.8, **soft) == "fc_linear"
    assert force_closure_quality(p, n, 0.8, torque_scale=0.04) == 0.0
    assert exact_force_closure(p, n, 0.8, torque_scale=0.04) == "not_fc"
    # not opposed enough for the friction cones (the pinch line leaves them)
    p2, n2 = sphere([[0, 0, 1], [math.sin(1.5), 0, math.cos(1.5)]])  # 86 deg apart
    assert force_closure_quality(p2, n2, 0.8, **soft) == 0.0
    # frictionless soft contacts: 4 at least (two generators each), never 3
    assert min_contacts(0.0, "soft") == 4 and min_contacts(0.8, "soft") == 2
    assert min_contacts(0.8, "point") == 3 and min_contacts(0.0, "point") == 7
    p3, n3 = sphere(TETRA[:3])
    assert force_closure_quality(p3, n3, 0.0, contact_model="soft", torsion=0.01) == 0.0


def test_soft_subgrasps_of_three_contacts() -> None:
    """A 3-contact soft grasp whose 2-contact subgrasps are FC (equatorial, 120 deg)."""
    tri = [[math.cos(a), math.sin(a), 0.0] for a in (0.0, 2.1, 4.2)]
    p, n = sphere(tri)
    soft = {"torque_scale": 0.04, "contact_model": "soft", "torsion": 0.005}
    m = min_subgrasp_quality(p, n, 1.0, **soft)
    subs = [
        force_closure_quality(np.delete(p, i, 0), np.delete(n, i, 0), 1.0, **soft) for i in range(3)
    ]
    assert m > 0.0 and m == pytest.approx(min(subs), rel=1e-6)
    assert min_subgrasp_quality(p, n, 1.0, torque_scale=0.04) == 0.0
    assert is_force_closure(p, n, 1.0, subgrasps=True, **soft)
    assert exact_force_closure(p, n, 1.0, subgrasps=True, **soft) == "fc_linear"


# ---------------------------------------------------------------------------
# Exact sets: round cone and elliptic set, against dense samples
# ---------------------------------------------------------------------------


def test_exact_sets_against_dense_samples() -> None:
    """The verdict never contradicts a hull of points of the exact sets.

    Sampled points lie in the exact set, so a sample hull that is force closure
    means the exact set is: the verdict must not be ``not_fc`` (which claims
    not FC even for a polytope containing the exact set). A rotated 8-edge
    pyramid (a pyramid in another tangent basis) is such a sample for point
    contacts.
    """
    rng = np.random.default_rng(24)
    counts = {"fc_linear": 0, "fc_dense": 0, "undecided": 0, "not_fc": 0}
    rescued = 0
    for i in range(300):
        soft = i % 2 == 1
        p, n, mu = random_grasp(rng, k=int(rng.integers(2 if soft else 3, 5)))
        mu = max(mu, 0.1)
        torsion = float(rng.uniform(0.002, 0.02)) if soft else 0.0
        ts = torque_scale(p)
        model = {"contact_model": "soft", "torsion": torsion} if soft else {}
        verdict = exact_force_closure(p, n, mu, torque_scale=ts, **model)
        counts[verdict] += 1
        lats = (-1.0, -0.5, 0.0, 0.5, 1.0) if soft else (0.0,)
        twist = float(rng.uniform(0, 2 * math.pi))
        eps = hull_epsilon(ellipse_samples(p, n, mu, torsion, ts, 8, lats, twist))
        if eps > 1e-9:
            assert verdict != "not_fc", (p, n, mu, torsion, eps)
        linear = force_closure_quality(p, n, mu, torque_scale=ts, **model) > 0.0
        assert (verdict == "fc_linear") == linear
        rescued += verdict == "fc_dense"
    assert counts["not_fc"] >= 50 and counts["fc_linear"] >= 50, counts
    assert counts["undecided"] <= 6, counts  # 2 %: the gap between dense inner and outer
    assert rescued >= 1, counts  # some grasps are FC for the exact set only


def test_exact_round_cone_rescues_a_rotated_pyramid() -> None:
    """Near the boundary the 8-edge verdict depends on the pyramid's turn; the
    round cone does not (a plan's force closure is judged against the round cone)."""
    rng = np.random.default_rng(25)
    found = 0
    for _ in range(3000):
        p, n, _ = random_grasp(rng, k=3, kind="sphere")
        ts = torque_scale(p)
        if force_closure_quality(p, n, 0.5, torque_scale=ts) > 0.0:
            continue
        eps = hull_epsilon(ellipse_samples(p, n, 0.5, 0.0, ts, 8, (0.0,), math.pi / 8))
        if eps > 1e-6:  # FC for another basis: FC for the round cone
            assert exact_force_closure(p, n, 0.5, torque_scale=ts) in ("fc_dense", "undecided")
            found += 1
    assert found >= 3


# ---------------------------------------------------------------------------
# Inputs and the let-go rule
# ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("model", "torsion", "needle"),
    [
        ("soft", 0.0, "torsion"),
        ("soft", -0.01, "torsion"),
        ("soft", 0.06, "torsion"),
        ("soft", math.nan, "torsion"),
        ("point", 0.01, "soft contacts only"),
        ("hard", 0.0, "contact_model"),
    ],
)
def test_bad_contact_models(model, torsion, needle) -> None:
    p, n = sphere(TETRA)
    with pytest.raises(InvalidInputError, match=needle):
        force_closure_quality(p, n, 0.8, contact_model=model, torsion=torsion)
    with pytest.raises(InvalidInputError, match=needle):
        ValiditySettings(contact_model=model, torsion=torsion)


def test_let_go_rule() -> None:
    point, soft = ValiditySettings(), ValiditySettings(contact_model="soft", torsion=0.005)
    msg = let_go_problem(3, point)
    assert msg is not None
    assert "no 2-finger subgrasp is force closure" in msg
    assert "the torque about the line through the two contacts is free" in msg
    assert '[contact] model = "soft" (with torsion > 0), or a fourth finger' in msg
    assert let_go_problem(4, point) is None and let_go_problem(3, soft) is None
    assert "at least 3 fingers" in let_go_problem(2, soft)
    assert "at least 4 fingers" in let_go_problem(2, point)
    frictionless = ValiditySettings(mu=0.0, contact_model="soft", torsion=0.005)
    assert "contact.mu > 0" in let_go_problem(4, frictionless)
    assert let_go_problem(5, frictionless) is None
    assert let_go_problem(3, ValiditySettings(subgrasps=False)) is None


# ---------------------------------------------------------------------------
# Scenario, context, CLI
# ---------------------------------------------------------------------------


def test_scenario_contact_fields(tmp_path: Path) -> None:
    s = load_scenario(SOFT)
    assert s.contact_model == "soft" and s.torsion == 0.005 and s.hand.builtin == "three_finger"
    assert load_scenario(SCENARIOS / "paper_sphere.toml").contact_model == "point"
    text = SOFT.read_text()
    for old, new, needle in [
        ("torsion = 0.005", "", "needs contact.torsion"),
        ("torsion = 0.005", "torsion = 0.0", "contact.torsion"),
        ("torsion = 0.005", "torsion = 0.5", "contact.torsion"),
        ('model = "soft"', 'model = "hard"', "contact.model"),
        ('model = "soft"', 'model = "point"', "contact.torsion applies"),
    ]:
        bad = tmp_path / "bad.toml"
        bad.write_text(text.replace(old, new))
        with pytest.raises(ScenarioError, match=needle):
            load_scenario(bad)


def test_point_contacts_three_fingers_refused_when_the_context_is_built() -> None:
    scenario = load_scenario(POINT)
    with pytest.raises(ScenarioError, match="fourth finger"):
        build_context(scenario)
    with pytest.raises(ScenarioError, match="no 2-finger subgrasp"):
        build_hand(scenario)
    assert build_hand(scenario, check_contacts=False).n_fingers == 3


def test_cli_refuses_point_contacts_on_three_fingers(capfd, tmp_path: Path) -> None:
    out = tmp_path / "plan.json"
    code, _, err = run_cli(capfd, "plan", POINT, "--time-limit", "300", "-o", out)
    assert_bad_input(
        code,
        err,
        names=(
            "no 2-finger subgrasp is force closure",
            "the torque about the line through the two contacts is free",
            '[contact] model = "soft" (with torsion > 0), or a fourth finger',
        ),
        outputs=(out,),
    )


# ---------------------------------------------------------------------------
# Plan files and verify
# ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def soft_plan():
    scenario = load_scenario(SOFT)
    result = plan(scenario, seed=3, time_limit=300.0)
    assert result.solved, (result.status, result.message)
    return scenario, build_plan_document(scenario, build_hand(scenario), result)


def test_soft_plan_round_trip_and_verify(soft_plan, tmp_path: Path) -> None:
    _, doc = soft_plan
    assert doc["contact_model"] == "soft" and doc["torsion"] == 0.005
    path = tmp_path / "plan.json"
    write_plan(path, doc)
    back = read_plan(path)
    assert back["contact_model"] == "soft" and back["torsion"] == 0.005
    report = verify_plan(back)
    assert report.ok, [str(v) for v in report.violations[:5]]


def test_verify_rejects_a_soft_plan_claimed_point(soft_plan) -> None:
    _, doc = soft_plan
    bad = copy.deepcopy(doc)
    bad["contact_model"], bad["torsion"] = "point", 0.0
    report = verify_plan(bad)
    rules = {v.rule for v in report.violations}
    assert not report.ok and rules & {"force_closure", "subgrasp_force_closure"}, rules
    assert any("point contacts" in v.message for v in report.violations)
    # absent fields mean point contacts, torsion 0: rejected the same way
    for key in ("contact_model", "torsion"):
        bad.pop(key)
    assert {v.rule for v in verify_plan(bad).violations} == rules


def test_plan_schema_contact_fields(soft_plan) -> None:
    _, doc = soft_plan
    for model, torsion, needle in [
        ("soft", 0.0, "torsion"),
        ("soft", 0.2, "torsion"),
        ("point", 0.005, "torsion must be 0"),
        ("rigid", 0.0, "contact_model"),
    ]:
        bad = copy.deepcopy(doc)
        bad["contact_model"], bad["torsion"] = model, torsion
        with pytest.raises(PlanFileError, match=needle):
            validate_plan(bad)
    bad = copy.deepcopy(doc)
    bad.pop("torsion")
    with pytest.raises(PlanFileError, match="torsion"):
        validate_plan(bad)
