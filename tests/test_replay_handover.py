"""Hand-overs of the replay (dexplan.execution.replay.handover) and the pressing holding tips."""

import copy

import numpy as np
import pytest

from dexplan.execution.forces import solver_from_plan
from dexplan.execution.replay.control import ObjectFeedback, pose_se3
from dexplan.execution.replay.driven_trajectory import replay_trajectory
from dexplan.execution.replay.handover import HANDOVER_TIME, insert_handovers, loaded_fingers_of
from dexplan.planfile import hand_from_plan, read_plan


@pytest.fixture(scope="module")
def stretched(tmp_path_factory, paper_plan):
    """paper_sphere seed 1 (rolling), its replay trajectory and the same with hand-overs."""
    doc = read_plan(paper_plan(1, tmp_path_factory.mktemp("handover")))
    hand = hand_from_plan(doc["hand"])
    traj = replay_trajectory(doc, hand=hand)
    solver = solver_from_plan(doc, traj.settings, hand)
    out, ho = insert_handovers(traj, solver)
    return doc, hand, traj, out, ho, solver


def _rows(ho):
    """Each hand-over's sample indices."""
    idx = np.flatnonzero(np.isfinite(ho.blend))
    return np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1)


def test_a_handover_at_every_change_of_the_loaded_fingers(stretched) -> None:
    _, _, traj, out, ho, _ = stretched
    loaded = loaded_fingers_of(traj)
    changes = sum(not np.array_equal(loaded[z - 1], loaded[z]) for _, _, _, z in traj.segments[:-1])
    assert ho.count == changes > 0
    assert ho.added_time == pytest.approx(ho.count * HANDOVER_TIME)
    assert out.duration == pytest.approx(traj.duration + ho.added_time)
    assert np.all(np.diff(out.t) >= 0)
    for (_, _, _, z), (_, _, a, _) in zip(out.segments[:-1], out.segments[1:], strict=True):
        assert z == a  # segments still share their boundary sample
    for s, (_, _, a, _) in enumerate(out.segments):
        assert out.t[a] == pytest.approx(out.timing.start_times[s])
    # outside the hand-overs the samples are the plan's, delayed
    plain = ~np.isfinite(ho.blend)
    assert np.isin(out.q[plain], traj.q).all()


def test_the_load_ramps_at_rest_and_balances_throughout(stretched) -> None:
    """In a hand-over the hand is still, every force set balances the weight, and the
    load moves in even steps: no finger's force changes by more than 1/N of its
    whole change between two samples (the old set's step was all of it at once)."""
    _, _, _, out, ho, solver = stretched
    weight = solver.settings.mass * np.asarray(solver.settings.gravity)
    for rows in _rows(ho):
        assert np.ptp(out.q[rows], axis=0).max() == 0.0
        assert np.abs(out.qd[rows]).max() == 0.0
        R = pose_se3(out.object_pose[rows[0]]).rotation
        f = np.nan_to_num(out.forces[rows])
        net = np.einsum("ij,knj->ki", R, f)
        assert np.allclose(net + weight, 0.0, atol=1e-6)
        whole = np.abs(f[-1] - f[0]).max()
        assert np.abs(np.diff(f, axis=0)).max() <= whole / (rows.size - 1) + 1e-9
        # a landing finger holds from the start unloaded; a releasing one ends unloaded
        landing = ho.loaded_to[rows[0]] & ~ho.loaded_from[rows[0]]
        leaving = ho.loaded_from[rows[0]] & ~ho.loaded_to[rows[0]]
        assert np.allclose(f[0][landing], 0.0) and np.allclose(f[-1][leaving], 0.0)
        assert not np.isnan(out.forces[rows][:, landing | leaving]).any()


def test_no_handover_time_leaves_the_trajectory(stretched) -> None:
    _, _, traj, _, _, solver = stretched
    out, ho = insert_handovers(traj, solver, 0.0)
    assert ho.count == 0 and np.array_equal(out.t, traj.t) and out.segments == traj.segments


def test_a_holding_tip_never_pulls_and_stays_on_the_object(stretched) -> None:
    """The object measured 2 mm off the plan, in any direction: no holding finger is aimed
    outward from where it is (it can only push), nor outside the measured object."""
    doc, hand, _, out, ho, solver = stretched
    fb = ObjectFeedback(hand, out, solver, rolling=True, handovers=ho)
    k = next(a + 5 for kind, _, a, _ in out.segments if kind == "transfer")
    q, pose = out.q[k], out.object_pose[k]
    p_plan = hand.fingertip_positions(q)
    r = float(doc["object"]["radius"]) + hand.fingertip_radius
    rng = np.random.default_rng(0)
    for d in rng.normal(size=(8, 3)):
        moved = copy.copy(pose)
        moved[:3] = pose[:3] + 0.002 * d / np.linalg.norm(d)
        tips = hand.fingertip_positions(fb.targets(k, q, q, pose, moved))
        for f in np.flatnonzero(fb.holding[k]):
            n_out = (p_plan[f] - moved[:3]) / np.linalg.norm(p_plan[f] - moved[:3])
            assert float(np.dot(tips[f] - p_plan[f], n_out)) <= 2e-4
            assert np.linalg.norm(tips[f] - moved[:3]) <= r + 2e-4
