"""Vectorised and closed-form finger IK (dexplan.model.hand.ik) against forward kinematics."""

import numpy as np
import pytest

from dexplan.model.hand.hand import Hand
from dexplan.model.hand.ik import (
    TRACK_RESOLUTION,
    FingerChain,
    SplitFingerIK,
    batch_dls,
    nearest_branch,
    planar_branches,
)


@pytest.fixture(scope="module", params=["paper", "allegro", "allegro_left", "three_finger"])
def hand(request) -> Hand:
    return Hand.builtin(request.param)


def _random_q(hand: Hand, finger: int, n: int, seed: int) -> np.ndarray:
    idx = hand.finger_q_index[finger]
    rng = np.random.default_rng(seed)
    return rng.uniform(hand.lower[idx], hand.upper[idx], size=(n, len(idx)))


def _pin_tip(hand: Hand, finger: int, q_f: np.ndarray) -> np.ndarray:
    q = hand.neutral.copy()
    q[hand.finger_q_index[finger]] = q_f
    return hand.fingertip_positions(q)[finger]


def test_chain_forward_kinematics_matches_pinocchio(hand: Hand) -> None:
    for i in range(hand.n_fingers):
        chain = FingerChain.from_model(hand.model, hand.tip_frame_ids[i])
        assert chain is not None
        qs = _random_q(hand, i, 30, i)
        ref = np.array([_pin_tip(hand, i, q) for q in qs])
        np.testing.assert_allclose(chain.tips(qs), ref, atol=1e-12)
        np.testing.assert_allclose(chain.forward(qs)[0], ref, atol=1e-12)


def test_chain_jacobian_matches_finite_differences(hand: Hand) -> None:
    eps = 1e-6
    for i in range(hand.n_fingers):
        chain = FingerChain.from_model(hand.model, hand.tip_frame_ids[i])
        qs = _random_q(hand, i, 10, 10 + i)
        _, J = chain.jacobian(qs)
        for k in range(chain.m):
            dq = np.zeros(chain.m)
            dq[k] = eps
            fd = (chain.tips(qs + dq) - chain.tips(qs - dq)) / (2 * eps)
            np.testing.assert_allclose(J[:, :, k], fd, atol=1e-8)
        # and Pinocchio's Jacobian
        q = hand.neutral.copy()
        q[hand.finger_q_index[i]] = qs[0]
        _, jacs = hand.fingertip_jacobians(q)
        np.testing.assert_allclose(J[0], jacs[i], atol=1e-12)


def test_allegro_fingers_have_closed_form() -> None:
    hand = Hand.builtin("allegro")
    for i in range(hand.n_fingers):
        assert hand.has_closed_form_ik(i)
    split = [hand.split_ik(i) for i in range(hand.n_fingers)]
    assert [None if s is None else s.free for s in split] == [
        3,
        3,
        3,
        0,
    ]  # distal joints free; thumb's first joint


def test_closed_form_reaches_targets_within_limits(hand: Hand) -> None:
    for i in range(hand.n_fingers):
        idx = hand.finger_q_index[i]
        qs = _random_q(hand, i, 60, 20 + i)
        chain = FingerChain.from_model(hand.model, hand.tip_frame_ids[i])
        targets = chain.tips(qs)
        q_b, ok = hand.finger_ik_batch(i, targets)
        assert ok.mean() > 0.85, (i, ok.mean())  # grid values of a free joint miss a few
        assert np.all(q_b >= hand.lower[idx] - 1e-12) and np.all(q_b <= hand.upper[idx] + 1e-12)
        for q_f, t in zip(q_b[ok], targets[ok], strict=True):
            assert np.linalg.norm(_pin_tip(hand, i, q_f) - t) < 1e-6
        cand, ok_c = hand.finger_ik_candidates(i, targets)
        assert cand.shape[:2] == ok_c.shape and cand.shape[2] == len(idx)
        assert np.all(ok_c.any(axis=1) >= ok)
        tips = chain.tips(cand[ok_c])
        rows = np.nonzero(ok_c)[0]
        assert np.max(np.linalg.norm(tips - targets[rows], axis=1)) < 1e-6
        assert np.all(cand[ok_c] >= hand.lower[idx] - 1e-12)
        assert np.all(cand[ok_c] <= hand.upper[idx] + 1e-12)


