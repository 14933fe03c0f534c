"""Loading hands: builtin Allegro hands, URDF checks, capsules, native stderr."""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from collections import Counter
from importlib import metadata
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import pytest

from dexplan.core.errors import DependencyError, ModelError
from dexplan.core.native_output import captured_stderr
from dexplan.model.collision import CollisionWorld
from dexplan.model.hand import builtin as hand_module
from dexplan.model.hand.builtin import ALLEGRO_TIPS, example_robot_data_file
from dexplan.model.hand.hand import Hand
from dexplan.model.hand.urdf import MOUNT_LINK, mount_urdf
from dexplan.model.objects.primitives import Sphere

#: A valid fingertip-only grasp of a R 6 cm sphere at (0.09, 0, -0.01)
#: in palm_link (right hand), joints in Pinocchio order.
ALLEGRO_GRASP_Q = np.array(
    [
        *(0.224, 0.8432, 0.7398, 1.5262, 1.2633, 0.4505, -0.1501, 0.9058),  # index, thumb
        *(0.1159, 0.491, 0.9425, 0.4704, -0.2485, 0.4538, 1.6597, 0.6968),  # middle, ring
    ]
)
ALLEGRO_SPHERE_PALM = np.array([0.09, 0.0, -0.01])
ALLEGRO_SPHERE_R = 0.06
#: The left hand mirrors the right through palm_link's xz plane: the abduction
#: joints of index, middle and ring change sign, the thumb's do not.
LEFT_FROM_RIGHT = np.ones(16)
LEFT_FROM_RIGHT[[0, 8, 12]] = -1.0


def _collision_elements(urdf_xml: str) -> int:
    root = ET.fromstring(urdf_xml)
    return sum(len(link.findall("collision")) for link in root.findall("link"))


@pytest.fixture(scope="module")
def allegro() -> Hand:
    return Hand.builtin("allegro")


@pytest.fixture(scope="module")
def allegro_left() -> Hand:
    return Hand.builtin("allegro_left")


@pytest.fixture(scope="module")
def three() -> Hand:
    return Hand.builtin("three_finger")


# ------------------------------------------------------------------ Allegro
@pytest.mark.parametrize("name", ["allegro", "allegro_left"])
def test_allegro_structure(name: str) -> None:
    h = Hand.builtin(name)
    assert h.name == name
    assert h.nq == 16 and h.n_fingers == 4
    assert h.fingertip_frames == ALLEGRO_TIPS
    assert h.fingertip_radius == 0.012
    # Pinocchio order: index q[0:4], thumb q[4:8], middle q[8:12], ring q[12:16]
    assert h.joint_names == tuple(
        f"joint_{k}.0" for k in (0, 1, 2, 3, 12, 13, 14, 15, 4, 5, 6, 7, 8, 9, 10, 11)
    )
    assert [list(i) for i in h.finger_q_index] == [
        [0, 1, 2, 3],
        [8, 9, 10, 11],
        [12, 13, 14, 15],
        [4, 5, 6, 7],
    ]
    assert h.lower[4] == pytest.approx(0.263)  # pin.neutral's 0 is outside [0.263, 1.396]
    assert h.within_limits(h.neutral)
    assert h.collision_exclude == (("palm_link", "link_13.0"),)
    # 16 boxes (3 on the palm, 2 on the thumb's base, 1 on each other
    # non-distal link), a capsule on each distal link and a sphere on each
    # fingertip: 24 shapes, all loaded
    geoms = h.geom_model.geometryObjects
    assert len(geoms) == _collision_elements(h.urdf_xml) == 24

    def links_of(kind: type) -> Counter[str]:
        return Counter(
            h.model.frames[g.parentFrame].name for g in geoms if isinstance(g.geometry, kind)
        )

    boxes = links_of(coal.Box)
    assert boxes == {
        "palm_link": 3,
        "link_12.0": 2,
        **{f"link_{k}.0": 1 for k in (0, 1, 2, 4, 5, 6, 8, 9, 10, 13, 14)},
    }
    assert sum(boxes.values()) == 16
    distal = {tip.removesuffix("_tip") for tip in ALLEGRO_TIPS}
    assert distal == {"link_3.0", "link_7.0", "link_11.0", "link_15.0"}
    assert links_of(coal.Capsule) == dict.fromkeys(distal, 1)
    assert links_of(coal.Sphere) == dict.fromkeys(ALLEGRO_TIPS, 1)
    for g in geoms:
        if isinstance(g.geometry, coal.Capsule):  # no wider than the fingertip
            assert g.geometry.radius == pytest.approx(0.0098)
            assert g.geometry.radius < h.fingertip_radius
        elif isinstance(g.geometry, coal.Sphere):
            assert g.geometry.radius == pytest.approx(0.012)


