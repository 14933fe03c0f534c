"""Local planners: the free finger's capped OMPL fallback; dropping needless regrasps."""

import dataclasses
import itertools
from pathlib import Path

import numpy as np

from dexplan.core.segments import Segment
from dexplan.model.grasp.rolling import ContactMotion
from dexplan.model.scenario import default_scenario
from dexplan.planning.context import build_context
from dexplan.planning.local.grasps import grasp_from_state
from dexplan.planning.local.smoothing import drop_regrasps
from dexplan.planning.local.transitions import TransitionSettings, densify_poses


def test_blocked_free_finger_move_falls_back_to_ompl() -> None:
    """No via points: moves the straight line cannot make are planned by RRTConnect."""
    scenario = default_scenario()
    ctx = build_context(scenario, seed=3, transition_settings=TransitionSettings(via_points=0))
    x = ctx.sampler.sample_at_pose(scenario.start.object_pose_xyzquat)
    assert x is not None
    pose, q0 = x[:7], x[7:]
    tr, hand = ctx.transitions, ctx.hand
    finger, idx = 0, hand.finger_q_index[0]
    mask = (False, True, True, True)
    rng = np.random.default_rng(0)
    free = []
    while len(free) < 12:
        q = q0.copy()
        q[idx] = rng.uniform(hand.lower[idx], hand.upper[idx])
        if ctx.world.is_free(q, pose, mask):
            free.append(q)
    pairs = itertools.combinations(free, 2)
    blocked = [(a, b) for a, b in pairs if tr._segment_free(finger, a, b, pose, mask) is None][:4]
    assert blocked, "expected free configurations the straight line cannot join"
    found = 0
    for qa, qb in blocked:
        path = tr._joint_move(finger, qa, qb, pose, mask)
        if path is None:
            continue
        found += 1
        np.testing.assert_array_equal(path[0], qa)
        np.testing.assert_array_equal(path[-1], qb)
        qs = np.array(path)
        others = np.setdiff1d(np.arange(hand.nq), idx)
        assert np.all(qs[:, others] == q0[others])  # only the free finger moves
        assert np.max(np.abs(np.diff(qs, axis=0))) <= tr.settings.max_step_rad + 1e-12
        assert all(ctx.world.is_free(q, pose, mask) for q in qs)
        assert np.all(qs >= hand.lower - 1e-12) and np.all(qs <= hand.upper + 1e-12)
    assert found >= 1
    assert tr.stats["transit_planned"] == len(blocked)
    assert tr.stats["transit_planned_found"] == found


def _landing(tr, f, pose, q, grasp, future):
    """A regrasp of finger f onto a contact it can follow the whole of ``future`` from."""
    for point, normal, _ in tr.landing_candidates(f, pose, q, grasp, future, limit=50):
        seg = tr.regrasp(pose, q, grasp, f, point, normal)
        new = grasp.replace(f, point, normal)
        if seg is not None and tr.transfer(future, 0, seg.end.q, new).reason is None:
            return seg, new
    raise AssertionError(f"no landing for finger {f}")


def _fixed_contacts():
    """The builtin scenario with the paper's fixed contacts (it rolls its fingertips)."""
    return dataclasses.replace(default_scenario(), contact_motion=ContactMotion.FIXED)


