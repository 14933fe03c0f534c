"""The gait search (:mod:`dexplan.planning.local.gait_search`): what it returns is a gait."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from dexplan.core.pose import quat_angle
from dexplan.core.segments import Segment, SegmentKind
from dexplan.model.scenario import default_scenario
from dexplan.planning.context import build_context
from dexplan.planning.gsn.space import POSE_DIM
from dexplan.planning.local import gait_search
from dexplan.planning.local.grasps import grasp_from_state
from dexplan.planning.local.transitions import TransferResult, densify_poses
from dexplan.planning.start import start_state


@pytest.fixture(scope="module")
def problem():
    """The paper's hand, its first sampled start grasp and the 180 degree turn."""
    sc = default_scenario()
    ctx = build_context(sc, seed=1)
    x0 = start_state(ctx, candidates=1)
    assert x0 is not None
    s = ctx.transitions.settings
    ends = np.stack([x0[:POSE_DIM], sc.goal.object_pose_xyzquat])
    if float(np.dot(ends[0, 3:], ends[1, 3:])) < 0.0:
        ends[1, 3:] = -ends[1, 3:]
    poses = densify_poses(ends, s.max_step_m, s.max_step_rad)
    return sc, x0, poses


def _search(ctx, x0, poses, **kw):
    args = {"beam_width": 3, "branching": 3, "max_regrasps": 60, "max_expanded": 150} | kw
    grasp = grasp_from_state(ctx.transitions, x0[:POSE_DIM], x0[POSE_DIM:])
    return gait_search.search_gaits(ctx.transitions, poses, x0[POSE_DIM:], grasp, **args)


def test_search_returns_a_connected_gait_to_the_end(problem) -> None:
    sc, x0, poses = problem
    ctx = build_context(sc, seed=1)
    res = _search(ctx, x0, poses)
    assert res.reason is None, res.reason
    segs = res.segments
    assert segs and segs[-1].kind == "transfer"
    np.testing.assert_allclose(segs[0].start.q, x0[POSE_DIM:], atol=1e-12)
    for a, b in itertools.pairwise(segs):
        np.testing.assert_allclose(a.end.q, b.start.q, atol=1e-12)
        np.testing.assert_allclose(a.end.object_pose_xyzquat, b.start.object_pose_xyzquat)
    assert quat_angle(segs[-1].end.object_pose_xyzquat[3:], poses[-1][3:]) < 1e-9
    for seg in segs:
        if seg.kind == "regrasp":  # the object stays, one finger moves
            w0, w1 = seg.start, seg.end
            np.testing.assert_array_equal(w0.object_pose_xyzquat, w1.object_pose_xyzquat)
            moved = {
                f
                for f, idx in enumerate(ctx.hand.finger_q_index)
                if any(not np.array_equal(w.q[idx], w0.q[idx]) for w in seg.waypoints)
            }
            assert moved == {seg.finger}


def test_search_is_deterministic(problem) -> None:
    sc, x0, poses = problem
    a = _search(build_context(sc, seed=3), x0, poses)
    b = _search(build_context(sc, seed=3), x0, poses)
    assert a.reason is None and b.reason is None
    assert len(a.segments) == len(b.segments)
    for sa, sb in zip(a.segments, b.segments, strict=True):
        assert sa.kind == sb.kind and sa.finger == sb.finger
        np.testing.assert_array_equal(sa.end.q, sb.end.q)


def test_no_feasible_regrasp_ends_the_search_with_its_reason(problem, monkeypatch) -> None:
    sc, x0, poses = problem
    ctx = build_context(sc, seed=1)
    monkeypatch.setattr(type(ctx.transitions), "regrasp", lambda *a, **k: None)
    res = _search(ctx, x0, poses)
    assert res.segments == ()
    assert res.reason == "no gait state has a feasible regrasp"
    assert res.reached < len(poses) - 1


