"""dexplan export -o traj.mcap: a ROS 2 bag, read back with rosbags, matches the JSON export."""

from collections import Counter, defaultdict

import numpy as np
import pytest
from cli_contract import assert_bad_input, run_cli

from dexplan.cli import main as cli
from dexplan.execution.bag import (
    CONTACT_FRAME,
    OBJECT_FRAME,
    WORLD_FRAME,
    bag_topics,
    read_bag,
    stamp_seconds,
)
from dexplan.execution.export import read_trajectory


@pytest.fixture(scope="module")
def exports(tmp_path_factory, paper_plan):
    """The same plan exported as JSON and as a bag at 20 Hz."""
    plan = paper_plan(3, tmp_path_factory.mktemp("bag"))
    js, bag = plan.with_name("traj.json"), plan.with_name("traj.mcap")
    for out in (js, bag):
        assert cli.run(["export", str(plan), "-o", str(out), "--rate", "20"]) == 0
    return read_trajectory(js), read_bag(bag), bag


def test_topics_and_counts(exports) -> None:
    doc, msgs, _ = exports
    counts = Counter(m.topic for m in msgs)
    n_pts = len(doc["points"])
    assert {m.topic: m.msgtype for m in msgs} == dict(bag_topics(doc))
    assert counts["/joint_trajectory"] == 1
    assert counts["/joint_states"] == counts["/object_pose"] == counts["/tf"] == n_pts
    touching = [
        sum(p["grip_forces"][i] is not None for p in doc["points"])
        for i in range(len(doc["fingertip_frames"]))
    ]
    for i, n_touch in enumerate(touching):
        # a finger's topic has a message wherever it touches, none where it is free
        assert 0 < counts[f"/grip_force/finger_{i}"] == n_touch <= n_pts
    assert min(touching) < n_pts  # the plan regrasps: some finger is free somewhere
    stamps = [m.timestamp_ns for m in msgs]
    assert stamps == sorted(stamps)


def test_messages_match_json(exports) -> None:
    doc, msgs, _ = exports
    by_topic = defaultdict(list)
    for m in msgs:
        by_topic[m.topic].append(m.message)
    pts = doc["points"]
    (traj,) = by_topic["/joint_trajectory"]
    assert list(traj.joint_names) == doc["joint_names"]
    assert len(traj.points) == len(pts)
    for tp, js, ps, p in zip(
        traj.points, by_topic["/joint_states"], by_topic["/object_pose"], pts, strict=True
    ):
        assert stamp_seconds(tp.time_from_start) == pytest.approx(p["time_from_start"], abs=1e-9)
        assert np.array_equal(tp.positions, p["positions"])
        assert np.array_equal(tp.velocities, p["velocities"])
        assert np.array_equal(tp.accelerations, p["accelerations"])
        assert np.array_equal(js.position, p["positions"])
        assert np.array_equal(js.effort, p["joint_torques"])
        assert list(js.name) == doc["joint_names"]
        assert stamp_seconds(js.header.stamp) == pytest.approx(p["time_from_start"], abs=1e-9)
        pose = ps.pose
        got = [pose.position.x, pose.position.y, pose.position.z]
        got += [pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w]
        assert got == p["object_pose_xyzquat"]
        assert ps.header.frame_id == WORLD_FRAME


def test_forces_and_tf_match_json(exports) -> None:
    doc, msgs, _ = exports
    pts = doc["points"]
    # the j-th message of a finger's topic is its j-th sample in contact
    for i in range(len(doc["fingertip_frames"])):
        wrenches = [m.message for m in msgs if m.topic == f"/grip_force/finger_{i}"]
        loaded = [p for p in pts if p["grip_forces"][i] is not None]
        for w, p in zip(wrenches, loaded, strict=True):
            f = w.wrench.force
            assert [f.x, f.y, f.z] == p["grip_forces"][i]
            assert w.header.frame_id == CONTACT_FRAME.format(i)
            assert stamp_seconds(w.header.stamp) == pytest.approx(p["time_from_start"], abs=1e-9)
    tfs = [m.message for m in msgs if m.topic == "/tf"]
    for tf, p in zip(tfs, pts, strict=True):
        obj, *contacts = tf.transforms
        assert (obj.header.frame_id, obj.child_frame_id) == (WORLD_FRAME, OBJECT_FRAME)
        t = obj.transform.translation
        assert [t.x, t.y, t.z] == p["object_pose_xyzquat"][:3]
        expect = {CONTACT_FRAME.format(i): c for i, c in enumerate(p["contacts"]) if c is not None}
        got = {
            c.child_frame_id: [c.transform.translation.x, c.transform.translation.y,
                               c.transform.translation.z]
            for c in contacts
        }  # fmt: skip
        assert got == expect
        assert all(c.header.frame_id == OBJECT_FRAME for c in contacts)


def test_bag_is_deterministic(exports, tmp_path) -> None:
    _, _, bag = exports
    plan = bag.with_name("plan.json")
    again = tmp_path / "again.mcap"
    assert cli.run(["export", str(plan), "-o", str(again), "--rate", "20"]) == 0
    assert again.read_bytes() == bag.read_bytes()


def test_no_partial_bag_on_error(exports, tmp_path, monkeypatch, capfd) -> None:
    _, _, bag = exports
    plan = bag.with_name("plan.json")
    out = tmp_path / "broken.mcap"

    def fail(*args, **kwargs):
        raise KeyboardInterrupt

    # Ctrl-C while the messages are written: nothing is left in the folder
    monkeypatch.setattr("dexplan.execution.bag._Messages.trajectory", fail)
    assert cli.run(["export", str(plan), "-o", str(out)]) == cli.EXIT_INTERRUPTED
    assert list(tmp_path.iterdir()) == []
    monkeypatch.undo()
    code, _, err = run_cli(capfd, "export", plan, "-o", tmp_path / "traj.bag")
    assert_bad_input(code, err, names=[".mcap", "traj.bag"])
    assert list(tmp_path.iterdir()) == []


def test_missing_rosbags_is_said_before_any_work(exports, tmp_path, monkeypatch, capfd) -> None:
    _, _, bag = exports
    import sys

    monkeypatch.setitem(sys.modules, "rosbags", None)  # as if not installed
    monkeypatch.setitem(sys.modules, "rosbags.rosbag2", None)
    monkeypatch.setattr(
        "dexplan.cli.commands.export.build_trajectory",
        lambda *a, **k: pytest.fail("timed before the dependency check"),
    )
    out = tmp_path / "t.mcap"
    code, _, err = run_cli(capfd, "export", bag.with_name("plan.json"), "-o", out)
    assert_bad_input(code, err, names=["rosbags", "dexplan[ros]"], outputs=[out])
