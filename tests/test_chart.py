"""The contact chart: GSn in object-pose + contact-direction coordinates for tree planners."""

import time

import numpy as np
import pytest

from dexplan.core.errors import InvalidInputError
from dexplan.model.scenario import builtin_scenario_path, load_scenario
from dexplan.planning.context import build_context
from dexplan.planning.gsn.chart import ChartProblem, ContactChart, DirectionCaps
from dexplan.planning.gsn.space import POSE_DIM
from dexplan.planning.ompl import RoadmapData
from dexplan.planning.ompl.registry import CAPPED_PLANNERS
from dexplan.planning.planner import goal_reached
from dexplan.planning.roadmap.module1 import explore_gsn
from dexplan.planning.roadmap.problems import chart_problem
from dexplan.planning.roadmap.search import GsnQuery
from dexplan.planning.start import start_state


@pytest.fixture(scope="module")
def cube():
    ctx = build_context(load_scenario(builtin_scenario_path("cube_obstacle")), seed=3)
    return ctx, ContactChart(ctx.gsn, ctx.validity.is_valid)


def _random_chart_states(chart: ContactChart, n: int, seed: int) -> np.ndarray:
    lo, up = chart.bounds()
    return np.random.default_rng(seed).uniform(lo, up, size=(n, chart.dim))