@pytest.mark.parametrize("name", ["allegro", "allegro_left"])
def test_allegro_palm_up_in_the_world_frame(name: str) -> None:
    h = Hand.builtin(name)
    rng = np.random.default_rng(0)
    for q in (h.neutral, rng.uniform(h.lower, h.upper)):
        palm = h.frame_placements(q)["palm_link"]
        np.testing.assert_allclose(palm.rotation[:, 0], [0, 0, 1], atol=1e-12)  # palm normal
        np.testing.assert_allclose(palm.rotation[:, 2], [1, 0, 0], atol=1e-12)  # fingers
        np.testing.assert_allclose(palm.translation, 0.0, atol=1e-12)
    # the fingertips of the open hand point along +x and stay near the palm plane
    tips = h.fingertip_positions(h.neutral)
    assert np.all(tips[:3, 0] > 0.1)
    # the placement is part of the URDF text (the plan file carries it)
    assert f'<link name="{MOUNT_LINK}"/>' in h.urdf_xml
    again = Hand(h.urdf_xml, h.fingertip_frames, h.fingertip_radius)
    np.testing.assert_allclose(again.fingertip_positions(h.neutral), tips, atol=1e-12)


def _sphere_world(h: Hand) -> np.ndarray:
    palm = h.frame_placements(h.neutral)["palm_link"]
    return palm.act(ALLEGRO_SPHERE_PALM)


def test_allegro_measured_grasp_touches_the_sphere(allegro: Hand, allegro_left: Hand) -> None:
    for h, q in ((allegro, ALLEGRO_GRASP_Q), (allegro_left, LEFT_FROM_RIGHT * ALLEGRO_GRASP_Q)):
        assert h.within_limits(q)
        centre = _sphere_world(h)
        np.testing.assert_allclose(centre, [-0.01, 0.0, 0.09], atol=1e-12)  # above the palm
        gaps = np.linalg.norm(h.fingertip_positions(q) - centre, axis=1) - (
            ALLEGRO_SPHERE_R + h.fingertip_radius
        )
        assert np.all(np.abs(gaps) < 1e-3), gaps
        # fingertip-only contact: no link collides with the sphere or with the hand
        world = CollisionWorld(h, Sphere(ALLEGRO_SPHERE_R))
        pose = np.r_[centre, 0.0, 0.0, 0.0, 1.0]
        report = world.check(q, pose, [True] * 4, first_only=False)
        assert report.free, report


def test_left_hand_mirrors_the_right(allegro: Hand, allegro_left: Hand) -> None:
    mirror = np.diag([1.0, -1.0, 1.0])  # world y (= -palm_link y)
    rng = np.random.default_rng(1)
    for _ in range(5):
        q = rng.uniform(allegro.lower, allegro.upper)
        ql = np.clip(LEFT_FROM_RIGHT * q, allegro_left.lower, allegro_left.upper)
        q = np.clip(LEFT_FROM_RIGHT * ql, allegro.lower, allegro.upper)
        np.testing.assert_allclose(
            allegro_left.fingertip_positions(ql),
            allegro.fingertip_positions(q) @ mirror,
            atol=1e-12,
        )


