"""dexplan replay: MuJoCo physics replay of plan pieces; limited actuators; honest verdicts."""

import copy
import math
import sys

import numpy as np
import pytest
from cli_contract import assert_bad_input, run_cli

from dexplan.core.errors import DependencyError
from dexplan.model.hand.urdf import with_effort_limits
from dexplan.planfile import hand_from_plan, read_plan, write_plan

mujoco = pytest.importorskip("mujoco")

from dexplan.execution.replay.driven_trajectory import (  # noqa: E402
    replay_settings,
    replay_trajectory,
)
from dexplan.execution.replay.mjcf import KP, build_mjcf  # noqa: E402
from dexplan.execution.replay.result import DROP_TOL, Loop  # noqa: E402
from dexplan.execution.replay.simulation import replay_plan, require_mujoco  # noqa: E402
from dexplan.execution.replay.squeeze import SQUEEZE_LEVELS, TORQUE_HEADROOM  # noqa: E402
from dexplan.execution.trajectory import Unbalanced, build_trajectory  # noqa: E402

#: Open loop the tips roll instead of sliding and the object turns by a fraction of
#: the planned turn (about two thirds, docs/trajectory_format.md): a first transfer
#: turning at least this far (rad) leaves the open-loop replay well beyond 0.1 rad.
BIG_TURN = 0.5
SEEDS = range(1, 11)


def _first_transfer(doc) -> int:
    return next(i for i, s in enumerate(doc["segments"]) if s["kind"] == "transfer")


def _first_regrasp(doc) -> int:
    return next(i for i, s in enumerate(doc["segments"]) if s["kind"] == "regrasp")


def _turn(seg) -> float:
    """The rotation (rad) between a segment's first and last object orientation."""
    a = np.asarray(seg["waypoints"][0]["object_pose_xyzquat"][3:])
    b = np.asarray(seg["waypoints"][-1]["object_pose_xyzquat"][3:])
    return 2.0 * math.acos(min(1.0, abs(float(np.dot(a, b)))))


@pytest.fixture(scope="module")
def planned(tmp_path_factory, paper_plan):
    """The first paper_sphere seed whose plan has a regrasp and a first transfer of a big turn.

    With fixed contacts: the open-loop gap (the tips roll where the plan slides
    them) is what :func:`test_first_transfer_tracks_only_with_feedback` shows.
    """
    for seed in SEEDS:
        folder = tmp_path_factory.mktemp(f"replay{seed}")
        doc = read_plan(paper_plan(seed, folder, motion="fixed"))
        kinds = [s["kind"] for s in doc["segments"]]
        if "regrasp" in kinds and _turn(doc["segments"][_first_transfer(doc)]) >= BIG_TURN:
            return folder, doc, hand_from_plan(doc["hand"])
    pytest.fail(f"no paper_sphere seed in {SEEDS} turns {BIG_TURN} rad in its first transfer")


def _short(doc, index):
    """The plan cut to one segment (start and goal at its ends)."""
    d = copy.deepcopy(doc)
    d["segments"] = [d["segments"][index]]
    w0, wl = d["segments"][0]["waypoints"][0], d["segments"][0]["waypoints"][-1]
    d["start"] = {"object_pose_xyzquat": w0["object_pose_xyzquat"], "q": w0["q"]}
    d["goal"] = dict(d["goal"], object_pose_xyzquat=wl["object_pose_xyzquat"])
    return d


def _tampered(doc):
    """A regrasp in which a second finger lets go and moves away."""
    d = _short(doc, _first_regrasp(doc))
    free = d["segments"][0]["finger"]
    other = next(i for i in range(4) if i != free)
    for w in d["segments"][0]["waypoints"][1:]:
        w["contacts"][other] = None
        if "tip_contacts" in w:  # format /2: both sides of a contact go together
            w["tip_contacts"][other] = None
        w["q"][3 * other : 3 * other + 3] = [0.0, -0.5, 0.0]
    return d, free, other


def test_model_from_plan_alone(planned) -> None:
    _, doc, hand = planned
    xml, tips = build_mjcf(doc, hand, mass=0.1, gravity=np.array([0, 0, -9.81]))
    m = mujoco.MjModel.from_xml_string(xml)
    assert m.nu == hand.nq
    assert len(tips) == hand.n_fingers
    assert m.body("object").mass[0] == pytest.approx(0.1)
    assert m.geom("object").condim == 3


