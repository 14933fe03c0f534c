"""``package://`` mesh URIs: scenario folders, ROS_PACKAGE_PATH, wheels, plan-file hashes."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import trimesh
from cli_contract import assert_bad_input, run_cli

from dexplan.cli import main as cli
from dexplan.core.errors import ModelError, PlanFileError
from dexplan.model.hand.builtin import example_robot_data_share
from dexplan.model.hand.hand import Hand
from dexplan.model.hand.packages import (
    ROS_PACKAGE_PATH,
    mesh_sha256,
    package_search_path,
    search_dirs,
)
from dexplan.model.scenario import load_scenario
from dexplan.planfile import hand_from_plan, hand_table

TIPS = ["f0_tip", "f1_tip", "f2_tip"]
URI = "package://my_hand_description/meshes/palm.stl"
PALM_CYLINDER = '<geometry><cylinder radius="0.09" length="0.01"/></geometry>'


def _workspace(root: Path, extent: float = 0.1) -> Path:
    """A ROS workspace ``root/src/my_hand_description`` with a palm mesh; its ``src``."""
    pkg = root / "src" / "my_hand_description"
    (pkg / "meshes").mkdir(parents=True)
    (pkg / "package.xml").write_text("<package><name>my_hand_description</name></package>")
    trimesh.creation.box((extent, extent, 0.01)).export(pkg / "meshes" / "palm.stl")
    return root / "src"


def _urdf(folder: Path) -> Path:
    """The three-finger hand with its palm a ``package://`` mesh, in ``folder``."""
    text = Hand.builtin("three_finger").urdf_xml
    assert PALM_CYLINDER in text
    text = text.replace(PALM_CYLINDER, f'<geometry><mesh filename="{URI}"/></geometry>', 1)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "hand.urdf").write_text(text)
    return folder / "hand.urdf"


def test_unresolved_package_uri_names_the_search_folders(tmp_path: Path) -> None:
    path = _urdf(tmp_path / "elsewhere")
    with pytest.raises(ModelError, match="package_dirs"):
        Hand.from_urdf_file(path, TIPS)


def test_package_dirs_and_ros_package_path_resolve(tmp_path: Path, monkeypatch) -> None:
    src = _workspace(tmp_path / "ws")
    path = _urdf(tmp_path / "elsewhere")
    hand = Hand.from_urdf_file(path, TIPS, package_dirs=[src])
    assert list(hand.mesh_sha256) == [URI]
    # ROS_PACKAGE_PATH naming the workspace: packages two levels below are found
    monkeypatch.setenv(ROS_PACKAGE_PATH, str(tmp_path / "ws"))
    assert Hand.from_urdf_file(path, TIPS).mesh_sha256 == hand.mesh_sha256
    monkeypatch.delenv(ROS_PACKAGE_PATH)
    with package_search_path([src]):  # what --package-dir does
        assert Hand.from_urdf_file(path, TIPS).mesh_sha256 == hand.mesh_sha256
    assert ROS_PACKAGE_PATH not in __import__("os").environ


def test_example_robot_data_share_is_searched() -> None:
    assert str(example_robot_data_share()) in search_dirs()


def test_scenario_package_dirs(tmp_path: Path) -> None:
    _workspace(tmp_path / "ws")
    _urdf(tmp_path / "hands")
    scenario = tmp_path / "s.toml"
    scenario.write_text(
        '[hand]\nurdf = "hands/hand.urdf"\nfingertip_frames = ["f0_tip", "f1_tip", "f2_tip"]\n'
        'package_dirs = ["ws/src"]\n[object]\nshape = "sphere"\nradius = 0.04\n'
        "[start]\nobject_pose_xyzquat = [0, 0, 0.1, 0, 0, 0, 1]\n"
        "[goal]\nobject_pose_xyzquat = [0, 0, 0.1, 0, 0, 0, 1]\n"
    )
    spec = load_scenario(scenario).hand
    assert spec.package_dirs == ((tmp_path / "ws" / "src").resolve(),)
    assert spec.fingertip_radius is None  # read from the URDF's tip spheres
    assert Hand.from_spec(spec).fingertip_radius == pytest.approx(0.012)


