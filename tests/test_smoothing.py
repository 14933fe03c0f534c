"""Smoothing: merged regrasps state the contacts the plan states."""

import numpy as np

from dexplan.model.scenario import default_scenario
from dexplan.planning.context import build_context
from dexplan.planning.local.grasps import grasp_from_state
from dexplan.planning.local.smoothing import merge_regrasps
from dexplan.planning.local.transitions import GraspContacts, densify_poses


def test_merged_regrasp_keeps_the_stated_contacts() -> None:
    """R_f R_f -> R_f copies the holding fingers' stated contacts, not their closest points.

    A stated contact need not be the surface point closest to its fingertip
    centre: in a concave region the fingertip sphere touches near two places
    and the closest point may be the other one (the verifier reads the stated
    contact when the fingertip is within 1 mm of it). The merged regrasp must
    state the same contacts for the other fingers at every waypoint
    (``regrasp_one_finger``); re-deriving them from the fingertips made
    bean_yaw180 seed 5 an ``invalid_plan``. Here a holding finger's contact
    is stated 0.5 mm from the point its fingertip touches on the sphere.
    """
    scenario = default_scenario()
    ctx = build_context(scenario, seed=2)
    tr = ctx.transitions
    x = ctx.sampler.sample_at_pose(scenario.start.object_pose_xyzquat)
    assert x is not None
    pose, q = x[:7], x[7:]
    touched = grasp_from_state(tr, pose, q)
    f, held = 1, 3
    c, n = touched.points[held], touched.normals_out[held]
    tangent = np.cross(n, [0.0, 0.0, 1.0] if abs(n[2]) < 0.9 else [1.0, 0.0, 0.0])
    pts, _ = tr.obj.closest_point((c + 5e-4 * tangent / np.linalg.norm(tangent))[None])
    stated = np.asarray(pts, dtype=float).reshape(3)
    assert 3e-4 < np.linalg.norm(stated - c) < 1e-3
    grasp = GraspContacts(touched.points.copy(), touched.normals_out.copy())
    grasp.points[held] = stated

    lifted = pose.copy()
    lifted[2] += 0.004
    future = densify_poses(np.stack([pose, lifted]), 0.002, 0.04)
    merged = None
    for point_a, normal_a, _ in tr.landing_candidates(f, pose, q, grasp, future, limit=20):
        r1 = tr.regrasp(pose, q, grasp, f, point_a, normal_a)
        if r1 is None:
            continue
        grasp_a = grasp.replace(f, point_a, normal_a)
        for point_b, normal_b, _ in tr.landing_candidates(
            f, pose, r1.end.q, grasp_a, future, limit=5
        ):
            r2 = tr.regrasp(pose, r1.end.q, grasp_a, f, point_b, normal_b)
            if r2 is None:
                continue
            out = merge_regrasps(tr, [r1, r2])
            if len(out) == 1:
                merged = (r1, r2, out[0])
                break
        if merged is not None:
            break
    assert merged is not None, "expected two regrasps of one finger that merge"
    r1, r2, seg = merged
    assert seg.kind == "regrasp" and seg.finger == f
    assert seg.start is r1.start and seg.end is r2.end
    np.testing.assert_array_equal(r1.start.contacts[held], stated)
    for w in seg.waypoints:
        np.testing.assert_array_equal(w.object_pose_xyzquat, pose)
        for i, contact in enumerate(w.contacts):
            if i != f:
                np.testing.assert_array_equal(contact, r1.start.contacts[i])
    assert all(w.contacts[f] is None for w in seg.waypoints[1:-1])
