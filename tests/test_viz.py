"""Rerun recordings: read the .rrd back and check entity paths, nodes and timelines."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from dexplan.core.errors import DependencyError
from dexplan.core.pose import quat_from_axis_angle, transform_points
from dexplan.model.hand.hand import Hand
from dexplan.planfile import hand_table

RADIUS = 0.04
CENTER = np.array([0.0, 0.0, 0.1])


# ------------------------------------------------------------------ helpers
def _contact(az_deg: float, el_deg: float = -20.0) -> np.ndarray:
    az, el = math.radians(az_deg), math.radians(el_deg)
    return RADIUS * np.array(
        [math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)]
    )


def _solve(hand: Hand, q: np.ndarray, finger: int, target: np.ndarray) -> np.ndarray:
    res = hand.finger_ik(finger, target, q)
    assert res.success, (finger, target, res.residual)
    q = q.copy()
    q[hand.finger_q_index[finger]] = res.q_finger
    return q


def _grasp_q(hand: Hand, pose: np.ndarray, contacts: list, q0: np.ndarray) -> np.ndarray:
    q = q0.copy()
    r_tip = hand.fingertip_radius
    for i, c in enumerate(contacts):
        if c is None:
            continue
        tip_obj = c * (1.0 + r_tip / RADIUS)  # sphere: the outward normal is c / |c|
        q = _solve(hand, q, i, transform_points(pose, tip_obj[None])[0])
    return q


def _wp(pose: np.ndarray, q: np.ndarray, contacts: list) -> dict:
    return {
        "object_pose_xyzquat": [float(v) for v in pose],
        "q": [float(v) for v in q],
        "contacts": [None if c is None else [float(v) for v in c] for c in contacts],
    }


def make_plan_doc(hand: Hand) -> dict:
    """A transfer (5 waypoints, yaw 0.1 rad) then a regrasp of finger 0 (5 waypoints)."""
    contacts = [_contact(45 + 90 * k) for k in range(4)]
    transfer = []
    q = hand.neutral.copy()
    for s in np.linspace(0.0, 1.0, 5):
        lift = np.array([0.0, 0.0, 0.004 * s])
        pose = np.concatenate([CENTER + lift, quat_from_axis_angle([0, 0, 1], 0.1 * s)])
        q = _grasp_q(hand, pose, contacts, q)
        transfer.append(_wp(pose, q, contacts))
    # regrasp finger 0: lift along the normal, move, land 15 degrees further round
    pose = np.asarray(transfer[-1]["object_pose_xyzquat"])
    q_end = np.asarray(transfer[-1]["q"])
    new_c = _contact(60.0)
    regrasp = [transfer[-1]]
    free = [None, *contacts[1:]]
    r_tip = hand.fingertip_radius
    for az, lift in ((45.0, 0.006), (52.5, 0.008), (60.0, 0.006)):
        tip_obj = _contact(az) * (1.0 + (r_tip + lift) / RADIUS)
        q_end = _solve(hand, q_end, 0, transform_points(pose, tip_obj[None])[0])
        regrasp.append(_wp(pose, q_end, free))
    landed = [new_c, *contacts[1:]]
    q_end = _grasp_q(hand, pose, [new_c, None, None, None], q_end)
    regrasp.append(_wp(pose, q_end, landed))
    return {
        "format": "dexplan-plan/1",
        "scenario": "viz_test",
        "hand": hand_table(hand),
        "object": {"shape": "sphere", "radius": RADIUS},
        "mu": 0.8,
        "friction_edges": 8,
        "obstacles": [
            {"shape": "box", "size": [0.3, 0.3, 0.01], "pose_xyzquat": [0, 0, -0.02, 0, 0, 0, 1]}
        ],
        "start": {"object_pose_xyzquat": transfer[0]["object_pose_xyzquat"], "q": transfer[0]["q"]},
        "goal": {
            "object_pose_xyzquat": transfer[-1]["object_pose_xyzquat"],
            "position_tol": 0.005,
            "angle_tol": 0.05,
        },
        "segments": [
            {"kind": "transfer", "finger": None, "waypoints": transfer},
            {"kind": "regrasp", "finger": 0, "waypoints": regrasp},
        ],
        "stats": {"planner": "synthetic", "seed": 0, "waypoints": len(transfer) + len(regrasp)},
    }


def make_roadmap(doc: dict):
    """Vertices from the plan's waypoints plus a detached pair: 3 GSn components, 1 link."""
    try:
        from dexplan.planning.roadmap.graph import Roadmap
    except ImportError as exc:  # the planning stack is not importable yet
        pytest.skip(f"dexplan.planning.roadmap.graph unavailable: {exc}")
    wps = [w for s in doc["segments"] for w in s["waypoints"]]
    V = np.array([w["object_pose_xyzquat"] + w["q"] for w in wps[:7]])
    edges = np.array([[0, 1], [1, 2], [2, 3], [4, 5]], dtype=np.int64)
    links = np.array([[3, 4]], dtype=np.int64)
    return Roadmap(V, edges, links, "synthetic", "test")


