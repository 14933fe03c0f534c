import dataclasses

import numpy as np
import pytest

from dexplan.core.errors import DexplanError, InvalidInputError, ModelError
from dexplan.model.hand.hand import Hand


@pytest.fixture(scope="module")
def hand() -> Hand:
    return Hand.builtin("paper")


def test_paper_hand_structure(hand: Hand) -> None:
    assert hand.n_fingers == 4
    assert hand.nq == 12
    for i, idx in enumerate(hand.finger_q_index):
        assert list(idx) == [3 * i, 3 * i + 1, 3 * i + 2]
    assert hand.joint_names[:3] == ("f0_abd", "f0_mcp", "f0_pip")
    assert np.all(hand.lower < hand.upper)
    assert hand.within_limits(hand.neutral)
    # every link carries collision geometry
    links = {hand.model.frames[g.parentFrame].name for g in hand.geom_model.geometryObjects}
    for i in range(4):
        for part in ("knuckle", "proximal", "distal", "tip"):
            assert f"f{i}_{part}" in links
    assert "palm" in links


def test_jacobians_match_finite_differences(hand: Hand) -> None:
    rng = np.random.default_rng(0)
    eps = 1e-6
    for _ in range(20):
        q = rng.uniform(hand.lower, hand.upper)
        p, jacs = hand.fingertip_jacobians(q)
        np.testing.assert_allclose(p, hand.fingertip_positions(q), atol=1e-12)
        for i, idx in enumerate(hand.finger_q_index):
            fd = np.empty((3, len(idx)))
            for k, j in enumerate(idx):
                qp, qm = q.copy(), q.copy()
                qp[j] += eps
                qm[j] -= eps
                fd[:, k] = (hand.fingertip_positions(qp)[i] - hand.fingertip_positions(qm)[i]) / (
                    2 * eps
                )
            np.testing.assert_allclose(jacs[i], fd, atol=1e-8)
            # other fingers' joints do not move this tip
            others = np.setdiff1d(np.arange(hand.nq), idx)
            qp = q.copy()
            qp[others] += 0.1
            np.testing.assert_allclose(hand.fingertip_positions(qp)[i], p[i], atol=1e-12)


def _ik_of_reachable_targets(hand: Hand, seed: int, rounds: int):
    """``(finger, target, finger_ik result)`` for the tips of random joint values."""
    rng = np.random.default_rng(seed)
    for _ in range(rounds):
        q = rng.uniform(hand.lower, hand.upper)
        target = hand.fingertip_positions(q)
        for i in range(hand.n_fingers):
            yield i, target[i], hand.finger_ik(i, target[i])


def test_ik_round_trip_on_reachable_targets(hand: Hand) -> None:
    for i, target, res in _ik_of_reachable_targets(hand, 1, 40):
        assert res.success, (i, target, res)
        q2 = hand.neutral.copy()
        q2[hand.finger_q_index[i]] = res.q_finger
        assert np.linalg.norm(hand.fingertip_positions(q2)[i] - target) < 1e-6
        assert hand.within_limits(q2)


def test_ik_unreachable_fails_cleanly(hand: Hand) -> None:
    far = np.array([0.0, 0.0, 1.0])
    res = hand.finger_ik(0, far)
    assert not res.success
    assert res.residual > 0.5
    q = hand.neutral.copy()
    q[hand.finger_q_index[0]] = res.q_finger
    assert hand.within_limits(q)
    # deterministic
    res2 = hand.finger_ik(0, far)
    np.testing.assert_array_equal(res.q_finger, res2.q_finger)


def test_ik_bad_inputs(hand: Hand) -> None:
    with pytest.raises(InvalidInputError, match="finger"):
        hand.finger_ik(7, [0, 0, 0.1])
    with pytest.raises(InvalidInputError, match="p_target_world"):
        hand.finger_ik(0, [0, np.nan, 0.1])
    with pytest.raises(InvalidInputError, match="p_target_world"):
        hand.finger_ik(0, [0, 0.1])
    with pytest.raises(InvalidInputError, match="q_init"):
        hand.finger_ik(0, [0, 0, 0.1], q_init=np.zeros(3))