def test_allegro_loads_without_native_output(capfd) -> None:
    capfd.readouterr()
    Hand.builtin("allegro")
    Hand.builtin("allegro_left")
    Hand.builtin("three_finger")
    out, err = capfd.readouterr()
    assert out == "" and err == ""


def test_allegro_files_come_from_the_distribution() -> None:
    path = example_robot_data_file("allegro_hand_description/urdf/allegro_right_hand.urdf")
    dist = metadata.distribution("example-robot-data")
    assert path.is_file()
    assert Path(str(dist.locate_file(""))).resolve() in path.resolve().parents


def test_allegro_without_example_robot_data(monkeypatch) -> None:
    def missing(name: str) -> metadata.Distribution:
        raise metadata.PackageNotFoundError(name)

    monkeypatch.setattr(hand_module.metadata, "distribution", missing)
    want = r"hand 'allegro_left': example-robot-data is not installed: pip install 'dexplan\["
    with pytest.raises(DependencyError, match=want):
        Hand.builtin("allegro_left")


# ---------------------------------------------------------------- capsules
def test_capsules_are_parsed(three: Hand) -> None:
    gm = three.geom_model
    assert gm.ngeoms == _collision_elements(three.urdf_xml) == 13
    capsules = [g for g in gm.geometryObjects if isinstance(g.geometry, coal.Capsule)]
    assert len(capsules) == 6
    by_link = {three.model.frames[g.parentFrame].name: g for g in capsules}
    assert set(by_link) == {f"f{i}_{p}" for i in range(3) for p in ("proximal", "distal")}
    prox = by_link["f0_proximal"]
    assert prox.geometry.radius == pytest.approx(0.008)
    assert 2 * prox.geometry.halfLength == pytest.approx(0.049)
    # placed on its link at <origin xyz="0 0 0.0325">: the capsule's centre is
    # halfway between the two flexion joints whatever the configuration
    rng = np.random.default_rng(2)
    data = three.model.createData()
    gd = pin.GeometryData(gm)
    for _ in range(5):
        q = rng.uniform(three.lower, three.upper)
        pin.updateGeometryPlacements(three.model, data, gm, gd, q)
        mcp = three.joint_origin(1, q)
        pip = three.joint_origin(2, q)
        k = gm.getGeometryId(prox.name)
        np.testing.assert_allclose(gd.oMg[k].translation, 0.5 * (mcp + pip), atol=1e-12)
        axis = (pip - mcp) / np.linalg.norm(pip - mcp)
        np.testing.assert_allclose(gd.oMg[k].rotation[:, 2], axis, atol=1e-12)


def test_capsules_collide(three: Hand) -> None:
    """A small ball at the middle of the proximal phalanx hits that capsule."""
    world = CollisionWorld(three, Sphere(0.005))
    q = three.neutral.copy()
    mid = 0.5 * (three.joint_origin(1, q) + three.joint_origin(2, q))
    hit = world.check(
        q, np.r_[mid + np.array([0.011, 0, 0]), 0, 0, 0, 1], [False] * 3, first_only=False
    )
    assert not hit.free and "f0_proximal" in hit.pair
    miss = world.check(q, np.r_[mid + np.array([0.015, 0, 0]), 0, 0, 0, 1], [False] * 3)
    assert miss.free


def test_capsule_hand_from_file_is_quiet(tmp_path, capfd) -> None:
    path = tmp_path / "three.urdf"
    path.write_text(Hand.builtin("three_finger").urdf_xml)
    capfd.readouterr()
    h = Hand.from_urdf_file(path, ["f0_tip", "f1_tip", "f2_tip"], 0.012)
    assert h.geom_model.ngeoms == 13
    assert capfd.readouterr() == ("", "")