def read_rrd(path: Path) -> dict[str, list]:
    """Entity path -> chunks (rerun's chunk API; pyarrow record batches)."""
    from rerun.chunk import RrdReader

    out: dict[str, list] = {}
    for chunk in RrdReader(path).store().stream():
        out.setdefault(chunk.entity_path, []).append(chunk)
    return out


def column(chunks: list, name: str) -> list:
    """One component over the chunks (static and temporal): every row's batch, concatenated."""
    vals = []
    for ch in chunks:
        rb = ch.to_record_batch()
        if name in rb.schema.names:
            for batch in rb.column(name).to_pylist():
                vals.extend(batch or [])
    return vals


def steps(chunks: list, timeline: str = "plan_step", component: str | None = None) -> list:
    """Sorted values of a timeline over the temporal chunks (rows holding ``component``)."""
    out = []
    for ch in chunks:
        rb = ch.to_record_batch()
        if timeline not in rb.schema.names:
            continue
        if component is None:
            out.extend(rb.column(timeline).to_pylist())
        elif component in rb.schema.names:
            t, v = rb.column(timeline).to_pylist(), rb.column(component).to_pylist()
            out.extend(ti for ti, vi in zip(t, v, strict=True) if vi is not None)
    return sorted(out)


# -------------------------------------------------------------------- tests
def test_require_rerun_without_rerun(monkeypatch: pytest.MonkeyPatch) -> None:
    from dexplan import viz

    monkeypatch.setitem(sys.modules, "rerun", None)
    with pytest.raises(DependencyError, match=r"pip install 'dexplan\[viz\]'"):
        viz.require_rerun()
    with pytest.raises(DependencyError):
        viz.record_plan({}, "unused.rrd")


def test_core_modules_do_not_import_rerun() -> None:
    import subprocess

    code = (
        "import sys; import dexplan.planfile.document, dexplan.viz, dexplan.model.hand.hand, "
        "dexplan.model.objects, "
        "dexplan.cli.main; "
        "sys.exit(1 if 'rerun' in sys.modules else 0)"
    )
    root = Path(__file__).resolve().parents[1]
    res = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True, timeout=60)
    assert res.returncode == 0, res.stderr.decode()


rr = pytest.importorskip("rerun")


@pytest.fixture(scope="module")
def plan_doc(paper_hand: Hand) -> dict:
    return make_plan_doc(paper_hand)


@pytest.fixture()
def fc_stub(monkeypatch: pytest.MonkeyPatch) -> bool:
    """Use dexplan.model.grasp when it exists, else stand-in qualities (True when real)."""
    from dexplan.viz import contacts

    if contacts.fc_functions() is not None:
        return True

    def quality(P, N, mu, *, edges=8, torque_scale=None):
        return 0.1 * len(P)

    def min_sub(P, N, mu, *, edges=8, torque_scale=None):
        return 0.05

    monkeypatch.setattr(contacts, "fc_functions", lambda: (quality, min_sub))
    return False


def test_synthetic_plan_is_consistent(paper_hand: Hand, plan_doc: dict) -> None:
    """The test plan itself: fingertips on the sphere, regrasp only moves finger 0."""
    from dexplan.planfile.document import segments_from_dicts

    r = RADIUS + paper_hand.fingertip_radius
    for seg in segments_from_dicts(plan_doc["segments"]):
        for w in seg.waypoints:
            tips = paper_hand.fingertip_positions(w.q)
            for i, c in enumerate(w.contacts):
                d = np.linalg.norm(tips[i] - w.object_pose_xyzquat[:3])
                assert (abs(d - r) < 1e-6) if c is not None else d > r + 1e-3


