"""Time parameterisation (dexplan.execution.timing): toppra's profile respects every limit."""

import numpy as np
import pytest

from dexplan.core.errors import InvalidInputError
from dexplan.execution.segment_timing import (
    DEFAULT_JOINT_VELOCITY,
    TimingLimits,
    joint_velocity_limits,
)
from dexplan.execution.timing import time_plan
from dexplan.planfile import hand_from_plan, read_plan


@pytest.fixture(scope="module")
def planned(tmp_path_factory, paper_plan):
    doc = read_plan(paper_plan(1, tmp_path_factory.mktemp("timing")))
    return doc, hand_from_plan(doc["hand"])


def _dense(seg, n=4000):
    return seg.sample(np.linspace(0.0, seg.duration, n))


def test_limits_respected_between_grid_points(planned) -> None:
    doc, hand = planned
    lim = TimingLimits()
    timing = time_plan(doc, lim, hand)
    vj = timing.joint_velocity
    assert timing.duration > 0
    for seg in timing.segments:
        s = _dense(seg)
        assert np.all(np.abs(s.qd) <= vj * (1 + 1e-9))
        assert np.all(np.abs(s.qdd) <= lim.max_acceleration * (1 + 1e-9))
        assert np.all(
            np.linalg.norm(s.object_velocity[:, :3], axis=1) <= lim.object_speed * 1.000001
        )
        w = np.linalg.norm(s.object_velocity[:, 3:], axis=1)
        assert np.all(w <= lim.object_angular_speed * 1.000001)
        # at rest at both ends
        ends = seg.sample([0.0, seg.duration])
        assert np.allclose(ends.qd, 0.0, atol=1e-12)
        assert np.allclose(ends.object_velocity, 0.0, atol=1e-12)


def test_waypoints_are_passed_in_order(planned) -> None:
    doc, hand = planned
    timing = time_plan(doc, TimingLimits(), hand)
    for seg, sd in zip(timing.segments, doc["segments"], strict=True):
        assert np.all(np.diff(seg.waypoint_times) >= -1e-12)
        at = seg.sample(seg.waypoint_times)
        q = np.array([w["q"] for w in sd["waypoints"]])
        pose = np.array([w["object_pose_xyzquat"] for w in sd["waypoints"]])
        assert np.allclose(at.q, q, atol=1e-9)
        assert np.allclose(at.object_pose[:, :3], pose[:, :3], atol=1e-9)
        dots = np.abs(np.sum(at.object_pose[:, 3:] * pose[:, 3:], axis=1))
        assert np.all(dots > 1 - 1e-9)


def test_tighter_limits_take_longer(planned) -> None:
    doc, hand = planned
    fast = time_plan(doc, TimingLimits(), hand).duration
    slow = time_plan(doc, TimingLimits(object_angular_speed=0.25), hand).duration
    assert slow > fast


def test_regrasp_slowed_near_contact(planned) -> None:
    doc, hand = planned
    si = next(i for i, s in enumerate(doc["segments"]) if s["kind"] == "regrasp")
    plain = time_plan(doc, TimingLimits(approach_scale=1.0), hand).segments[si].duration
    slowed = time_plan(doc, TimingLimits(approach_scale=0.1), hand).segments[si].duration
    assert slowed > plain


def test_velocity_limits_from_urdf(paper_hand) -> None:
    v = joint_velocity_limits(paper_hand.model)
    assert v.shape == (paper_hand.nq,) and np.allclose(v, 2.0)  # the URDF's velocity="2"
    m = paper_hand.model.copy()
    m.velocityLimit[:] = 0.0
    assert np.allclose(joint_velocity_limits(m), DEFAULT_JOINT_VELOCITY)


def test_bad_limits_rejected() -> None:
    with pytest.raises(InvalidInputError, match="object_speed"):
        TimingLimits(object_speed=0.0)
    with pytest.raises(InvalidInputError, match="approach_scale"):
        TimingLimits(approach_scale=2.0)


def test_a_stalled_toppra_pass_is_solved_again() -> None:
    """An Allegro regrasp on which toppra's forward pass all but stopped before the end.

    Seidel picked a path velocity of 2e-4 one grid point before the final rest,
    where the controllable set allowed 4: the last grid interval took 2727 s.
    The segment is timed in seconds (no grid interval near a second: the
    stall can stay at an interior point, where it costs a fraction of one),
    the limits hold between grid points, and the path run backward takes as long.
    """
    import json
    from pathlib import Path

    from dexplan.execution.timing import time_segment
    from dexplan.model.hand.hand import Hand

    data = json.loads((Path(__file__).parent / "data/allegro_regrasp_stall.json").read_text())
    hand = Hand.builtin("allegro")
    q = np.asarray(data["q"], dtype=float)
    poses = np.asarray(data["object_pose_xyzquat"], dtype=float)
    vj = joint_velocity_limits(hand.model)
    lim = TimingLimits()
    seg = time_segment("regrasp", data["finger"], q, poses, vj, lim)
    # 14 steps of about 0.04 rad at up to 7 rad/s, slowed near both ends: seconds
    assert seg.duration < 10.0
    assert np.diff(seg.times).max() < 0.5
    s = _dense(seg)
    assert np.all(np.abs(s.qd) <= vj * (1 + 1e-9))
    assert np.all(np.abs(s.qdd) <= lim.max_acceleration * (1 + 1e-9))
    back = time_segment("regrasp", data["finger"], q[::-1], poses[::-1], vj, lim)
    assert back.duration == pytest.approx(seg.duration, rel=1e-6)
