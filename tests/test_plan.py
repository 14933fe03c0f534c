"""Plans from the planner pass the verifier; tampered plans are rejected."""

import copy
import json
from pathlib import Path

import numpy as np
import pytest

from dexplan.core.errors import PlanFileError
from dexplan.model.scenario import builtin_scenario_path, default_scenario, load_scenario
from dexplan.planfile import build_plan_document, read_plan, verify_plan, write_plan
from dexplan.planning.context import build_hand
from dexplan.planning.planner import plan


@pytest.fixture(scope="module")
def solved():
    scenario = default_scenario()
    result = plan(scenario, time_limit=300.0)
    assert result.solved, (result.status, result.message)
    doc = build_plan_document(scenario, build_hand(scenario), result)
    return scenario, result, doc


def _rules(doc) -> set[str]:
    return {v.rule for v in verify_plan(doc).violations}


def _first(doc, kind: str):
    for si, s in enumerate(doc["segments"]):
        if s["kind"] == kind:
            return si, s
    raise AssertionError(f"no {kind} segment")


def test_planner_plan_passes_verify(solved) -> None:
    _, result, doc = solved
    report = verify_plan(doc)
    assert report.ok, [str(v) for v in report.violations[:5]]
    assert report.waypoints == sum(len(s["waypoints"]) for s in doc["segments"])
    assert result.stats.regrasps >= 1  # 180 degrees needs finger gaits
    kinds = [s["kind"] for s in doc["segments"]]
    assert "transfer" in kinds and "regrasp" in kinds


def test_planner_document_is_well_formed(solved) -> None:
    """Every field the planner writes is one the format knows (plan_schema)."""
    from dexplan.planfile.schema import validate_plan

    _, _, doc = solved
    validate_plan(doc)
    validate_plan(json.loads(json.dumps(doc)))
    for seg in doc["segments"]:
        assert (seg["finger"] is None) == (seg["kind"] == "transfer")


def test_plan_file_round_trip_atomic(solved, tmp_path: Path) -> None:
    _, _, doc = solved
    path = tmp_path / "p.json"
    write_plan(path, doc)
    assert read_plan(path) == json.loads(json.dumps(doc))
    assert [p.name for p in tmp_path.iterdir()] == ["p.json"]  # no temp file left
    with pytest.raises(PlanFileError, match="not found"):
        read_plan(tmp_path / "missing.json")
    (tmp_path / "bad.json").write_text("{")
    with pytest.raises(PlanFileError, match="JSON"):
        read_plan(tmp_path / "bad.json")
    (tmp_path / "other.json").write_text('{"format": "x"}')
    with pytest.raises(PlanFileError, match="format"):
        read_plan(tmp_path / "other.json")


def test_rejects_moved_waypoint(solved) -> None:
    doc = copy.deepcopy(solved[2])
    _, seg = _first(doc, "transfer")
    seg["waypoints"][1]["object_pose_xyzquat"][0] += 0.003
    assert {"fingertip_distance", "contact_matches_fingertip"} & _rules(doc)


def test_rejects_contact_off_surface(solved) -> None:
    doc = copy.deepcopy(solved[2])
    _, seg = _first(doc, "transfer")
    c = seg["waypoints"][0]["contacts"][0]
    seg["waypoints"][0]["contacts"][0] = [1.2 * v for v in c]
    assert "contact_on_surface" in _rules(doc)


def test_rejects_two_fingers_moving_in_regrasp(solved) -> None:
    doc = copy.deepcopy(solved[2])
    _, seg = _first(doc, "regrasp")
    other = (seg["finger"] + 1) % 4
    j = 3 * other
    for w in seg["waypoints"][1:-1]:
        w["q"][j] += 0.01
    assert "regrasp_one_finger" in _rules(doc)


def test_rejects_object_moving_in_regrasp(solved) -> None:
    doc = copy.deepcopy(solved[2])
    _, seg = _first(doc, "regrasp")
    seg["waypoints"][1]["object_pose_xyzquat"][2] += 0.002
    assert "regrasp_object_still" in _rules(doc)


def test_rejects_non_force_closure_holding_grasp(solved) -> None:
    doc = copy.deepcopy(solved[2])
    doc["mu"] = 0.0  # frictionless point contacts: never force closure with 4 fingers
    assert "force_closure" in _rules(doc)


def test_rejects_jump_between_waypoints(solved) -> None:
    doc = copy.deepcopy(solved[2])
    _, seg = _first(doc, "transfer")
    del seg["waypoints"][1:6]
    assert "step" in _rules(doc)