def test_tip_centres_lie_on_the_offset_surface(cube) -> None:
    ctx, chart = cube
    rng = np.random.default_rng(0)
    dirs = rng.normal(size=(200, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    tips = np.concatenate([chart.tip_centres(dirs[i : i + 4]) for i in range(0, 200, 4)])
    r = ctx.hand.fingertip_radius
    np.testing.assert_allclose(ctx.obj.signed_distance(tips), r, atol=1e-9)
    # on the ray: parallel to its direction
    unit = tips / np.linalg.norm(tips, axis=1, keepdims=True)
    np.testing.assert_allclose(np.einsum("ij,ij->i", unit, dirs), 1.0, atol=1e-12)
    # straight through a face centre: half the side plus the tip radius
    half = float(ctx.obj.signed_distance(np.zeros(3))) * -1.0
    face = chart.tip_centres(np.array([[1.0, 0.0, 0.0]]))
    np.testing.assert_allclose(face, [[half + r, 0.0, 0.0]], atol=1e-9)


def test_every_mapped_state_is_on_gsn_and_round_trips(cube) -> None:
    ctx, chart = cube
    mapped = 0
    for y in _random_chart_states(chart, 600, 1):
        x = chart.to_ambient(y)
        if x is None:
            continue
        mapped += 1
        assert ctx.gsn.residual(x) < 1e-8
        assert ctx.hand.within_limits(x[POSE_DIM:])
        back = chart.to_chart(x)
        np.testing.assert_allclose(chart.to_ambient(back), x, atol=1e-9)
    assert mapped >= 5


def test_sampler_states_round_trip(cube) -> None:
    ctx, chart = cube
    errors = []
    for _ in range(200):
        x = ctx.sampler.sample()
        if x is not None:
            errors.append(chart.round_trip_error(x))
        if len(errors) == 10:
            break
    assert len(errors) == 10
    assert max(errors) < 1e-7


def test_chart_needs_the_origin_inside_the_object(cube) -> None:
    ctx, _ = cube

    class Shifted:
        def signed_distance(self, p):
            return 1.0

    class Gsn:
        obj = Shifted()

    assert not ContactChart.applies(Gsn())  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match="origin"):
        ContactChart(Gsn(), ctx.validity.is_valid)  # type: ignore[arg-type]


def test_chart_motions_valid_one_way_are_paths_both_ways(cube) -> None:
    """A chart motion valid in one direction is a valid path in either.

    OMPL's discrete geodesic walks from its start, so a -> b and b -> a pass
    through different projected states and ``check_motion`` may differ by
    direction (near the force-closure boundary; one of 30 motions from
    this module's start grasp did, once the sampler used per-finger pools;
    90 are drawn since the sampler's later settings drew a start grasp with
    fewer usable ones).
    ``check_path`` then
    travels the segment along the reversed reverse geodesic: the roadmap's
    undirected edges must be usable both ways, every state valid.
    """
    ctx, chart = cube
    x0 = start_state(ctx, candidates=1)  # the grasp the 30 motions were drawn around
    assert x0 is not None
    charted = chart_problem(ctx, "RRTConnect", None, "projected", 1, x0)
    assert charted is not None
    y0 = chart.to_chart(x0)
    rng = np.random.default_rng(2)
    valid = usable = 0
    for _ in range(90):
        y = y0 + rng.normal(0.0, 0.1, size=len(y0)) * np.r_[np.full(3, 0.02), np.ones(len(y0) - 3)]
        y[-1] = 0.0
        y[3:POSE_DIM] /= np.linalg.norm(y[3:POSE_DIM])
        d = y[POSE_DIM:-1].reshape(-1, 3)
        y[POSE_DIM:-1] = (d / np.linalg.norm(d, axis=1, keepdims=True)).reshape(-1)
        if not chart.is_valid_chart(y):
            continue
        valid += 1
        either = charted.problem.check_motion(y0, y) or charted.problem.check_motion(y, y0)
        usable += either
        ends = np.stack([chart.to_ambient(y0), chart.to_ambient(y)])
        for a, b in (ends, ends[::-1]):
            checked = charted.check_path(np.stack([a, b]))
            assert checked.path_valid == either
            if either:
                np.testing.assert_allclose(checked.path[0], a, atol=1e-9)
                np.testing.assert_allclose(checked.path[-1], b, atol=1e-9)
                assert all(ctx.validity.is_valid(x) for x in checked.path)
    assert valid >= 5 and usable >= 3


def test_planner_data_leaves_out_states_the_chart_cannot_map(cube) -> None:
    ctx, chart = cube
    x0 = start_state(ctx)
    assert x0 is not None
    y0 = chart.to_chart(x0)
    bad = y0.copy()
    bad[POSE_DIM : POSE_DIM + 3] = 0.0  # no direction
    other = chart.to_chart(x0)
    other[0] += 1e-4

    class Fake:
        def planner_data(self) -> RoadmapData:
            return RoadmapData(
                vertices=np.stack([y0, bad, other]),
                edges=np.array([[0, 1], [1, 2], [0, 2]]),
                start_ids=np.array([0]),
                goal_ids=np.array([2, 1]),
            )

    data = ChartProblem(chart, Fake()).planner_data()  # type: ignore[arg-type]
    assert data.vertices.shape == (2, ctx.gsn.ambient_dim)
    np.testing.assert_array_equal(data.edges, [[0, 1]])
    np.testing.assert_array_equal(data.start_ids, [0])
    np.testing.assert_array_equal(data.goal_ids, [1])


@pytest.mark.timeout(240)
@pytest.mark.parametrize(
    "planner",
    [
        "RRTConnect",
        "BITstar",
        "RRT",
        "RRTstar",
        "InformedRRTstar",
        "SORRTstar",
        "KPIECE1",
        "BKPIECE1",
        "LBKPIECE1",
        "BFMT",
        "FMT",
    ],
)
def test_tree_planners_search_the_chart_and_return_valid_gsn_paths(planner: str) -> None:
    """Every tree planner on the paper's half turn (FMT through module 2's link)."""
    scenario = load_scenario(builtin_scenario_path("paper_sphere"))
    ctx = build_context(scenario, seed=2)
    x0 = start_state(ctx)
    assert x0 is not None
    assert chart_problem(ctx, planner, None, "projected", 2, x0) is not None
    query = GsnQuery(
        x0,
        lambda x: goal_reached(scenario, x[:POSE_DIM]),
        lambda: ctx.sampler.sample_at_pose(scenario.goal.object_pose_xyzquat),
    )
    res = explore_gsn(ctx, query, planner, seed=2, deadline=time.perf_counter() + 300.0)
    assert res.path is not None, res.message
    np.testing.assert_array_equal(res.path[0], x0)
    assert goal_reached(scenario, res.path[-1][:POSE_DIM])[0]
    for x in res.path[:: max(1, len(res.path) // 40)]:
        assert ctx.gsn.residual(x) < 1e-6
        assert ctx.validity.check(x).valid
    assert np.all(np.isfinite(res.roadmap.vertices))


def test_a_start_the_chart_cannot_represent_falls_back_to_the_ambient_space(cube) -> None:
    ctx, _ = cube
    x0 = start_state(ctx)
    assert x0 is not None
    assert chart_problem(ctx, "RRTConnect", None, "projected", 1, x0) is not None
    off = x0.copy()
    off[POSE_DIM] += 0.05  # a fingertip off the offset surface: not a chart state
    assert chart_problem(ctx, "RRTConnect", None, "projected", 1, off) is None


def test_direction_caps_round_trip_and_bound_the_directions(cube) -> None:
    """A capped chart stores each direction in its cap's frame: the box bounds are the cap."""
    ctx = build_context(load_scenario(builtin_scenario_path("cube_obstacle")), seed=3)
    chart = ContactChart(ctx.gsn, ctx.validity.is_valid)  # own sampler: the module's stays put
    xs = [x for x in (ctx.sampler.sample() for _ in range(200)) if x is not None][:12]
    k = chart.k
    dirs = np.array([chart.to_chart(x)[POSE_DIM : POSE_DIM + 3 * k].reshape(k, 3) for x in xs])
    centres = dirs.mean(axis=0)
    centres /= np.linalg.norm(centres, axis=1, keepdims=True)
    angle = np.radians(75.0)
    caps = DirectionCaps(centres, angle)
    frames = caps.frames()
    for f, c in zip(frames, centres, strict=True):
        np.testing.assert_allclose(f.T @ f, np.eye(3), atol=1e-12)
        np.testing.assert_allclose(f[:, 2], c, atol=1e-12)
        assert np.linalg.det(f) > 0.0
    capped = ContactChart(ctx.gsn, ctx.validity.is_valid, caps=caps)
    inside = 0
    for x, d in zip(xs, dirs, strict=True):
        within = bool(np.all(np.einsum("kj,kj->k", d, centres) >= np.cos(angle)))
        assert capped.represents(x) == within
        inside += within
        np.testing.assert_allclose(capped.to_ambient(capped.to_chart(x)), x, atol=1e-9)
    assert inside >= 6
    # mapped uniform box states of the capped chart keep every direction within
    # atan(sqrt(2) tan 75 deg) = 79.3 deg of its axis (the box's corners)
    mapped = 0
    for y in _random_chart_states(capped, 400, 2):
        x = capped.to_ambient(y)
        if x is not None:
            mapped += 1
            d = chart.to_chart(x)[POSE_DIM : POSE_DIM + 3 * k].reshape(k, 3)
            assert np.all(np.einsum("kj,kj->k", d, centres) >= np.cos(np.radians(80.0)))
    assert mapped >= 20
    with pytest.raises(InvalidInputError, match="caps"):
        ContactChart(ctx.gsn, ctx.validity.is_valid, caps=DirectionCaps(centres[:2], angle))
    with pytest.raises(InvalidInputError, match="caps"):
        ContactChart(ctx.gsn, ctx.validity.is_valid, caps=DirectionCaps(centres, 0.0))
    with pytest.raises(InvalidInputError, match="caps"):  # R^n boxes must avoid the origin
        ContactChart(
            ctx.gsn, ctx.validity.is_valid, spheres=False, caps=DirectionCaps(centres, 1.6)
        )
    with pytest.raises(InvalidInputError, match="caps"):
        ContactChart(ctx.gsn, ctx.validity.is_valid, caps=DirectionCaps(0.0 * centres, angle))


def test_batch_and_informed_planners_get_a_capped_chart(cube) -> None:
    ctx, _ = cube
    x0 = start_state(ctx)
    assert x0 is not None
    for planner in CAPPED_PLANNERS:
        problem = chart_problem(ctx, planner, None, "projected", 1, x0)
        assert problem is not None and problem.chart.caps is not None
        assert problem.chart.represents(x0)
    problem = chart_problem(ctx, "RRTConnect", None, "projected", 1, x0)
    assert problem is not None and problem.chart.caps is None