def test_a_finger_that_cannot_be_let_go_where_it_blocks_is_regrasped_before(
    problem, monkeypatch
) -> None:
    """Where the others cannot hold the object without the blocking finger, the
    search cuts the transfer at the latest step where they can and regrasps there."""
    sc, x0, poses = problem
    ctx = build_context(sc, seed=1)
    trans = ctx.transitions
    grasp = grasp_from_state(trans, x0[:POSE_DIM], x0[POSE_DIM:])
    tr = trans.transfer(poses, 0, x0[POSE_DIM:], grasp)
    assert tr.blocking is not None and tr.reached >= 6, tr.reached
    cut = tr.reached - 3  # the blocking finger may go only up to here
    real = type(trans).can_release

    def can_release(self, finger, pose, q, g):
        if finger == tr.blocking:
            step = int(np.argmin(np.linalg.norm(poses - pose, axis=1)))
            if step > cut:
                return False
        return real(self, finger, pose, q, g)

    monkeypatch.setattr(type(trans), "can_release", can_release)
    start = gait_search._State(0, x0[POSE_DIM:], grasp, (0,) * ctx.hand.n_fingers, (), 0, 0.0)
    (state,) = gait_search._evaluate(trans, poses, [start])  # its transfer, where it can let go
    assert state.transfer is not None and state.transfer.reached == tr.reached
    assert not state.viable
    kids = gait_search._children(trans, poses, state, state.transfer, 3, 0.85)
    assert kids
    for kid in kids:
        assert len(kid.segments) == 2, (tr.reached, kid.idx)
        first, regrasp = kid.segments
        assert first.kind == "transfer" and regrasp.finger == tr.blocking
        step = int(np.argmin(np.linalg.norm(poses - first.end.object_pose_xyzquat, axis=1)))
        assert step <= cut and kid.idx == step
        assert cut - step < 2  # the latest such step (every second one is tried)


@pytest.mark.parametrize("moved", [False, True])
def test_a_finger_is_never_regrasped_twice_where_the_object_has_not_moved(
    problem, monkeypatch, moved
) -> None:
    """A blocked finger without a landing makes way for the others, except the one
    regrasped last when the object has not moved since: two regrasps of one finger
    there are one regrasp onto the second landing."""
    sc, x0, poses = problem
    ctx = build_context(sc, seed=1)
    trans, q = ctx.transitions, x0[POSE_DIM:]
    grasp = grasp_from_state(trans, x0[:POSE_DIM], q)
    tr = trans.transfer(poses, 0, q, grasp)
    n, blocked, last = ctx.hand.n_fingers, 0, 1
    wp = tr.waypoints[0]
    regrasp = Segment(SegmentKind.REGRASP, last, (wp, wp))
    stop = TransferResult(
        tr.waypoints[: 3 if moved else 1], 2 if moved else 0, blocked, tr.reason, grasp
    )
    state = gait_search._State(0, q, grasp, (len(poses),) * n, (regrasp,), 1, 0.0)
    asked: list[int] = []

    def regrasps_of(trans, poses, state, tr, at, finger, *rest):
        asked.append(finger)
        return []

    monkeypatch.setattr(gait_search, "_release_step", lambda *a: None)
    monkeypatch.setattr(gait_search, "_regrasps_of", regrasps_of)
    gait_search._children(trans, poses, state, stop, 2, 0.85)
    expected = set(range(n)) - {blocked} - (set() if moved else {last})
    assert set(asked) == expected


def test_the_lazy_beam_is_the_beam_of_every_child_evaluated(monkeypatch) -> None:
    """Children run best promise first give the beam running them all gives, in order."""
    rng = np.random.default_rng(7)
    end = 60

    def child(i: int) -> gait_search._State:
        cover = tuple(int(c) for c in rng.integers(5, 70, size=4))
        weakest = float(rng.choice([0.01, 0.02, 0.05]))
        return gait_search._State(10, np.zeros(3), None, cover, (), 1, weakest, weakest=weakest)  # type: ignore[arg-type]

    def evaluate(trans, poses, states):
        out = []
        for s in states:  # a transfer lowers the rank: one finger's stroke ends, maybe for good
            if hash(s.cover) % 7 == 0:
                continue  # dropped, as a landing that blocks at once
            cover = list(s.cover)
            f = hash(s.cover) % 4
            cover[f] = min(cover[f], s.idx + hash(s.cover) % 40)
            tr = TransferResult((), cover[f], f, None, None)  # type: ignore[arg-type]
            out.append(
                gait_search.dataclasses.replace(
                    s, cover=tuple(cover), viable=hash(s.cover) % 3 > 0, transfer=tr
                )
            )
        return out

    monkeypatch.setattr(gait_search, "_evaluate", evaluate)
    for _ in range(200):
        states = [child(i) for i in range(int(rng.integers(1, 9)))]
        width = int(rng.integers(1, 4))
        eager = sorted(evaluate(None, None, states), key=lambda s: s.rank(end), reverse=True)
        layer, spare = gait_search._beam(None, None, states, width, end)  # type: ignore[arg-type]
        assert [s.cover for s in layer] == [s.cover for s in eager[:width]]
        assert all(s.transfer is not None for s in layer)
        # the rest are kept, evaluated or not, and evaluate to the eager rest
        rest = gait_search._evaluated(None, None, spare)  # type: ignore[arg-type]
        assert sorted(s.cover for s in rest) == sorted(s.cover for s in eager[width:])
