import numpy as np
import pytest

from dexplan.core.errors import InvalidInputError
from dexplan.model.collision import CONTACT_PENETRATION_TOL, CollisionWorld, Obstacle
from dexplan.model.hand.hand import Hand
from dexplan.model.objects import Box, Sphere

CENTRE = np.array([0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0])


def _open_hand(hand: Hand) -> np.ndarray:
    q = hand.neutral.copy()
    q[1::3] = -0.5  # lean outwards: far from the object
    q[2::3] = 0.0
    return q


def _touching(hand: Hand, finger: int, depth: float = 0.0) -> np.ndarray:
    """Configuration with finger's tip touching the sphere (radius 0.04) at its equator."""
    q = _open_hand(hand)
    az = np.deg2rad(45 + 90 * finger)
    d = 0.04 + hand.fingertip_radius - depth
    target = CENTRE[:3] + d * np.array([np.cos(az), np.sin(az), 0.0])
    res = hand.finger_ik(finger, target, q)
    assert res.success
    q[hand.finger_q_index[finger]] = res.q_finger
    return q


def test_open_hand_is_free(paper_hand: Hand) -> None:
    world = CollisionWorld(paper_hand, Sphere(0.04))
    rep = world.check(_open_hand(paper_hand), CENTRE, [False] * 4)
    assert rep.free and rep.pair is None


def test_contact_finger_touch_is_not_a_collision(paper_hand: Hand) -> None:
    world = CollisionWorld(paper_hand, Sphere(0.04))
    q = _touching(paper_hand, 0)
    assert world.check(q, CENTRE, [True, False, False, False]).free
    # the same touch by a free finger is a collision with the object
    rep = world.check(q, CENTRE, [False] * 4)
    assert not rep.free and "object" in rep.pair and "f0_tip" in rep.pair


def test_contact_penetration_reported_beyond_tolerance(paper_hand: Hand) -> None:
    world = CollisionWorld(paper_hand, Sphere(0.04))
    shallow = world.check(_touching(paper_hand, 0, 0.5e-3), CENTRE, [True, False, False, False])
    assert shallow.free
    assert shallow.max_penetration == pytest.approx(0.5e-3, abs=1e-6)
    deep = world.check(_touching(paper_hand, 0, 3e-3), CENTRE, [True, False, False, False])
    assert not deep.free
    assert deep.max_penetration > CONTACT_PENETRATION_TOL


def test_finger_object_distance(paper_hand: Hand) -> None:
    world = CollisionWorld(paper_hand, Sphere(0.04))
    q = _touching(paper_hand, 1, depth=-0.005)  # 5 mm above the surface
    d = world.finger_object_distance(q, CENTRE, 1)
    assert d == pytest.approx(0.005, abs=1e-4)
    with pytest.raises(InvalidInputError):
        world.finger_object_distance(q, CENTRE, 9)


def test_obstacles_collide_with_hand_and_object(paper_hand: Hand) -> None:
    wall = Obstacle(Box([0.02, 0.3, 0.1]), (0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0), "wall")
    world = CollisionWorld(paper_hand, Sphere(0.01), [wall])
    assert world.object_collides(CENTRE)
    assert not world.object_collides(np.array([0.0, 0.2, 0.5, 0, 0, 0, 1.0]))
    far = np.array([0.5, 0.5, 0.5, 0, 0, 0, 1.0])
    rep = world.check(_open_hand(paper_hand), far, [False] * 4)
    assert rep.free  # the wall at x = 0 misses the open fingers at +-0.057
    table = Obstacle(Box([0.3, 0.3, 0.01]), (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0), "table")
    world2 = CollisionWorld(paper_hand, Sphere(0.01), [table])
    rep = world2.check(_open_hand(paper_hand), far, [False] * 4)
    assert not rep.free and "table_0" in rep.pair


def test_self_collision_between_fingers(paper_hand: Hand) -> None:
    world = CollisionWorld(paper_hand, Sphere(0.01))
    far = np.array([0.5, 0.5, 0.5, 0, 0, 0, 1.0])
    # all fingers bent fully inwards meet above the palm centre
    q = paper_hand.neutral.copy()
    q[1::3] = 1.2
    q[2::3] = 0.8
    rep = world.check(q, far, [False] * 4)
    assert not rep.free
    assert world.finger_of(rep.pair[0]) != world.finger_of(rep.pair[1])


def test_object_clearance_to_obstacles(paper_hand: Hand) -> None:
    """Exact distances: a sphere of radius 1 cm beside a 2 cm thick wall at x = 0."""
    wall = Obstacle(Box([0.02, 0.3, 0.3]), (0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0), "wall")
    world = CollisionWorld(paper_hand, Sphere(0.01), [wall])
    for gap in (0.0005, 0.003, 0.02):
        pose = np.array([0.01 + 0.01 + gap, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0])
        assert world.object_clearance(pose) == pytest.approx(gap, abs=1e-6)
        assert not world.object_collides(pose)
    assert world.object_clearance(CENTRE) <= 0.0 and world.object_collides(CENTRE)
    assert CollisionWorld(paper_hand, Sphere(0.01)).object_clearance(CENTRE) == np.inf


def test_pair_subset_answers_as_its_pairs_one_by_one() -> None:
    """``pairs_collide`` over a subset of pairs agrees with checking them one at a time."""
    import pinocchio as pin

    from dexplan.model.collision import pose_to_se3
    from dexplan.model.scenario import load_scenario
    from dexplan.planning.context import build_context

    ctx = build_context(load_scenario("dexplan/data/scenarios/allegro_sphere.toml"), seed=1)
    world, hand = ctx.world, ctx.hand
    gm = world.geom_model
    rng = np.random.default_rng(2)
    pairs = [k for k in range(len(gm.collisionPairs)) if k % 3 == 0]
    gd = world.pairs_data(pairs)
    pose = ctx.scenario.start.object_pose_xyzquat
    M = pose_to_se3(pose)
    seen = set()
    for _ in range(200):
        q = rng.uniform(hand.lower, hand.upper)
        ref = world.geom_data
        pin.updateGeometryPlacements(hand.model, hand.data, gm, ref, q)
        ref.oMg[world.object_geom] = M
        expected = any(pin.computeCollision(gm, ref, k) for k in pairs)
        assert world.pairs_collide(gd, q, M) == expected
        seen.add(expected)
    assert seen == {True, False}
