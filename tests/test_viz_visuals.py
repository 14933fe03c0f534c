"""The hand drawn as it looks: URDF visual geometry, with a collision-geometry fallback."""

from __future__ import annotations

from pathlib import Path

from dexplan.model.hand.hand import Hand
from dexplan.viz.visuals import hand_package_dirs, visual_geometry


def test_allegro_visual_meshes_load_one_per_link(tmp_path: Path) -> None:
    hand = Hand.builtin("allegro")
    visual = visual_geometry(hand)
    assert visual is not None
    # the URDF has one <visual> per link, each an STL mesh with triangles
    assert visual.ngeoms == hand.urdf_xml.count("<visual>")
    for g in visual.geometryObjects:
        assert g.meshPath.endswith(".STL")
        assert int(g.geometry.num_tris) > 0
        assert 0 <= int(g.parentFrame) < hand.model.nframes


def test_missing_meshes_fall_back_to_collision_geometry(tmp_path: Path) -> None:
    hand = Hand.builtin("allegro")
    assert str(hand_package_dirs(tmp_path)[1]) in hand.package_dirs
    hand.package_dirs = (str(tmp_path),)  # a plan moved to where the meshes are not
    assert visual_geometry(hand) is None


def test_hand_without_visuals_uses_collision_geometry(tmp_path: Path) -> None:
    assert visual_geometry(Hand.builtin("paper")) is None