def test_needless_regrasps_are_dropped() -> None:
    """R_f, T, R_f where the old grasp makes T too -> T on the old grasp, one R_f."""
    scenario = _fixed_contacts()
    ctx = build_context(scenario, seed=2)
    tr = ctx.transitions
    x = ctx.sampler.sample_at_pose(scenario.start.object_pose_xyzquat)
    assert x is not None
    pose, q = x[:7], x[7:]
    grasp = grasp_from_state(tr, pose, q)
    lifted = pose.copy()
    lifted[2] += 0.004
    moves = densify_poses(np.stack([pose, lifted]), 0.002, 0.04)
    f = 1
    r1, grasp1 = _landing(tr, f, pose, q, grasp, moves)
    t = tr.transfer(moves, 0, r1.end.q, grasp1)
    assert t.reason is None
    transfer = Segment("transfer", None, t.waypoints)
    lifted2 = lifted.copy()
    lifted2[2] += 0.004
    moves2 = densify_poses(np.stack([lifted, lifted2]), 0.002, 0.04)
    r2, grasp2 = _landing(tr, f, lifted, transfer.end.q, grasp1, moves2)
    t2 = tr.transfer(moves2, 0, r2.end.q, grasp2)
    last = Segment("transfer", None, t2.waypoints)
    assert tr.transfer(moves, 0, q, grasp).reason is None  # the old grasp lifts it too

    # R_f T R_f T: the old grasp makes the first transfer (R_f T R_f -> T R_f), then
    # the last one too (R_f T -> T), and the transfers in a row join: one transfer
    out = drop_regrasps(tr, [r1, transfer, r2, last])
    assert [s.kind for s in out] == ["transfer"]
    assert out[0].start is r1.start  # the plan before it is unchanged
    np.testing.assert_array_equal(out[0].end.object_pose_xyzquat, lifted2)
    held = np.array(out[0].start.contacts)
    assert all(np.array_equal(np.array(w.contacts), held) for w in out[0].waypoints)
    poses = np.array([w.object_pose_xyzquat for w in out[0].waypoints])
    assert np.all(np.diff(poses[:, 2]) >= 0) and len(poses) >= len(moves) + len(moves2) - 1
    # a trailing regrasp goes (the object is already where the plan ends)
    assert [s.kind for s in drop_regrasps(tr, [transfer, r2])] == ["transfer"]
    # the only segment is kept even if it is a regrasp
    assert drop_regrasps(tr, [r1]) == [r1]


def test_tracked_follow_bounds_the_transfer() -> None:
    """A transfer stops no later than the finger that tracks the least far (links checked)."""
    scenario = _fixed_contacts()  # the tracked follow keeps each contact fixed
    ctx = build_context(scenario, seed=2)
    x = ctx.sampler.sample_at_pose(scenario.start.object_pose_xyzquat)
    assert x is not None
    pose, q = x[:7], x[7:]
    tr = ctx.transitions
    grasp = grasp_from_state(tr, pose, q)
    goal = pose.copy()
    goal[3:] = [0.0, 0.0, 1.0, 0.0]  # 180 degrees about z
    poses = densify_poses(np.stack([pose, goal]), 0.008, 0.04)
    r = ctx.hand.fingertip_radius
    counts = []
    for f in range(ctx.hand.n_fingers):
        tip = grasp.points[f] + r * grasp.normals_out[f]
        bound = int(tr.follow_scores(f, tip[None], poses)[0])
        count, q_land = tr.track_score(f, q, tip, grasp.normals_out[f], poses, len(poses))
        assert q_land is not None  # the current contact: its own posture
        np.testing.assert_allclose(q_land, q[ctx.hand.finger_q_index[f]])
        assert 1 <= count <= bound + tr.settings.follow_stride
        counts.append(count)
    res = tr.transfer(poses, 0, q, grasp)
    assert res.reached + 1 <= min(counts)


def _start_grasp_and_yaw_turn(ctx, scenario):
    """A sampled grasp at the start pose and the densified poses of a 180-degree yaw from it."""
    x = ctx.sampler.sample_at_pose(scenario.start.object_pose_xyzquat)
    assert x is not None
    pose, q = x[:7], x[7:]
    grasp = grasp_from_state(ctx.transitions, pose, q)
    goal = pose.copy()
    goal[3:] = [0.0, 0.0, 1.0, 0.0]
    return pose, q, grasp, densify_poses(np.stack([pose, goal]), 0.008, 0.04)


def test_resumed_track_equals_a_fresh_one() -> None:
    """A track resumed from a stored one (later start, longer horizon) counts as a fresh one."""
    scenario = default_scenario()
    ctx = build_context(scenario, seed=2)
    fresh = build_context(scenario, seed=2).transitions
    _pose, q, grasp, poses = _start_grasp_and_yaw_turn(ctx, scenario)
    tr = ctx.transitions
    r = ctx.hand.fingertip_radius
    idx = ctx.hand.finger_q_index
    for f in range(ctx.hand.n_fingers):
        tip, n_out = grasp.points[f] + r * grasp.normals_out[f], grasp.normals_out[f]
        short, _ = tr.track_score(f, q, tip, n_out, poses, 5)
        full, _ = tr.track_score(f, q, tip, n_out, poses, len(poses))
        assert full == fresh.track_score(f, q, tip, n_out, poses, len(poses))[0]
        assert short == min(5, full)
        # from a later pose, the finger where the track had it
        k = min(3, full - 1)
        track = next(t for key, t in tr._tracks.items() if key[0] == f)
        q_k = q.copy()
        q_k[idx[f]] = track.qs[k]
        got = tr.track_score(f, q_k, tip, n_out, poses[k:], len(poses))
        want = fresh.track_score(f, q_k, tip, n_out, poses[k:], len(poses))
        assert got[0] == want[0]
        np.testing.assert_array_equal(got[1], want[1])