def _expected_plan_entities(hand: Hand) -> set[str]:
    """Every entity path a plan recording with a roadmap and one obstacle holds."""
    expected = {
        "/world",
        "/world/hand",
        "/world/object",
        "/world/object/shape",
        "/world/goal",
        "/world/obstacles/obstacle0",
        "/world/obstacles/obstacle0/shape",
        "/world/roadmap",
        "/world/roadmap/nodes",
        "/world/roadmap/axes",
        "/world/roadmap/edges",
        "/world/roadmap/links",
        "/roadmap/summary",
        "/plan/segment",
        "/plan/summary",
        "/plan/quality",
        "/plan/state/mode",
        "/plan/state/free_finger",
        "/plan/fc/full",
        "/plan/fc/min_subgrasp",
    }
    expected |= {f"/world/contacts/finger_{i}" for i in range(hand.n_fingers)}
    expected |= {f"/world/contacts/finger_{i}/cone" for i in range(hand.n_fingers)}
    links = {f.name for f in hand.model.frames if f.name.endswith(("_proximal", "_tip"))}
    expected |= {f"/world/hand/{name}" for name in links | {"palm"}}
    return expected


def _check_roadmap_entities(ents: dict, roadmap) -> None:
    """One logged node per vertex, one strip per edge / link."""
    nodes = column(ents["/world/roadmap/nodes"], "Points3D:positions")
    assert len(nodes) == roadmap.n_vertices
    assert len(column(ents["/world/roadmap/edges"], "LineStrips3D:strips")) == len(roadmap.edges)
    assert len(column(ents["/world/roadmap/links"], "LineStrips3D:strips")) == 1
    assert column(ents["/world/roadmap"], "nodes_per_component") == [4, 2, 1]


def _check_timeline(ents: dict, n_wp: int) -> None:
    """plan_step: one step per waypoint (boundary waypoints counted in both segments)."""
    from dexplan.viz import STEP_SECONDS

    assert steps(ents["/world/object"]) == list(range(n_wp))
    assert steps(ents["/world/hand/f0_distal"]) == list(range(n_wp))
    times = steps(ents["/world/object"], "time")
    assert times[-1].total_seconds() == pytest.approx((n_wp - 1) * STEP_SECONDS)
    assert steps(ents["/plan/fc/full"]) == list(range(n_wp))
    assert steps(ents["/plan/segment"]) == [0, 5]
    texts = column(ents["/plan/segment"], "TextLog:text")
    assert any("transfer" in t for t in texts) and any("regrasp of finger 0" in t for t in texts)
    assert column(ents["/plan/state/free_finger"], "StateChange:state") == ["none", "finger 0"]


def _check_poses(ents: dict, plan_doc: dict, hand: Hand) -> None:
    """The object follows the waypoints; the hand links follow forward kinematics."""
    trans = column(ents["/world/object"], "Transform3D:translation")
    wps = [w for s in plan_doc["segments"] for w in s["waypoints"]]
    np.testing.assert_allclose(
        np.array(trans), np.array([w["object_pose_xyzquat"][:3] for w in wps]), atol=1e-6
    )
    # the fingertip frames are the sphere centres
    tip = np.array(column(ents["/world/hand/f2_tip"], "Transform3D:translation"))
    fk = np.array([hand.fingertip_positions(np.asarray(w["q"]))[2] for w in wps])
    np.testing.assert_allclose(tip, fk, atol=1e-6)


def _check_contacts(ents: dict, plan_doc: dict, hand: Hand, n_wp: int) -> None:
    """Finger 0 is free at the 3 interior regrasp waypoints: its contact is empty there."""
    free_steps = [6, 7, 8]
    for i in range(hand.n_fingers):
        for name, per_step in (("", 1), ("/cone", plan_doc["friction_edges"] + 1)):
            chunks = ents[f"/world/contacts/finger_{i}{name}"]
            comp = "LineStrips3D:strips" if name else "Points3D:positions"
            sizes = {}
            for ch in chunks:
                rb = ch.to_record_batch()
                if "plan_step" in rb.schema.names:
                    ts, bs = rb.column("plan_step").to_pylist(), rb.column(comp).to_pylist()
                    sizes.update({t: len(b) for t, b in zip(ts, bs, strict=True)})
            want = {t: 0 if (i == 0 and t in free_steps) else per_step for t in range(n_wp)}
            assert sizes == want, (i, name)
    # min over subgrasps only where every finger holds
    assert len(column(ents["/plan/fc/min_subgrasp"], "Scalars:scalars")) == n_wp - len(free_steps)