def test_three_finger_hand_grasps_a_sphere(three: Hand) -> None:
    """Tips reach a R 4 cm sphere at z = 0.1 at many azimuths, collision-free."""
    assert three.nq == 9 and three.n_fingers == 3
    assert all(three.has_closed_form_ik(i) for i in range(3))
    radius, centre = 0.04, np.array([0.0, 0.0, 0.1])
    world = CollisionWorld(three, Sphere(radius))
    pose = np.r_[centre, 0, 0, 0, 1]
    d = radius + three.fingertip_radius
    for turn_deg in (-60.0, -30.0, 0.0, 20.0, 45.0, 60.0):  # covers the 120-deg period
        for elevation_deg in (-45.0, -20.0, 0.0):
            q = three.neutral.copy()
            for i in range(3):
                az = math.radians(120.0 * i + turn_deg)
                el = math.radians(elevation_deg)
                target = centre + d * np.array(
                    [math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)]
                )
                res = three.finger_ik(i, target, q)
                assert res.success, (turn_deg, elevation_deg, i, res)
                q[three.finger_q_index[i]] = res.q_finger
            gaps = np.linalg.norm(three.fingertip_positions(q) - centre, axis=1) - d
            assert np.all(np.abs(gaps) < 1e-6)
            report = world.check(q, pose, [True] * 3, first_only=False)
            assert report.free, (turn_deg, elevation_deg, report)


# ------------------------------------------------------------ bad URDF hands
TIPS3 = ["f0_tip", "f1_tip", "f2_tip"]
DISTAL_CAPSULE = (
    '<collision><origin xyz="0 0 0.024500"/>'
    '<geometry><capsule radius="0.008" length="0.017000"/></geometry></collision>'
)


def _edit(three: Hand, old: str, new: str) -> str:
    assert old in three.urdf_xml
    return three.urdf_xml.replace(old, new, 1)


def test_link_without_collision_geometry_is_named(three: Hand) -> None:
    text = _edit(three, DISTAL_CAPSULE, "")
    with pytest.raises(ModelError, match=r"link 'f0_distal' .*no collision geometry"):
        Hand(text, TIPS3, 0.012)
    tip = '<collision><geometry><sphere radius="0.012"/></geometry></collision>'
    # a tip frame without a sphere gets one (docs/hands.md, "Fingertips")
    hand = Hand(_edit(three, tip, ""), TIPS3, 0.012)
    added = hand.geom_model.geometryObjects[hand.tip_geom_ids[0]]
    assert added.name == "f0_tip_fingertip" and added.geometry.radius == 0.012


def _finger(f: str, y: float, *, virtual_knuckle: bool) -> str:
    """A 2-DOF finger on the palm at (0, y, 0): knuckle, phalanx, fingertip sphere."""
    knuckle = (
        ""
        if virtual_knuckle
        else '<collision><geometry><sphere radius="0.01"/></geometry></collision>'
    )
    return f"""
      <joint name="{f}_abd" type="revolute"><parent link="palm"/><child link="{f}_knuckle"/>
        <origin xyz="0 {y} 0.01"/><axis xyz="1 0 0"/>
        <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
      <link name="{f}_knuckle">{knuckle}</link>
      <joint name="{f}_flex" type="revolute"><parent link="{f}_knuckle"/><child link="{f}_link"/>
        <axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
      <link name="{f}_link"><collision><origin xyz="0 0 0.04"/>
        <geometry><capsule radius="0.008" length="0.05"/></geometry></collision></link>
      <joint name="{f}_tip_joint" type="fixed"><parent link="{f}_link"/><child link="{f}_tip"/>
        <origin xyz="0 0 0.09"/></joint>
      <link name="{f}_tip"><collision><geometry><sphere radius="0.01"/></geometry></collision>
      </link>"""


def _two_finger_urdf(*, virtual_knuckle: bool) -> str:
    return (
        '<robot name="two"><link name="palm"><collision>'
        '<geometry><box size="0.1 0.1 0.01"/></geometry></collision></link>'
        + _finger("a", 0.03, virtual_knuckle=virtual_knuckle)
        + _finger("b", -0.03, virtual_knuckle=False)
        + "</robot>"
    )