def test_rejects_missing_goal_and_broken_continuity(solved) -> None:
    doc = copy.deepcopy(solved[2])
    doc["goal"]["object_pose_xyzquat"] = [0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0]
    assert "goal" in _rules(doc)
    doc = copy.deepcopy(solved[2])
    del doc["segments"][1]["waypoints"][0]
    assert "continuity" in _rules(doc)


def test_same_seed_same_plan(solved) -> None:
    scenario, result, doc = solved
    again = plan(scenario, time_limit=300.0)
    assert again.solved
    # module 1 repeats as well: PRM's roadmap grows to milestone counts, not by the clock
    np.testing.assert_array_equal(again.gsn_path, result.gsn_path)
    doc2 = build_plan_document(scenario, build_hand(scenario), again)
    assert doc2["segments"] == doc["segments"]


@pytest.mark.parametrize("planner", ["KPIECE1", "RRTConnect"])
def test_same_seed_same_plan_with_an_obstacle(planner: str) -> None:
    """On the cube the plan follows the GSn path: module 1 must repeat too."""
    scenario = load_scenario(builtin_scenario_path("cube_obstacle"))
    seed = 4 if planner == "KPIECE1" else 1  # seeds both solve
    a = plan(scenario, planner=planner, seed=seed, time_limit=300.0)
    b = plan(scenario, planner=planner, seed=seed, time_limit=300.0)
    assert a.solved and b.solved, (a.message, b.message)
    np.testing.assert_array_equal(a.gsn_path, b.gsn_path)
    assert [s.kind for s in a.segments] == [s.kind for s in b.segments]
    for sa, sb in zip(a.segments, b.segments, strict=True):
        np.testing.assert_array_equal([w.q for w in sa.waypoints], [w.q for w in sb.waypoints])


def test_roadmap_save_load_answers_a_query(solved, tmp_path: Path) -> None:
    from dexplan.planning.context import build_context
    from dexplan.planning.roadmap.graph import Roadmap, scenario_key

    scenario, result, _ = solved
    path = tmp_path / "rm.npz"
    result.roadmap.save(path)
    key = scenario_key(build_context(scenario))
    loaded = Roadmap.load(path, key)
    np.testing.assert_array_equal(loaded.vertices, result.roadmap.vertices)
    np.testing.assert_array_equal(loaded.edges, result.roadmap.edges)
    answer = plan(scenario, roadmap=loaded, time_limit=300.0)
    assert answer.solved, (answer.status, answer.message)
    doc = build_plan_document(scenario, build_hand(scenario), answer)
    assert verify_plan(doc).ok
    with pytest.raises(PlanFileError, match="other models"):
        Roadmap.load(path, "0" * 16)


def _follows_all_the_way(ctx, x: np.ndarray) -> bool:
    """Whether the grasp ``x`` follows the scenario's straight move to the goal (IK-only)."""
    from dexplan.planning.local.grasps import grasp_follow
    from dexplan.planning.local.transitions import densify_poses

    sc, st = ctx.scenario, ctx.transitions.settings
    pose, goal = sc.start.object_pose_xyzquat, sc.goal.object_pose_xyzquat
    future = densify_poses(np.array([pose, goal]), st.max_step_m, st.max_step_rad)
    return grasp_follow(ctx.transitions, pose, x[7:], future)[0] >= len(future)


def _start_candidates(scenario, seed: int):
    """A start grasp chosen from 8 candidates, and the candidates, for ``seed``.

    Returns ``(ctx, ref, chosen, first, pool)``: the context the choice used,
    a fresh one of the same seed, the chosen state, the first candidate
    alone, and all 8 candidates.
    """
    from dexplan.planning.context import build_context
    from dexplan.planning.start import start_state

    pose = scenario.start.object_pose_xyzquat
    ctx = build_context(scenario, seed=seed)
    chosen = start_state(ctx, candidates=8, rng=np.random.default_rng([seed, 5]))
    ref = build_context(scenario, seed=seed)
    first = start_state(ref, candidates=1)
    extra = ref.sampler.samples_at_pose(pose, 7, np.random.default_rng([seed, 5]))
    assert chosen is not None and first is not None and len(extra) == 7
    pool = [first, *extra]
    assert any(np.array_equal(chosen, x) for x in pool)
    return ctx, ref, chosen, first, pool


