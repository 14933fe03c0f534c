"""IK with every branch: the offset-axes closed form (TriFinger) and seeded numerical solves."""

from __future__ import annotations

import numpy as np
import pytest

from dexplan.model.hand.hand import Hand
from dexplan.model.hand.ik import OffsetFingerIK, branch_solutions


@pytest.fixture(scope="module")
def trifinger() -> Hand:
    return Hand.builtin("trifinger")


def _reachable(hand: Hand, finger: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    idx = hand.finger_q_index[finger]
    q = np.random.default_rng(3).uniform(hand.lower[idx], hand.upper[idx], (n, len(idx)))
    chain = hand.finger_chain(finger)
    assert chain is not None
    return q, chain.tips(q)


def test_trifinger_fingers_get_the_offset_closed_form(trifinger: Hand) -> None:
    for f in range(3):
        assert trifinger.has_closed_form_ik(f)
        assert trifinger.planar_ik(f) is None and trifinger.split_ik(f) is None


def test_offset_branches_reach_the_target_and_include_the_generating_posture(
    trifinger: Hand,
) -> None:
    q_true, tips = _reachable(trifinger, 1, 300)
    q, ok = trifinger.finger_ik_candidates(1, tips)
    assert q.shape == (300, 4, 3) and ok.any(axis=1).all()
    chain = trifinger.finger_chain(1)
    assert chain is not None
    err = np.linalg.norm(chain.tips(q[ok]) - np.repeat(tips, 4, axis=0)[ok.ravel()], axis=1)
    assert err.max() < 1e-9
    # the posture the target came from is one of the branches
    d = np.abs(q - q_true[:, None, :]).max(axis=2)
    assert (np.where(ok, d, np.inf).min(axis=1) < 1e-6).all()
    # knee in and knee out: most targets have two postures within the limits
    assert (ok.sum(axis=1) >= 2).mean() > 0.5


def test_seeded_numerical_solves_find_several_branches(trifinger: Hand) -> None:
    """Without the closed form, seeded DLS still finds both postures of most targets."""
    idx = trifinger.finger_q_index[0]
    chain = trifinger.finger_chain(0)
    assert chain is not None
    _, tips = _reachable(trifinger, 0, 100)
    q, ok = branch_solutions(chain, tips, trifinger.lower[idx], trifinger.upper[idx])
    assert ok.any(axis=1).mean() > 0.95
    assert (ok.sum(axis=1) >= 2).mean() > 0.5
    err = np.linalg.norm(
        chain.tips(q[ok]) - np.repeat(tips, q.shape[1], axis=0)[ok.ravel()], axis=1
    )
    assert err.max() < 1e-6
    # kept solutions are distinct
    for row, keep in zip(q, ok, strict=True):
        sols = row[keep]
        for a in range(len(sols)):
            for b in range(a + 1, len(sols)):
                assert np.abs(sols[a] - sols[b]).max() >= 1e-3


def test_offset_solver_is_exact_wherever_it_is_detected() -> None:
    paper = Hand.builtin("paper")
    idx = paper.finger_q_index[0]
    chain = paper.finger_chain(0)
    # the paper hand's planar fingers are the zero-offset case of this geometry
    solver = OffsetFingerIK.detect(chain, paper.lower[idx], paper.upper[idx])
    if solver is not None:
        _, tips = _reachable(paper, 0, 50)
        q, ok = solver.branches(tips)
        assert chain is not None
        err = np.linalg.norm(chain.tips(q[ok]) - np.repeat(tips, 4, axis=0)[ok.ravel()], axis=1)
        assert err.max() < 1e-9