def test_bad_models_raise_typed_errors(hand: Hand, tmp_path) -> None:
    with pytest.raises(ModelError, match="nope"):
        Hand(hand.urdf_xml, ["f0_tip", "nope"], 0.012)
    with pytest.raises(ModelError):
        Hand("<robot name='x'><link name='a'/>", ["a", "b"], 0.012)
    with pytest.raises(ModelError, match="fingertip_radius"):
        Hand(hand.urdf_xml, ["f0_tip", "f1_tip"], -1.0)
    with pytest.raises(ModelError, match="not found"):
        Hand.from_urdf_file(tmp_path / "missing.urdf", ["a", "b"], 0.01)
    with pytest.raises(InvalidInputError, match=r"hand\.builtin"):
        Hand.builtin("shadow")
    assert issubclass(ModelError, DexplanError)


def test_load_from_file_with_subset_of_fingers(hand: Hand, tmp_path) -> None:
    path = tmp_path / "h.urdf"
    path.write_text(hand.urdf_xml)
    h3 = Hand.from_urdf_file(path, ["f0_tip", "f1_tip", "f2_tip"], 0.012)
    assert h3.n_fingers == 3
    assert h3.nq == 12


def test_damped_least_squares_path_without_closed_form() -> None:
    h = Hand.builtin("paper")
    assert all(h.planar_ik(i) is not None for i in range(h.n_fingers))  # closed form built in
    h._ik_solvers = dataclasses.replace(h._ik, analytic=(None,) * h.n_fingers)
    for i, _, res in _ik_of_reachable_targets(h, 2, 15):
        assert res.success and res.residual < 1e-6, (i, res)


def test_batch_ik_matches_forward_kinematics(hand: Hand) -> None:
    rng = np.random.default_rng(3)
    for i in range(hand.n_fingers):
        idx = hand.finger_q_index[i]
        qs = rng.uniform(hand.lower[idx], hand.upper[idx], size=(50, len(idx)))
        targets = []
        for qf in qs:
            q = hand.neutral.copy()
            q[idx] = qf
            targets.append(hand.fingertip_positions(q)[i])
        targets.append([0.0, 0.0, 1.0])  # unreachable
        q_sol, ok = hand.finger_ik_batch(i, np.array(targets))
        assert ok[:-1].all() and not ok[-1]
        for qf, t in zip(q_sol[:-1], targets[:-1], strict=True):
            q = hand.neutral.copy()
            q[idx] = qf
            assert np.linalg.norm(hand.fingertip_positions(q)[i] - t) < 1e-8
            assert hand.within_limits(q)


def test_reach_voxels_are_the_box_dilation_of_the_sampled_tips() -> None:
    """Each sampled fingertip's voxel and its 26 neighbours, as scipy's morphology gives them."""
    from scipy.ndimage import binary_dilation

    from dexplan.model.hand.reach import ReachVoxels

    rng = np.random.default_rng(3)
    tips = np.vstack([rng.normal(0.0, 0.03, size=(500, 3)), [[0.1, -0.05, 0.02]]])
    vox = ReachVoxels.from_tips(tips, 0.004)
    ijk = np.floor((tips - vox.origin) / vox.size).astype(np.int64)
    seeds = np.zeros(vox.occupied.shape, dtype=bool)
    seeds[tuple(ijk.T)] = True
    want = binary_dilation(seeds, structure=np.ones((3, 3, 3), dtype=bool))
    assert np.array_equal(vox.occupied, want)
    # a lone tip: exactly its 27 voxels
    lone = ReachVoxels.from_tips(np.array([[0.0, 0.0, 0.0]]), 0.004)
    assert int(lone.occupied.sum()) == 27