def _landing_is_sound(ctx, scenario, pose, grasp, point, normal) -> None:
    """A landing of finger 0 judged without the code that chose it.

    On the surface with the surface's own normal there (the object's closest
    point), reachable by finger 0's inverse kinematics, and every 3-finger
    subgrasp of the new grasp force closure under the verifier's exact check.
    """
    from dexplan.core.pose import transform_points
    from dexplan.model.grasp import exact_force_closure

    obj, hand = ctx.obj, ctx.hand
    p_s, n_s = (np.asarray(v, dtype=float).reshape(3) for v in obj.closest_point(point))
    np.testing.assert_allclose(p_s, point, atol=1e-6)
    np.testing.assert_allclose(n_s, normal, atol=1e-6)
    tip = transform_points(pose, (point + hand.fingertip_radius * normal)[None])[0]
    assert hand.finger_ik(0, tip).success
    P = grasp.points.copy()
    N = -grasp.normals_out.copy()
    P[0], N[0] = point, -normal
    verdict = exact_force_closure(
        P,
        N,
        scenario.mu,
        edges=scenario.friction_edges,
        torque_scale=obj.characteristic_length,
        subgrasps=True,
        contact_model=scenario.contact_model,
        torsion=scenario.torsion,
    )
    assert verdict in ("fc_linear", "fc_dense"), verdict


def test_non_redundant_fingers_track_fewer_landings() -> None:
    """Closed-form fingers track at most ``tracked_landings_simple`` landings; all are sound."""
    scenario = default_scenario()
    for simple in (0, 2):
        settings = TransitionSettings(tracked_landings_simple=simple)
        ctx = build_context(scenario, seed=2, transition_settings=settings)
        pose, q, grasp, poses = _start_grasp_and_yaw_turn(ctx, scenario)
        tr = ctx.transitions
        assert tr.tracked_count(0) == min(simple, tr.settings.tracked_landings)
        got = list(tr.landing_candidates(0, pose, q, grasp, poses, limit=6))
        assert got
        assert len(tr._postures) <= simple  # one landing posture per tracked landing
        for point, normal, _ in got:
            _landing_is_sound(ctx, scenario, pose, grasp, point, normal)


def test_free_finger_checks_agree_with_the_full_check() -> None:
    """A free finger's moves are checked on its own pairs: same answers as is_free.

    From a collision-free reference (only the finger free), random postures of
    that finger, colliding and not, get the full check's answer; a
    configuration where another finger moves too, or another mask, falls back
    to the full check.
    """
    from dexplan.model.scenario import load_scenario

    for path, fingers in (
        ("scenarios/paper_sphere.toml", (0, 2)),
        ("scenarios/allegro_sphere.toml", (1, 3)),
        ("scenarios/cube_obstacle.toml", (0,)),
    ):
        scenario = load_scenario(path)
        ctx = build_context(scenario, seed=2)
        tr, hand, world = ctx.transitions, ctx.hand, ctx.world
        x = ctx.sampler.sample_at_pose(scenario.start.object_pose_xyzquat)
        assert x is not None
        pose, q0 = x[:7], x[7:]
        rng = np.random.default_rng(1)
        for finger in fingers:
            idx = hand.finger_q_index[finger]
            mask = tuple(i != finger for i in range(hand.n_fingers))
            ref = None
            while ref is None:
                q = q0.copy()
                q[idx] = rng.uniform(hand.lower[idx], hand.upper[idx])
                ref = q if world.is_free(q, pose, mask) else None
            answers = []
            for _ in range(150):
                q = ref.copy()
                q[idx] = rng.uniform(hand.lower[idx], hand.upper[idx])
                full = world.is_free(q, pose, mask)
                assert tr._moved_free(finger, q, ref, pose, mask) == full
                answers.append(full)
            assert any(answers) and not all(answers), path  # both kinds were met
            other = hand.finger_q_index[(finger + 1) % hand.n_fingers]
            q = ref.copy()
            q[other] = hand.upper[other]
            assert tr._moved_free(finger, q, ref, pose, mask) == world.is_free(q, pose, mask)