def test_batch_equals_single(hand: Hand) -> None:
    for i in range(hand.n_fingers):
        chain = FingerChain.from_model(hand.model, hand.tip_frame_ids[i])
        targets = chain.tips(_random_q(hand, i, 20, 40 + i))
        q_b, ok_b = hand.finger_ik_batch(i, targets)
        for k in range(len(targets)):
            q_1, ok_1 = hand.finger_ik_batch(i, targets[k : k + 1])
            assert ok_1[0] == ok_b[k]
            np.testing.assert_allclose(q_1[0], q_b[k], atol=1e-12)


def test_tracking_is_exact_and_continuous() -> None:
    """A contact moved in small steps: finger_ik_fast stays near the previous joints."""
    hand = Hand.builtin("allegro")
    for i in range(hand.n_fingers):
        idx = hand.finger_q_index[i]
        chain = FingerChain.from_model(hand.model, hand.tip_frame_ids[i])
        split = hand.split_ik(i)
        # a start on the free joint's table, mid-range
        q0 = 0.5 * (hand.lower[idx] + hand.upper[idx])
        q0[split.free] = split.table[len(split.table) // 2]
        q = hand.neutral.copy()
        q[idx] = q0
        start = chain.tips(q0[None])[0]
        direction = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
        for step in range(1, 40):
            target = start + direction * 2e-4 * step  # 0.2 mm steps
            q_f = hand.finger_ik_fast(i, target, q)
            if q_f is None:
                break
            assert np.linalg.norm(_pin_tip(hand, i, q_f) - target) < 1e-6
            assert np.max(np.abs(q_f - q[idx])) < 0.05  # no branch jumps
            assert abs(q_f[split.free] - q[idx][split.free]) <= 8 * TRACK_RESOLUTION + 1e-9
            q[idx] = q_f
        else:
            step = 40
        assert step > 10, (i, step)


@pytest.mark.parametrize("name", ["allegro", "allegro_left"])
def test_scalar_tracking_equals_the_vectorised_path(name: str) -> None:
    """solve_near's scalar arithmetic picks what the NumPy candidates would.

    The same targets solved by a copy of the solver without its scalar table
    (``_rows`` empty: candidates, best posture and nearest solution in NumPy,
    last-link direction by forward kinematics): same answers to 1e-12, with
    and without an approach direction, including far targets (grid search).
    """
    import copy

    hand = Hand.builtin(name)
    rng = np.random.default_rng(7)
    for i in range(hand.n_fingers):
        split = hand.split_ik(i)
        assert split._rows, "the Allegro fingers have the scalar tracker"
        vectorised = copy.copy(split)
        vectorised._rows = []
        q = _random_q(hand, i, 300, seed=i)
        q[:, split.free] = split.table[rng.integers(0, len(split.table), len(q))]
        # small steps (tracking), 5 mm (the step bound binds) and 5 cm (far targets)
        noise = np.concatenate([np.full(150, 5e-4), np.full(100, 5e-3), np.full(50, 5e-2)])
        targets = split.chain.tips(q) + rng.normal(size=(len(q), 3)) * noise[:, None]
        approach = rng.normal(size=(len(q), 3))
        approach /= np.linalg.norm(approach, axis=1, keepdims=True)
        found = 0
        for k in range(len(q)):
            for app in (approach[k], None):
                a = split.solve_near(targets[k], q[k], app)
                b = vectorised.solve_near(targets[k], q[k], app)
                assert (a is None) == (b is None), (i, k)
                if a is not None:
                    found += 1
                    np.testing.assert_allclose(a, b, atol=1e-12)
                    assert np.linalg.norm(split.chain.tips(a[None])[0] - targets[k]) < 1e-9
        assert found > 300


def test_directions_match_forward_kinematics() -> None:
    """SplitFingerIK.directions from the plane angles equals FK's last link and flexion axis."""
    hand = Hand.builtin("allegro")
    rng = np.random.default_rng(3)
    for i in range(hand.n_fingers):
        split = hand.split_ik(i)
        q = _random_q(hand, i, 200, seed=10 + i)
        on_table = q.copy()
        on_table[:, split.free] = split.table[rng.integers(0, len(split.table), len(q))]
        for qs in (on_table, q):  # the second: off the table, by FK
            last, normal = split.directions(qs)
            tip, origins, axes = split.chain.forward(qs)
            d = tip - origins[:, -1]
            np.testing.assert_allclose(last, d / np.linalg.norm(d, axis=1)[:, None], atol=1e-12)
            np.testing.assert_allclose(normal, axes[:, split.sub[1]], atol=1e-12)


def test_finger_ik_nearest_to_q_init() -> None:
    """Hand.finger_ik on a redundant finger returns the solution nearest q_init."""
    hand = Hand.builtin("allegro")
    i, idx = 0, hand.finger_q_index[0]
    split = hand.split_ik(0)
    q_f = np.array([0.1, 0.6, 0.7, split.table[200]])
    q = hand.neutral.copy()
    q[idx] = q_f
    res = hand.finger_ik(i, _pin_tip(hand, i, q_f), q)
    assert res.success
    np.testing.assert_allclose(res.q_finger, q_f, atol=1e-9)


def test_batch_dls_reaches_targets_within_limits(hand: Hand) -> None:
    for i in range(hand.n_fingers):
        idx = hand.finger_q_index[i]
        lo, hi = hand.lower[idx], hand.upper[idx]
        chain = FingerChain.from_model(hand.model, hand.tip_frame_ids[i])
        qs = _random_q(hand, i, 40, 60 + i)
        targets = chain.tips(qs)
        # started near the answer, as when following a contact
        q, ok = batch_dls(chain, targets, np.clip(qs + 0.05, lo, hi), lo, hi)
        assert ok.mean() > 0.9
        assert np.all(q >= lo) and np.all(q <= hi)
        err = np.linalg.norm(chain.tips(q[ok]) - targets[ok], axis=1)
        assert np.all(err < 1e-6)
        # batch equals single
        for k in range(5):
            q1, ok1 = batch_dls(chain, targets[k : k + 1], np.clip(qs[k] + 0.05, lo, hi), lo, hi)
            assert ok1[0] == ok[k]
            np.testing.assert_allclose(q1[0], q[k], atol=1e-12)


def test_unreachable_targets_fail_cleanly() -> None:
    hand = Hand.builtin("allegro")
    far = np.array([[0.0, 0.0, 1.0], [0.5, 0.5, 0.5]])
    for i in range(hand.n_fingers):
        idx = hand.finger_q_index[i]
        q, ok = hand.finger_ik_batch(i, far)
        assert not ok.any()
        assert np.all(q >= hand.lower[idx]) and np.all(q <= hand.upper[idx])
        assert hand.finger_ik_fast(i, far[0], hand.neutral) is None
        res = hand.finger_ik(i, far[0])
        assert not res.success


def test_split_detect_rejects_other_structures() -> None:
    """A chain whose joints are not an axis + planar 2R gets no closed form."""
    hand = Hand.builtin("allegro")
    chain = FingerChain.from_model(hand.model, hand.tip_frame_ids[3])
    idx = hand.finger_q_index[3]
    # the thumb split the other way (first three joints, last free) is not planar
    solver = SplitFingerIK(chain, hand.lower[idx], hand.upper[idx], (0, 1, 2), 3)
    assert not solver._verified()


def test_planar_branches_pick_what_the_scalar_solver_picks() -> None:
    """Batched branches + nearest_branch give bit for bit the closed-form solver's answer."""
    hand = Hand.builtin("paper")
    rng = np.random.default_rng(4)
    for f in range(hand.n_fingers):
        solver = hand.planar_ik(f)
        assert solver is not None
        idx = hand.finger_q_index[f]
        qs = rng.uniform(hand.lower, hand.upper, size=(300, hand.nq))
        tips = np.array([hand.fingertip_positions(q)[f] for q in qs])
        tips += rng.normal(0.0, 0.01, tips.shape)  # some unreachable
        q, ok, q_clip = planar_branches(solver, tips)
        near = rng.uniform(hand.lower[idx], hand.upper[idx], size=(len(tips), 3))
        for i in range(len(tips)):
            a = solver.solve(tips[i], near[i])
            b = nearest_branch(q[i], ok[i], q_clip[i], near[i])
            assert (a is None) == (b is None)
            if a is not None:
                assert np.array_equal(a, b)