@pytest.mark.parametrize(("name", "seed"), [("suite/box_tilt90", 2), ("paper_sphere", 2)])
def test_sampled_start_grasp_follows_all_the_way_or_is_strong(name: str, seed: int) -> None:
    """The start grasp is one that follows the straight move to the goal all the way
    if a candidate does (the first such); else, among the candidates that follow
    nearly as far as the best, one of the strongest few, and no stronger one
    of them lets more fingers go. The extra candidates leave the sampler's own
    stream as it was."""
    from dexplan.planning.context import build_context
    from dexplan.planning.local.grasps import grasp_follow, grasp_from_state
    from dexplan.planning.local.transitions import densify_poses
    from dexplan.planning.start import START_FOLLOW_SHARE, START_HOLD_CHECKS, start_state

    scenario = load_scenario(builtin_scenario_path(name))
    pose = scenario.start.object_pose_xyzquat
    if name != "paper_sphere":
        # a seed where the first candidate needs regrasps and another turns the box
        # alone: the first such within 1-12 (seed 2 today, tried first)
        for s in (seed, *(s for s in range(1, 13) if s != seed)):
            ctx, ref, chosen, first, pool = _start_candidates(scenario, s)
            covering = [x for x in pool if _follows_all_the_way(ref, x)]
            if covering and not _follows_all_the_way(ref, first):
                break
        else:
            raise AssertionError("no seed within 1-12 whose first start grasp needs regrasps")
        seed = s
        np.testing.assert_array_equal(chosen, covering[0])
    else:
        # no grasp of the paper hand turns the sphere 180 degrees: true of every seed
        ctx, ref, chosen, first, pool = _start_candidates(scenario, seed)
        covering = [x for x in pool if _follows_all_the_way(ref, x)]
        assert not covering
        tr = ref.transitions
        st = tr.settings
        goal = scenario.goal.object_pose_xyzquat
        future = densify_poses(np.array([pose, goal]), st.max_step_m, st.max_step_rad)
        follow = [grasp_follow(tr, pose, x[7:], future)[0] for x in pool]
        near = [
            x for x, f in zip(pool, follow, strict=True) if f >= START_FOLLOW_SHARE * max(follow)
        ]
        grasps = [grasp_from_state(tr, pose, x[7:]) for x in near]
        strength = [tr.grasp_quality(g, exact=True) for g in grasps]
        k = next(i for i, x in enumerate(near) if np.array_equal(x, chosen))
        assert sorted(strength, reverse=True).index(strength[k]) < START_HOLD_CHECKS

        def free(i: int) -> int:
            return sum(tr.can_release(f, pose, near[i][7:], grasps[i]) for f in range(4))

        stronger = [i for i in range(len(near)) if strength[i] > strength[k]]
        assert all(free(i) < free(k) for i in stronger)
    # the search that follows samples exactly as after the first grasp alone
    after = build_context(scenario, seed=seed)
    start_state(after, candidates=1)
    assert ctx.sampler.rng.random() == after.sampler.rng.random()


def test_start_q_a_little_off_the_surface_is_moved_onto_it(tmp_path) -> None:
    """A start.q whose fingertips are 1e-5 to 1e-3 m off the object plans.

    OMPL's constrained space takes states within 1e-5 only; the planner moves
    the joints onto GSn first (the plan starts there, within the 1 mm check).
    """
    import dataclasses

    from dexplan.planning.context import build_context
    from dexplan.planning.start import start_state

    scenario = default_scenario()
    ctx = build_context(scenario, seed=1)
    x0 = start_state(ctx, candidates=1)
    q_off = x0[7:] + 2e-3  # every joint 2 mrad off: fingertips ~1e-4 m off the sphere
    assert 1e-5 < ctx.gsn.residual(ctx.gsn.join(x0[:7], q_off)) < 1e-3
    start = dataclasses.replace(scenario.start, q=q_off)
    res = plan(dataclasses.replace(scenario, start=start), seed=1, time_limit=300.0)
    assert res.solved, res.message
    q_first = res.segments[0].start.q
    assert ctx.gsn.residual(ctx.gsn.join(x0[:7], q_first)) < 1e-8
    assert np.max(np.abs(q_first - q_off)) < 0.01