def test_no_finger_is_let_go_that_the_others_cannot_hold_within_the_effort_limits() -> None:
    """A regrasp starts only where the other fingers hold the weight within 1 N m.

    The same start grasp, once with the scenario's 0.1 kg and once with
    30 kg (which no 3-finger hold of the paper hand carries within its 1 N m
    effort limits): the heavy object gets no regrasp at all, each refusal
    counted as a weak hold, and no OMPL or IK work is spent on it.
    """
    import dataclasses

    scenario = default_scenario()
    light = build_context(scenario, seed=3)
    heavy = build_context(dataclasses.replace(scenario, object_mass=30.0), seed=3)
    x = light.sampler.sample_at_pose(scenario.start.object_pose_xyzquat)
    assert x is not None
    pose, q = x[:7], x[7:]
    grasp = grasp_from_state(light.transitions, pose, q)
    future = densify_poses(np.array([pose, pose]), 0.008, 0.04)
    assert all(light.transitions.can_release(f, pose, q, grasp) for f in range(4))
    assert not any(heavy.transitions.can_release(f, pose, q, grasp) for f in range(4))
    assert heavy.transitions.stats["weak_holds"] == 4
    for f in range(4):
        point, normal, _ = next(
            iter(light.transitions.landing_candidates(f, pose, q, grasp, future))
        )
        assert heavy.transitions.regrasp(pose, q, grasp, f, point, normal) is None
    assert heavy.transitions.stats["regrasp_attempts"] == 0
    assert heavy.transitions.stats["weak_holds"] == 8


def test_rolled_grasps_are_judged_with_the_verifiers_normals(monkeypatch) -> None:
    """A rolling transfer judges force closure with the normals the verifier will use.

    On a box edge the tip sphere's closest-point normal (towards its centre,
    which places the tip) and the stated contact's own normal (a face's, what
    the verifier reads, :func:`fingertip_contact`) can differ by degrees,
    enough to flip force closure near its margin. Fingers are landed on the
    cube's edges, then the grasp rolls through the quarter turn; every force
    closure check of the transfer must see the verifier's normals.
    """
    from dexplan.core.pose import inverse_transform_points
    from dexplan.model.objects.fingertip import fingertip_contact
    from dexplan.model.scenario.scenario import load_scenario
    from dexplan.planning.gsn.space import POSE_DIM

    sc = load_scenario(Path(__file__).resolve().parents[1] / "scenarios" / "allegro_cube.toml")
    ctx = build_context(sc, seed=8)
    trans, obj, hand = ctx.transitions, ctx.obj, ctx.hand
    r = hand.fingertip_radius
    half = 0.5 * np.asarray(sc.object["size"])
    rolling = trans.transfers
    judged: list[tuple[np.ndarray, np.ndarray]] = []
    quality = rolling.quality

    def recording(grasp):
        judged.append((grasp.points.copy(), grasp.normals_out.copy()))
        return quality(grasp)

    monkeypatch.setattr(rolling, "quality", recording)
    differ = 0
    for x in ctx.sampler.samples_at_pose(sc.start.object_pose_xyzquat, 6, np.random.default_rng(1)):
        pose, q = x[:POSE_DIM], x[POSE_DIM:]
        grasp = grasp_from_state(trans, pose, q)
        poses = densify_poses(np.array([pose, sc.goal.object_pose_xyzquat]), 0.008, 0.04)
        for f in range(hand.n_fingers):
            for p, n, _ in trans.landing_candidates(f, pose, q, grasp, poses, None, 8):
                if np.sum(np.abs(np.abs(p) - half) < 1e-6) < 2:
                    continue  # not on an edge
                seg = trans.regrasp(pose, q, grasp, f, p, n)
                if seg is None:
                    continue
                judged.clear()
                tr = trans.transfer(poses, 0, seg.end.q, grasp.replace(f, p, n))
                for w, (points, normals) in zip(tr.waypoints[1:], judged, strict=False):
                    tips = inverse_transform_points(
                        w.object_pose_xyzquat, hand.fingertip_positions(w.q)
                    )
                    for g in range(hand.n_fingers):
                        np.testing.assert_allclose(points[g], w.contacts[g], atol=1e-12)
                        read = fingertip_contact(obj, points[g], tips[g], r)[1]
                        np.testing.assert_allclose(normals[g], read, atol=1e-12)
                        centre = np.ravel(obj.closest_point(tips[g])[1])
                        differ += int(np.degrees(np.arccos(min(1.0, float(read @ centre)))) > 1)
                break
    assert differ > 0  # some edge contact where the two readings differ