def test_actuators_are_limited_to_the_urdf_effort_limits(planned) -> None:
    """forcerange and the joint's total actuator torque are the URDF's effort, never more."""
    _, doc, hand = planned
    xml, _ = build_mjcf(doc, hand, mass=0.1, gravity=np.array([0, 0, -9.81]))
    m = mujoco.MjModel.from_xml_string(xml)
    for k, name in enumerate(hand.joint_names):
        jm = hand.model.joints[hand.model.getJointId(name)]
        e = float(hand.model.effortLimit[jm.idx_v])
        lo, hi = hand.model.lowerPositionLimit[jm.idx_q], hand.model.upperPositionLimit[jm.idx_q]
        a, j = m.actuator(f"a_{name}"), m.joint(name)
        assert m.actuator_trnid[a.id, 0] == j.id and k == a.id
        assert np.allclose(m.actuator_forcerange[a.id], [-e, e])
        assert m.jnt_actfrclimited[j.id] and np.allclose(m.jnt_actfrcrange[j.id], [-e, e])
        assert np.allclose(m.actuator_ctrlrange[a.id], [lo - e / KP, hi + e / KP])


def test_replay_never_exceeds_the_limits_and_reports_saturation(planned) -> None:
    """With the paper hand's limits cut to 0.02 N m the actuators saturate but never exceed."""
    _, doc, _ = planned
    weak = _short(doc, _first_regrasp(doc))
    weak["hand"] = dict(weak["hand"], urdf_xml=with_effort_limits(weak["hand"]["urdf_xml"], 0.02))
    r = replay_plan(weak, gravity=True)
    assert r.effort_limits == (0.02,) * len(r.effort_limits)
    assert r.max_effort_ratio <= 1.0 + 1e-9
    assert r.saturated_time > 0.0
    assert "torque limited to the URDF's effort limits (0.02 N m)" in r.summary()


def _normal_forces(traj) -> tuple[np.ndarray, np.ndarray]:
    """(m, n) each contact's normal force (N) and whether it is loaded."""
    loaded = np.linalg.norm(np.nan_to_num(traj.forces), axis=2) > 0
    return np.einsum("mfk,mfk->mf", np.nan_to_num(traj.forces), traj.normals), loaded


def test_replay_squeezes_every_loaded_contact(planned) -> None:
    """The replay's grip forces press each loaded contact harder than the plan's least forces,
    without giving up cone margin or torque headroom for it: the paper hand squeezes its
    first regrasp with the largest level everywhere."""
    _, doc, hand = planned
    short = _short(doc, _first_regrasp(doc))
    traj = replay_trajectory(short, hand=hand)
    plain = build_trajectory(short, settings=replay_settings(short, True, None, None)[0], hand=hand)
    fn, loaded = _normal_forces(traj)
    assert loaded.any() and not np.isnan(traj.margins).any()
    assert fn[loaded].min() >= SQUEEZE_LEVELS[0] - 1e-6
    assert np.all(traj.margins >= plain.margins - 1e-12)
    ratio = np.abs(traj.joint_torques) / traj.joint_effort[None, :]
    plain_ratio = np.abs(plain.joint_torques) / traj.joint_effort[None, :]
    assert np.all(ratio.max(1) <= np.maximum(TORQUE_HEADROOM, plain_ratio.max(1)) + 1e-9)


def test_a_hand_too_weak_to_squeeze_hard_squeezes_less(planned) -> None:
    """At 0.1 N m the paper hand cannot press 2 N in this hold: it presses less, within its
    limits and the plan's cone margins."""
    _, doc, _ = planned
    weak = _short(doc, _first_regrasp(doc))
    weak["hand"] = dict(weak["hand"], urdf_xml=with_effort_limits(weak["hand"]["urdf_xml"], 0.1))
    hand = hand_from_plan(weak["hand"])
    traj = replay_trajectory(weak, hand=hand)
    settings = replay_settings(weak, True, None, None)[0]
    plain = build_trajectory(weak, settings=settings, hand=hand, unbalanced=Unbalanced.ZERO)
    fn, loaded = _normal_forces(traj)
    assert (fn[loaded] < SQUEEZE_LEVELS[0] - 1e-6).any()
    assert not np.isnan(plain.margins).any() and not np.isnan(traj.margins).any()
    assert np.all(traj.margins >= plain.margins - 1e-12)
    assert np.all(np.abs(traj.joint_torques) <= 0.1 + 1e-9)