def test_record_plan_entities_and_timeline(
    tmp_path: Path, paper_hand: Hand, plan_doc: dict, fc_stub
) -> None:
    from dexplan.viz import record_plan

    roadmap = make_roadmap(plan_doc)
    out = tmp_path / "plan.rrd"
    record_plan(plan_doc, out, roadmap=roadmap)
    assert out.stat().st_size > 0
    ents = read_rrd(out)

    n_wp = sum(len(s["waypoints"]) for s in plan_doc["segments"])
    expected = _expected_plan_entities(paper_hand)
    assert expected <= set(ents), sorted(expected - set(ents))
    # the world is right-handed, z up
    assert column(ents["/world"], "ViewCoordinates:xyz")
    _check_roadmap_entities(ents, roadmap)
    _check_timeline(ents, n_wp)
    _check_poses(ents, plan_doc, paper_hand)
    _check_contacts(ents, plan_doc, paper_hand, n_wp)
    # the quality summary: the file has no stats.quality, so the segments' figures
    # (one transfer turning the object 0.1 rad = 5.73 degrees, one regrasp)
    (quality,) = column(ents["/plan/quality"], "TextDocument:text")
    assert "| transfers | 1 |" in quality and "| regrasps | 1 |" in quality
    assert "| rotation per transfer, median (deg) | 5.73 |" in quality

    # a blueprint travels with the recording
    from rerun.chunk import RrdReader

    assert RrdReader(out).blueprints()


def test_record_roadmap_alone_and_with_scene(tmp_path: Path, plan_doc: dict) -> None:
    from dexplan.viz import record_roadmap

    roadmap = make_roadmap(plan_doc)
    out = tmp_path / "rm.rrd"
    summary = record_roadmap(roadmap, out)
    assert summary.nodes == (4, 2, 1) and summary.components == 3
    assert summary.merged_components == 2 and summary.links == (1, 1, 0)
    ents = read_rrd(out)
    assert len(column(ents["/world/roadmap/nodes"], "Points3D:positions")) == roadmap.n_vertices
    assert not any(p.startswith("/world/hand") for p in ents)

    out2 = tmp_path / "rm_scene.rrd"
    record_roadmap(roadmap, out2, scene=plan_doc)
    ents2 = read_rrd(out2)
    assert "/world/hand/f2_tip" in ents2 and "/world/obstacles/obstacle0" in ents2
    assert steps(ents2["/world/object"], "roadmap_node") == list(range(roadmap.n_vertices))
    node_pos = np.array(column(ents2["/world/object"], "Transform3D:translation"))
    np.testing.assert_allclose(node_pos, roadmap.vertices[:, :3], atol=1e-6)

    out3 = tmp_path / "rm_still.rrd"
    record_roadmap(roadmap, out3, scene=plan_doc, browse_nodes=False)
    obj = read_rrd(out3)["/world/object"]
    assert all(ch.is_static for ch in obj)  # the start configuration, no timeline
    start = plan_doc["start"]["object_pose_xyzquat"][:3]
    np.testing.assert_allclose(column(obj, "Transform3D:translation"), [start], atol=1e-6)


def test_write_recording_from_files(tmp_path: Path, plan_doc: dict, fc_stub) -> None:
    from dexplan.planfile.document import write_plan
    from dexplan.viz import write_recording

    plan_path = tmp_path / "plan.json"
    write_plan(plan_path, plan_doc)
    rm_path = tmp_path / "rm.npz"
    make_roadmap(plan_doc).save(rm_path)
    a = write_recording(plan_path, tmp_path / "a.rrd", roadmap=rm_path)
    assert "/world/roadmap/links" in read_rrd(a)
    b = write_recording(rm_path, tmp_path / "b.rrd")
    assert "/world/roadmap/nodes" in read_rrd(b) and "/plan/segment" not in read_rrd(b)
    c = write_recording(rm_path, tmp_path / "c.rrd", plan=plan_path)
    ents = read_rrd(c)
    assert "/world/hand/f1_distal" in ents
    assert steps(ents["/world/hand/f1_distal"], "roadmap_node") == list(range(7))
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "a.rrd",
        "b.rrd",
        "c.rrd",
        "plan.json",
        "rm.npz",
    ]  # no temporary files left behind