def test_joint_travel_sums_every_joint_change() -> None:
    """``joint_travel``: the L1 length of the hand's joint path over all segments."""
    from dexplan.core.segments import Segment, Waypoint, joint_travel

    pose = np.array([0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0])
    c = (np.zeros(3),)
    qs = [np.array([0.0, 0.0]), np.array([0.1, -0.2]), np.array([0.1, 0.3])]
    seg = Segment("transfer", None, tuple(Waypoint(pose, q, c) for q in qs))
    back = Segment("transfer", None, tuple(Waypoint(pose, q, c) for q in qs[::-1]))
    assert joint_travel([seg]) == pytest.approx(0.1 + 0.2 + 0.5)
    assert joint_travel([seg, back]) == pytest.approx(1.6)
    assert joint_travel([]) == 0.0


def test_the_allegro_starts_from_a_grasp_every_finger_can_leave() -> None:
    """Under the real hand's torque caps, the Allegro's start grasp lets its fingers go.

    The ranking of start grasps applies to redundant fingers too: the grasp
    kept is one from which each finger can be lifted while the other three
    hold the 0.1 kg ball within the scenario's 80 % of the effort limits (2 mm
    contact shifts included), else the one from which most can. Seed 1 has
    such a grasp among its candidates; on seed 2 none frees all four and the
    one kept frees three.
    """
    from dexplan.planning.context import build_context
    from dexplan.planning.local.grasps import grasp_from_state
    from dexplan.planning.start import start_state

    scenario = load_scenario(builtin_scenario_path("allegro_sphere"))
    assert scenario.hold_effort_share == 0.8
    pose = scenario.start.object_pose_xyzquat
    for seed, least in ((1, 4), (2, 3)):
        ctx = build_context(scenario, seed=seed)
        chosen = start_state(ctx, candidates=8)
        assert chosen is not None
        grasp = grasp_from_state(ctx.transitions, pose, chosen[7:])
        free = [ctx.transitions.can_release(f, pose, chosen[7:], grasp) for f in range(4)]
        assert sum(free) >= least, (seed, free)


def test_a_path_whose_object_trajectory_collides_is_explored_again() -> None:
    """When every reduction of the GSn path fails early, module 1 explores again.

    A query where the slerp between two GSn states clips the obstacle: both
    gait reductions stop at once (the object itself collides) and the
    edge-by-edge one hits its bisection limit; such a query used to end
    ``reduction_failed`` after about 1 s of its time limit. The first seed of
    cube_obstacle (within 1-20) that explores again is checked: seed 8 at the
    sampler's current settings, tried first; a sampler change moves it, and
    none within the bound fails the test.
    """
    scenario = load_scenario(builtin_scenario_path("cube_obstacle"))
    tried = []
    for seed in (8, *(s for s in range(1, 21) if s != 8)):
        events: list = []
        # a generous limit: what is checked must not hinge on the machine's speed
        res = plan(scenario, seed=seed, time_limit=300.0, progress=events.append)
        tried.append((seed, res.status, res.stats.explorations))
        if res.stats.explorations >= 2:
            break
    else:
        raise AssertionError(f"no seed of cube_obstacle within 1-20 explores again: {tried}")
    assert res.solved, res.message
    messages = [e.message for e in events]
    again = next(i for i, m in enumerate(messages) if m.startswith("exploring GSn again"))
    assert any("object_collision" in m for m in messages[:again])
    doc = build_plan_document(scenario, build_hand(scenario), res)
    assert verify_plan(doc).ok


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_start_candidates_left_untracked_could_not_be_near_the_best(seed: int) -> None:
    """The start grasp's near set, tracking only the grasps whose IK-only bound
    can reach the share of the best tracked one, is the set tracking them all gives."""
    from dexplan.planning.local.grasps import finger_follows, grasp_from_state
    from dexplan.planning.local.transitions import densify_poses
    from dexplan.planning.start import START_FOLLOW_SHARE, _near, _stroke_sum

    scenario = load_scenario(builtin_scenario_path("paper_sphere"))
    _, ref, _, _, pool = _start_candidates(scenario, seed)
    tr = ref.transitions
    pose, goal = scenario.start.object_pose_xyzquat, scenario.goal.object_pose_xyzquat
    future = densify_poses(np.array([pose, goal]), tr.settings.max_step_m, tr.settings.max_step_rad)
    grasps = [grasp_from_state(tr, pose, x[7:]) for x in pool]
    ik = [finger_follows(tr, g, future) for g in grasps]
    strokes = [_stroke_sum(tr, x, g, f, future) for x, g, f in zip(pool, grasps, ik, strict=True)]
    eager = [i for i, s in enumerate(strokes) if s >= START_FOLLOW_SHARE * max(strokes)]
    assert _near(tr, future, pool, grasps, ik) == eager