def test_short_plan_tracks_without_gravity(planned) -> None:
    _, doc, hand = planned
    r = replay_plan(_short(doc, _first_regrasp(doc)), gravity=False, hand=hand)
    assert r.loop == Loop.CLOSED
    assert r.tracked and r.at_goal and not r.dropped, r.summary()
    assert r.waypoint_position_error < 0.005 and r.waypoint_angle_error < 0.1
    assert r.waypoints_reached == r.waypoints and r.unbalanced_samples == 0


def test_short_plan_tracks_with_gravity_cli_both_loops(planned, capfd) -> None:
    folder, doc, _ = planned
    path = folder / "short.json"
    write_plan(path, _short(doc, _first_regrasp(doc)))
    code, out, _ = run_cli(capfd, "replay", path, "--gravity")
    assert code == 0, out
    assert "replay, closed loop (object-pose feedback), gravity" in out
    assert "replay, open loop, gravity" in out
    assert "verdict: closed loop TRACKED, open loop " in out
    assert " deg" in out and " rad" not in out


def test_tampered_plan_drops_and_says_where(planned, capfd) -> None:
    """The drop: its time, segment, moving finger, holding fingers, hold quality; errors bounded."""
    folder, doc, hand = planned
    tampered, free, other = _tampered(doc)
    r = replay_plan(tampered, gravity=True, hand=hand)
    assert r.dropped and r.drop is not None, r.summary()
    d = r.drop
    assert (d.segment, d.kind, d.finger) == (0, "regrasp", free)
    assert set(d.holding_fingers) == set(range(4)) - {free, other}
    assert d.planned_hold_quality == 0.0  # two fingers on a sphere: no force closure
    assert 0.0 <= d.lost_track_time <= d.time <= r.duration
    assert r.t[-1] == pytest.approx(d.time)  # the replay stops at the drop
    assert np.all(np.isfinite(r.position_error)) and np.all(np.isfinite(r.angle_error))
    assert r.max_position_error <= DROP_TOL and r.goal_position_error is None
    path = folder / "tampered.json"
    write_plan(path, tampered)
    code, out, _ = run_cli(capfd, "replay", path, "--loop", "closed")
    assert code == 1, out
    assert f"DROPPED at {d.time:.2f} s in segment 1 of 1 (regrasp of finger {free};" in out
    assert "goal: not reached" in out and "open loop" not in out


def test_tampered_plan_loses_track_without_gravity(planned) -> None:
    _, doc, hand = planned
    r = replay_plan(_tampered(doc)[0], gravity=False, hand=hand)
    # whether the two fingers left can squeeze in balance (unbalanced_samples) depends on
    # the plan's grasp, and so does whether they keep their contacts (they press on the
    # object wherever it goes); losing the track does not
    assert not r.tracked


def test_missing_mujoco_is_a_dependency_error(monkeypatch, capfd, planned) -> None:
    monkeypatch.setitem(sys.modules, "mujoco", None)
    with pytest.raises(DependencyError, match=r"pip install 'dexplan\[sim\]'"):
        require_mujoco()
    folder, _, _ = planned
    code, _, err = run_cli(capfd, "replay", folder / "plan.json")
    assert_bad_input(code, err, names=["pip install"])


def test_first_transfer_tracks_only_with_feedback(planned, capfd) -> None:
    """Open loop the rolling tips turn the object less than planned; the feedback corrects it."""
    folder, doc, hand = planned
    short = _short(doc, _first_transfer(doc))
    r = replay_plan(short, gravity=False, hand=hand)
    assert r.tracked and r.at_goal, r.summary()
    assert r.waypoint_angle_error < 0.02
    path = folder / "transfer.json"
    write_plan(path, short)
    for flags in (["--loop", "open"], ["--open-loop"]):
        code, out, _ = run_cli(capfd, "replay", path, "--no-gravity", *flags)
        assert code == 1 and "LOST TRACK" in out and "closed loop" not in out, out


def test_bad_loop_is_exit_2(planned, capfd) -> None:
    folder, _, _ = planned
    code, _, err = run_cli(capfd, "replay", folder / "plan.json", "--loop", "sideways")
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert "--loop" in lines[0] and "invalid choice: 'sideways'" in lines[0]


def test_replay_rrd_records_the_closed_loop(planned, capfd) -> None:
    pytest.importorskip("rerun")
    folder, doc, _ = planned
    path, rrd = folder / "short_rrd.json", folder / "replay.rrd"
    write_plan(path, _short(doc, _first_regrasp(doc)))
    code, out, err = run_cli(capfd, "replay", path, "--loop", "closed", "--rrd", rrd)
    assert code == 0, out + err
    assert rrd.stat().st_size > 0 and f"recording written to {rrd}" in err