def test_plan_keeps_uris_and_refuses_other_meshes(tmp_path: Path) -> None:
    src = _workspace(tmp_path / "ws")
    hand = Hand.from_urdf_file(_urdf(tmp_path / "h"), TIPS, package_dirs=[src])
    table = hand_table(hand)
    assert URI in table["urdf_xml"] and str(tmp_path) not in table["urdf_xml"]
    assert list(table["mesh_sha256"]) == [URI]
    # another machine: the same package elsewhere rebuilds the hand
    other = _workspace(tmp_path / "other")
    assert hand_from_plan(table, [other]).mesh_sha256 == hand.mesh_sha256
    # a different mesh under the same URI is refused
    changed = _workspace(tmp_path / "changed", extent=0.12)
    with pytest.raises(PlanFileError, match=r"hand\.mesh_sha256: mesh 'package://my_hand"):
        hand_from_plan(table, [changed])
    # no mesh at all: the message says where meshes are searched
    with pytest.raises(PlanFileError, match="--package-dir"):
        hand_from_plan(table, [tmp_path / "nowhere"])


def _with_package_mesh(plan: Path, ws_src: Path) -> None:
    """The plan's hand with an extra palm mesh ``package://my_hand_description/...``.

    The mesh sits 0.5 m below the palm, clear of everything, so the plan stays valid.
    """
    doc = json.loads(plan.read_text())
    extra = (
        '<collision><origin xyz="0 0 -0.5"/>'
        f'<geometry><mesh filename="{URI}"/></geometry></collision>'
    )
    text = doc["hand"]["urdf_xml"]
    head, sep, tail = text.partition('<link name="palm">')
    assert sep, "the paper hand's palm link"
    doc["hand"]["urdf_xml"] = head + sep + extra + tail
    doc["hand"]["mesh_sha256"] = mesh_sha256(doc["hand"]["urdf_xml"], [ws_src])
    plan.write_text(json.dumps(doc))


def test_verify_package_dir(paper_plan, tmp_path: Path, capfd) -> None:
    """`dexplan verify --package-dir`: the plan's package:// mesh found, changed or missing."""
    src = _workspace(tmp_path / "ws", extent=0.01)
    plan = paper_plan(1, tmp_path)
    _with_package_mesh(plan, src)
    code, _, err = run_cli(capfd, "verify", plan)
    assert_bad_input(code, err, names=["--package-dir"])
    code, out, _ = run_cli(capfd, "verify", plan, "--package-dir", src)
    assert code == cli.EXIT_OK and out.startswith("OK"), out
    other = _workspace(tmp_path / "other", extent=0.02)
    code, _, err = run_cli(capfd, "verify", plan, "--package-dir", other)
    assert_bad_input(code, err, names=["hand.mesh_sha256", URI])


def test_plan_of_a_scenario_package_dirs_hand_is_verified(tmp_path: Path) -> None:
    """The planner's own verification finds the meshes where the scenario's
    ``package_dirs`` put them (before, it searched only the plan's folder,
    ROS_PACKAGE_PATH and example-robot-data, and every such plan failed)."""
    import dexplan

    _workspace(tmp_path / "ws")
    _urdf(tmp_path / "hands")
    scenario = tmp_path / "s.toml"
    scenario.write_text(
        '[hand]\nurdf = "hands/hand.urdf"\nfingertip_frames = ["f0_tip", "f1_tip", "f2_tip"]\n'
        'package_dirs = ["ws/src"]\n[object]\nshape = "sphere"\nradius = 0.04\n'
        '[contact]\nmu = 1.0\nfc_margin = 0.002\nmodel = "soft"\ntorsion = 0.005\n'
        "[start]\nobject_pose_xyzquat = [0, 0, 0.1, 0, 0, 0, 1]\n"
        # 20 degrees about z: one transfer
        "[goal]\nobject_pose_xyzquat = [0, 0, 0.1, 0, 0, 0.17364817766693033, 0.984807753012208]\n"
    )
    plan = dexplan.plan(load_scenario(scenario), seed=1, quality="none", time_limit=60.0)
    assert plan.result.solved, plan.result.message
    table = hand_table(plan.hand)
    assert URI in table["urdf_xml"] and list(table["mesh_sha256"]) == [URI]