def test_zero_length_virtual_link_needs_no_geometry() -> None:
    """A universal knuckle (two joints at one point) may have a bare link between them."""
    h = Hand(_two_finger_urdf(virtual_knuckle=True), ["a_tip", "b_tip"], 0.01)
    assert h.nq == 4 and h.geom_model.ngeoms == 1 + 3 + 2
    text = _two_finger_urdf(virtual_knuckle=True).replace(
        '<link name="a_link"><collision><origin xyz="0 0 0.04"/>\n'
        '        <geometry><capsule radius="0.008" length="0.05"/></geometry></collision></link>',
        '<link name="a_link"/>',
    )
    assert text.count("<capsule") == 1
    with pytest.raises(ModelError, match=r"link 'a_link' \(moved by joint 'a_flex'"):
        Hand(text, ["a_tip", "b_tip"], 0.01)


@pytest.mark.parametrize(
    ("old", "new", "match"),
    [
        (
            'lower="-0.6" upper="1.2"',
            'lower="1.2" upper="-0.6"',
            r"joint 'f0_mcp' has inverted limits: lower=1.2 > upper=-0.6",
        ),
        ('upper="1.2"', 'upper="inf"', r"joint 'f0_mcp': limit upper must be a finite"),
        ('lower="-0.6"', 'lower="nan"', r"joint 'f0_mcp': limit lower must be a finite"),
        ('lower="-0.6"', 'lower="abc"', r"joint 'f0_mcp': limit lower must be a finite"),
        ('type="revolute"', 'type="continuous"', r"joint 'f0_abd' has type 'continuous'"),
        (
            '<limit lower="-0.7" upper="0.7" effort="1" velocity="2"/>',
            "",
            r"revolute joint 'f0_abd' has no <limit",
        ),
        ('<capsule radius="0.008"', '<capsule radius="-1"', r"<capsule> of link 'f0_proximal'"),
        ('<box size="0.014 0.014 0.015000"/>', '<cone radius="1"/>', r"Unknown geometry type"),
        (
            '<box size="0.014 0.014 0.015000"/>',
            '<mesh filename="missing_mesh.stl"/>',
            r"Mesh missing_mesh.stl could not be found.*package_dirs",
        ),
        ('<robot name="dexplan_three_finger_hand">', "<robot>", r"No name given for the robot"),
        ("</robot>", "", r"malformed URDF XML: no element found: line \d+"),
        ('<link name="f0_knuckle">', '<link name="f0_knuckle"><x>', r"mismatched tag: line"),
    ],
)
def test_bad_urdf_gives_one_clean_error(three: Hand, capfd, old: str, new: str, match: str) -> None:
    text = _edit(three, old, new)
    capfd.readouterr()
    with pytest.raises(ModelError, match=match) as info:
        Hand(text, TIPS3, 0.012)
    assert "\n" not in str(info.value)
    assert len(str(info.value)) < 400
    assert capfd.readouterr() == ("", "")  # native output became the message or was dropped


def test_binary_and_non_utf8_urdf(tmp_path) -> None:
    png = tmp_path / "hand.urdf"
    png.write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR" + bytes(range(256)))
    with pytest.raises(ModelError, match=r"hand\.urdf.* is not a UTF-8 text URDF"):
        Hand.from_urdf_file(png, TIPS3, 0.012)
    latin1 = tmp_path / "latin1.urdf"
    latin1.write_bytes('<robot name="é"/>'.encode("latin-1"))
    with pytest.raises(ModelError, match="not a UTF-8 text URDF"):
        Hand.from_urdf_file(latin1, TIPS3, 0.012)
    nul = tmp_path / "nul.urdf"
    nul.write_bytes(b"<robot name='x'>\x00</robot>")
    with pytest.raises(ModelError, match=r"not a UTF-8 text URDF \(NUL"):
        Hand.from_urdf_file(nul, TIPS3, 0.012)
    with pytest.raises(ModelError, match="not a UTF-8 text URDF"):
        Hand(b"\xff\xfe<robot/>", TIPS3, 0.012)  # type: ignore[arg-type]
    with pytest.raises(ModelError, match="must be URDF text"):
        Hand(42, TIPS3, 0.012)  # type: ignore[arg-type]