def test_mesh_object_and_bad_inputs(tmp_path: Path, plan_doc: dict, fc_stub) -> None:
    from dexplan.core.errors import InvalidInputError, PlanFileError
    from dexplan.model.objects import BUILTIN_MESH_DIR
    from dexplan.viz import record_plan, show

    doc = dict(plan_doc)
    doc["object"] = {"shape": "mesh", "path": str(Path(BUILTIN_MESH_DIR) / "ellipsoid.obj")}
    doc["segments"] = plan_doc["segments"][:1]
    out = tmp_path / "mesh.rrd"
    record_plan(doc, out)  # contacts off the mesh surface are drawn where they are stated
    ents = read_rrd(out)
    assert column(ents["/world/object/shape"], "Mesh3D:vertex_positions")

    with pytest.raises(PlanFileError, match="segments"):
        record_plan({k: v for k, v in plan_doc.items() if k != "segments"}, tmp_path / "x.rrd")
    with pytest.raises(InvalidInputError, match="folder"):
        record_plan(plan_doc, tmp_path / "missing" / "x.rrd")
    with pytest.raises(PlanFileError, match="not found"):
        show(tmp_path / "nope.rrd")


def test_show_headless_fails_clearly(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, plan_doc: dict
) -> None:
    from dexplan.viz import show

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(sys, "platform", "linux")
    with pytest.raises(DependencyError, match="no display"):
        show(plan_doc)


def test_failed_recording_leaves_no_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, plan_doc: dict
) -> None:
    from dexplan import viz
    from dexplan.viz import plan_recording

    def boom(*args: object, **kwargs: object) -> None:
        raise RuntimeError("boom")

    monkeypatch.setattr(plan_recording, "_log_plan_states", boom)
    with pytest.raises(RuntimeError, match="boom"):
        viz.record_plan(plan_doc, tmp_path / "x.rrd")
    assert list(tmp_path.iterdir()) == []


def test_summarize_empty_and_linkless_roadmaps(plan_doc: dict) -> None:
    from dexplan.viz import summarize_roadmap

    rm = make_roadmap(plan_doc)
    empty = type(rm)(np.zeros((0, rm.vertices.shape[1])), np.zeros((0, 2), np.int64),
                     np.zeros((0, 2), np.int64), "none", "k")  # fmt: skip
    s = summarize_roadmap(empty)
    assert s.components == 0 and s.nodes == () and "0 nodes" in s.markdown()
    rm.links = np.zeros((0, 2), np.int64)
    s = summarize_roadmap(rm)
    assert s.components == s.merged_components == 3 and s.merged == (0, 1, 2)


def test_plan_with_rrd_writes_a_recording_of_the_plan(capfd, tmp_path) -> None:
    """``dexplan plan -o p.json --rrd p.rrd``: the plan, and a recording that reads back."""
    from cli_contract import run_cli

    plan_file, rrd = tmp_path / "p.json", tmp_path / "p.rrd"
    args = ["-q", "--time-limit", "300", "-o", plan_file, "--rrd", rrd]
    code, stdout, err = run_cli(capfd, "plan", *args)
    assert code == 0, err
    assert stdout.startswith("status: solved")
    chunks = read_rrd(rrd)
    n_waypoints = sum(len(s["waypoints"]) for s in json.loads(plan_file.read_text())["segments"])
    steps = [
        v
        for ch in chunks["/world/object"]
        if "plan_step" in (rb := ch.to_record_batch()).schema.names
        for v in rb.column("plan_step").to_pylist()
        if v is not None
    ]
    assert sorted(steps) == list(range(n_waypoints))  # the object at every waypoint, once
    assert "/world/hand/f0_tip" in chunks
