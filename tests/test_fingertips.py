"""Fingertips are what they say: a sphere at the tip frame, the rest of the link checked."""

from __future__ import annotations

import numpy as np
import pytest

from dexplan.core.errors import ModelError
from dexplan.model.collision import CollisionWorld
from dexplan.model.hand.hand import Hand
from dexplan.model.objects import Box

TIP_Z = 0.06  # m: fingertip centre above each finger's joint at q = 0


def _finger(k: int, x: float, tip_collision: str) -> str:
    """A 1-joint finger at (x, 0, 0): a capsule link along z up to its tip frame."""
    return f"""
  <joint name="j{k}" type="revolute">
    <parent link="palm"/><child link="distal{k}"/>
    <origin xyz="{x} 0 0"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
  <link name="distal{k}">
    <collision><origin xyz="0 0 {TIP_Z / 2}"/>
      <geometry><capsule radius="0.008" length="{TIP_Z}"/></geometry></collision>
  </link>
  <joint name="tip{k}_fix" type="fixed">
    <parent link="distal{k}"/><child link="tip{k}"/><origin xyz="0 0 {TIP_Z}"/>
  </joint>
  <link name="tip{k}">{tip_collision}</link>"""


def _urdf(tip_collision: str = "") -> str:
    fingers = "".join(_finger(k, x, tip_collision) for k, x in enumerate((0.0, 0.2)))
    return f"""<robot name="dip">
  <link name="palm"><collision><origin xyz="0 0 -0.02"/>
    <geometry><box size="0.3 0.1 0.01"/></geometry></collision></link>{fingers}
</robot>"""


def test_distal_link_dipping_into_the_object_is_rejected() -> None:
    """Finger 0's tip rests on the box's top face while its link pierces the box."""
    hand = Hand(_urdf(), ["tip0", "tip1"], 0.01, name="dip")
    # box z in [0.02, 0.05]: the tip centre (z = 0.06) is one radius above its top face
    world = CollisionWorld(hand, Box((0.1, 0.1, 0.03)))
    pose = np.array([0.0, 0.0, 0.035, 0.0, 0.0, 0.0, 1.0])
    q = np.zeros(2)
    assert hand.fingertip_positions(q)[0] == pytest.approx([0.0, 0.0, TIP_Z])
    report = world.check(q, pose, [True, False], first_only=False)
    assert report.max_penetration == pytest.approx(0.0, abs=1e-9)
    assert not report.free
    assert report.pair is not None and set(report.pair) == {"distal0", "object"}
    # the same finger held clear of the box (object lowered by 3 cm) is free
    low = pose + np.array([0.0, 0.0, -0.1, 0, 0, 0, 0])
    assert world.check(q, low, [False, False]).free


def test_missing_tip_sphere_is_added_at_the_tip_frame() -> None:
    hand = Hand(_urdf(), ["tip0", "tip1"], 0.01, name="dip")
    for fid, g in zip(hand.tip_frame_ids, hand.tip_geom_ids, strict=True):
        go = hand.geom_model.geometryObjects[g]
        assert go.parentFrame == fid
        assert go.geometry.radius == pytest.approx(0.01)
        assert go.name.endswith("_fingertip")


def test_radius_read_from_the_urdf_sphere() -> None:
    sphere = '<collision><geometry><sphere radius="0.0085"/></geometry></collision>'
    hand = Hand(_urdf(sphere), ["tip0", "tip1"], None, name="dip")
    assert hand.fingertip_radius == pytest.approx(0.0085)
    # the URDF's sphere is the fingertip: nothing added
    assert [hand.geom_model.geometryObjects[g].name for g in hand.tip_geom_ids] == [
        "tip0_0",
        "tip1_0",
    ]


def test_radius_disagreeing_with_the_urdf_sphere_is_refused() -> None:
    sphere = '<collision><geometry><sphere radius="0.0085"/></geometry></collision>'
    with pytest.raises(ModelError, match=r"fingertip_radius=0.012 m disagrees .*0\.0085"):
        Hand(_urdf(sphere), ["tip0", "tip1"], 0.012, name="dip")


def test_no_radius_and_no_sphere_is_refused() -> None:
    with pytest.raises(ModelError, match="fingertip_radius is not given and fingertip frame"):
        Hand(_urdf(), ["tip0", "tip1"], None, name="dip")


@pytest.mark.parametrize("radius", [0.0, 0.06, 0.5, float("nan"), True])
def test_one_radius_rule(radius: object) -> None:
    with pytest.raises(ModelError, match=r"fingertip_radius must be a finite number in \(0, 0\.05"):
        Hand(_urdf(), ["tip0", "tip1"], radius, name="dip")  # type: ignore[arg-type]


def test_unknown_tip_frame_did_you_mean_and_full_list() -> None:
    with pytest.raises(ModelError) as info:
        Hand(_urdf(), ["tip0", "tipp1"], 0.01, name="dip")
    msg = str(info.value)
    assert "did you mean 'tip1'?" in msg
    for frame in ("palm", "distal0", "distal1", "tip0", "tip1"):
        assert frame in msg