@pytest.mark.parametrize("radius", [0.0, -0.01, math.nan, math.inf, 0.5, "big"])
def test_fingertip_radius_must_be_plausible(three: Hand, radius: object) -> None:
    with pytest.raises(
        ModelError, match=r"fingertip_radius must be a finite number in \(0, 0\.05\]"
    ):
        Hand(three.urdf_xml, TIPS3, radius)  # type: ignore[arg-type]


def test_fingertip_frames_and_exclusions_are_checked(three: Hand) -> None:
    with pytest.raises(ModelError, match="unknown fingertip frame 'f9_tip'"):
        Hand(three.urdf_xml, ["f0_tip", "f9_tip"], 0.012)
    with pytest.raises(ModelError, match="fingertip_frames must be a list"):
        Hand(three.urdf_xml, "f0_tip", 0.012)
    with pytest.raises(ModelError, match="at least 2 fingertip frames"):
        Hand(three.urdf_xml, ["f0_tip"], 0.012)
    with pytest.raises(ModelError, match=r"unknown link 'f0_proximl'; did you mean 'f0_proximal'"):
        Hand(three.urdf_xml, TIPS3, 0.012, collision_exclude=[("palm", "f0_proximl")])
    with pytest.raises(ModelError, match=r"collision_exclude\[0\] must be a \[link, link\] pair"):
        Hand(three.urdf_xml, TIPS3, 0.012, collision_exclude=[("palm",)])  # type: ignore[list-item]
    ok = Hand(three.urdf_xml, TIPS3, 0.012, collision_exclude=[["palm", "f0_proximal"]])
    assert ok.collision_exclude == (("palm", "f0_proximal"),)


# ------------------------------------------------------------------ mounting
def test_mount_urdf_places_the_root(three: Hand) -> None:
    text = mount_urdf(three.urdf_xml, (0.0, 0.0, math.pi / 2), (0.0, 0.0, 0.2))
    robot_tag = '<robot name="dexplan_three_finger_hand">'
    head = three.urdf_xml[: three.urdf_xml.index(robot_tag) + len(robot_tag)]
    assert text.startswith(head) and text.endswith(three.urdf_xml[len(head) :])
    h = Hand(text, TIPS3, 0.012)
    palm = h.frame_placements(h.neutral)["palm"]
    np.testing.assert_allclose(palm.translation, [0, 0, 0.2], atol=1e-12)
    np.testing.assert_allclose(palm.rotation[:, 0], [0, 1, 0], atol=1e-12)
    p0 = three.fingertip_positions(three.neutral)
    np.testing.assert_allclose(
        h.fingertip_positions(h.neutral), p0 @ palm.rotation.T + [0, 0, 0.2], atol=1e-12
    )
    with pytest.raises(ModelError, match="already has a link named"):
        mount_urdf(text, (0, 0, 0))
    with pytest.raises(ModelError, match="malformed XML"):
        mount_urdf("<robot", (0, 0, 0))


# --------------------------------------------------------------- fd capture
def test_captured_stderr_takes_fd_2_and_restores_it(capfd) -> None:
    capfd.readouterr()
    with captured_stderr() as err:
        os.write(2, b"Error:   Could not parse thing [x]\n         at line 3 in foo.cpp\n")
    assert err.lines == ["Error:   Could not parse thing [x]", "at line 3 in foo.cpp"]
    assert err.first_line() == "Could not parse thing [x]"
    with pytest.raises(RuntimeError), captured_stderr() as err2:
        os.write(2, b"before the failure\n")
        raise RuntimeError("boom")
    assert err2.first_line() == "before the failure"
    with captured_stderr() as outer:
        os.write(2, b"outer\n")
        with captured_stderr() as inner:
            os.write(2, b"inner\n")
        os.write(2, b"outer again\n")
    assert inner.lines == ["inner"] and outer.lines == ["outer", "outer again"]
    os.write(2, b"visible\n")
    assert capfd.readouterr().err == "visible\n"
    assert captured_stderr().__class__  # reusable factory
