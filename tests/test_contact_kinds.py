"""Edge contacts wherever faces alone cannot hold, and the screened-out failure message."""

from __future__ import annotations

import numpy as np

from dexplan.model.grasp.halfspace import faces_cannot_hold
from dexplan.model.hand.hand import Hand
from dexplan.model.objects import Box, Sphere
from dexplan.planning.diagnostics import Rejections
from dexplan.planning.gsn.contact_kinds import face_normals, faces_only_reason

CUBE_NORMALS = np.vstack([np.eye(3), -np.eye(3)])


def test_three_fingers_on_cube_faces_cannot_hold_four_can() -> None:
    # 2-finger subgrasps on adjacent faces push 90 deg apart: more than two cones close
    assert faces_cannot_hold(CUBE_NORMALS, 3, 0.8)
    # with 4 fingers two opposite pairs keep every 3-finger subgrasp possible
    assert not faces_cannot_hold(CUBE_NORMALS, 4, 0.8)
    # above mu = 1 (cone half-angle > 45 deg) adjacent faces may oppose
    assert not faces_cannot_hold(CUBE_NORMALS, 3, 1.2)


def test_face_normals_of_a_box_and_none_for_a_sphere() -> None:
    normals = face_normals(Box((0.065, 0.065, 0.065)))
    assert normals is not None
    assert sorted(map(tuple, normals.round(6).tolist())) == sorted(
        map(tuple, CUBE_NORMALS.tolist())
    )
    assert face_normals(Sphere(0.03)) is None


def test_faces_only_reason_names_the_subgrasp() -> None:
    hand = Hand.builtin("three_finger")
    reason = faces_only_reason(Box((0.06, 0.06, 0.06)), hand, 3, 0.8)
    assert reason == (
        "faces only: no 2-finger subgrasp of hand 'three_finger' can be force closure at mu 0.8"
    )
    assert faces_only_reason(Sphere(0.04), hand, 3, 0.8) is None


def test_screened_out_message() -> None:
    common = dict(
        attempts=400, ik_failures=0, valid=0, bounds=0, joint_limits=0, collision=0,
        force_closure=0, top_pairs=(),
    )  # fmt: skip
    reason = "faces only: no 2-finger subgrasp of hand 'h' can be force closure at mu 0.8"
    line = Rejections(checked=0, screened=312, screen_reason=reason, **common).describe()
    assert "every grasp was screened out before any check (312 object poses)" in line
    assert line.endswith(reason)
    # something reached the checker: the usual counts
    line = Rejections(checked=5, screened=3, **common).describe()
    assert "0 of 5 checked states valid" in line
