"""GSn roadmaps: module 1 (explore GSn with OMPL) and module 2 (link components).

Module 1 hands the GSn constraint, validity checker and RLG-style sampler to an
OMPL planner (through :mod:`dexplan.planning.ompl`, the only package
that imports OMPL) and keeps what it explored as a :class:`Roadmap`: vertices
(ambient GSn states), edges and connected components.

Module 2 links components that GSn paths cannot join, with transfer-regrasp
sequences computed by the same local planners as the reduction: a link from
vertex a to vertex b exists when the object can be carried from a's pose to
b's pose by transfers and regrasps starting from a's grasp. Linked components
are merged. Most of the paper's planning time went here; the attempts, links
and time are counted.

A roadmap can be saved (``.npz``) and loaded to answer later queries
(multi-query mode): start and goal are linked into it the same way.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components as _csgraph_components
from scipy.sparse.csgraph import dijkstra

from dexplan.core.errors import InvalidInputError, RoadmapFileError, shorten
from dexplan.core.files import atomic_output
from dexplan.core.pose import quat_angle
from dexplan.core.segments import Segment
from dexplan.core.typing import FloatArray
from dexplan.model.scenario.scenario import scenario_description
from dexplan.planning.context import PlanningContext
from dexplan.planning.gsn.chart import ChartProblem, ContactChart, DirectionCaps
from dexplan.planning.gsn.space import POSE_DIM
from dexplan.planning.local.contact_paths import ContactPaths
from dexplan.planning.local.geodesic_motion import GeodesicFallback
from dexplan.planning.local.reduction import (
    ReductionResult,
    ReductionSettings,
    grasp_from_state,
    reduce_object_path,
    regrasps_onto,
)
from dexplan.planning.local.smoothing import straight_move_ok
from dexplan.planning.local.transitions import densify_poses
from dexplan.planning.ompl import (
    MULTI_QUERY_PLANNERS,
    ConstraintSpec,
    GoalSpec,
    PlanningProblem,
    ProjectionSpec,
)
from dexplan.planning.roadmap.file import ROADMAP_FORMAT, read_roadmap_arrays

MODULE2_WAYPOINTS = 16
"""RLG states a single query's module 2 adds once when it has no link to try
(:func:`link_query`'s ``waypoints``), for :data:`WAYPOINT_PLANNERS`."""

WAYPOINT_PLANNERS = frozenset({"BFMT"})
"""Planners whose module 2 gets waypoints.

BFMT's planner data holds only its two trees (no sample it left
unconnected), on cube_post none at all: with the straight turn blocked by
the post, module 2 had nothing to link (0/10, every run 0 attempts).
Measured for every planner (the eighth session's sweep, cut after 676
runs): waypoints made BFMT solve cube_post, but for the others they
replaced the next round's growth with detours through random poses:
more regrasps (PRM seed 1: 13), and failures where there were none
(RRTConnect seed 4 no GSn path, InformedRRTstar and SORRTstar seed 1
reductions failed)."""

#: Share of the time left that one module-2 pass of a single query may use.
MODULE2_SHARE = 0.3


def connected_components(n: int, edges: object) -> tuple[np.ndarray, np.ndarray]:
    """Label the connected components of an undirected graph.

    Args:
        n: number of vertices N (vertices are ``0..N-1``).
        edges: ``(E, 2)`` integer vertex pairs; direction is ignored, self-loops and
            duplicates are allowed.

    Returns:
        ``(labels, sizes)``: ``labels`` ``(N,)`` int64, the component of each vertex,
        numbered ``0..C-1`` by first appearance; ``sizes`` ``(C,)`` int64 vertex counts.

    Raises:
        InvalidInputError: negative ``n``, wrong edge shape or an index out of range.

    """
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 0:
        raise InvalidInputError(f"n must be an integer >= 0, got {n!r}")
    n = int(n)
    arr = np.asarray(edges)
    if arr.size == 0:
        arr = np.zeros((0, 2), dtype=np.int64)
    if arr.ndim != 2 or arr.shape[1] != 2 or not np.issubdtype(arr.dtype, np.integer):
        raise InvalidInputError(f"edges must be an (E, 2) integer array, got shape {arr.shape}")
    arr = arr.astype(np.int64, copy=False)
    if arr.size and (arr.min() < 0 or arr.max() >= n):
        raise InvalidInputError(
            f"edges index vertices outside 0..{n - 1}: min {arr.min()}, max {arr.max()}"
        )
    if n == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    graph = coo_matrix(
        (np.ones(arr.shape[0], dtype=np.int8), (arr[:, 0], arr[:, 1])), shape=(n, n)
    ).tocsr()
    _, raw = _csgraph_components(graph, directed=False)
    # renumber by first appearance so labels do not depend on scipy's internals
    _, first, inverse = np.unique(raw, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    labels = rank[inverse].astype(np.int64)
    sizes = np.bincount(labels, minlength=order.size).astype(np.int64)
    return labels, sizes


@dataclass(frozen=True)
class GsnQuery:
    """A GSn query: start state, goal test and goal-state sampler.

    Attributes:
        start: (7 + nq,) start state on GSn.
        goal_test: maps a state to (in goal region, distance to it).
        goal_sampler: returns a valid GSn state in the goal region, or None.
        goal_pose: (7,) the goal object pose itself, when the region has one:
            module-2 links into the goal region end there, the pose the
            planner's reduction ends on (so it can reuse them).
    """

    start: FloatArray
    goal_test: Callable[[FloatArray], tuple[bool, float]]
    goal_sampler: Callable[[], FloatArray | None]
    goal_pose: FloatArray | None = None


@dataclass(frozen=True)
class LinkReduction:
    """A successful module-2 link: the transfers and regrasps that make it.

    The planner reduces its GSn path's object trajectory afresh; when that
    trajectory is a link's own (a link from the start straight into the goal
    region), it takes the link's reduction instead of redoing it (seconds on a
    many-DOF hand, and a fresh try can fail where the link went through).

    Attributes:
        poses: (P, 7) the dense object trajectory the link followed.
        q_start: (nq,) hand joints at its start.
        result: its reduction (successful).
    """

    poses: FloatArray
    q_start: FloatArray
    result: ReductionResult

    def matches(self, poses: FloatArray, q_start: FloatArray, tol: float = 1e-9) -> bool:
        """Whether it follows ``poses: (P, 7)`` from ``q_start: (nq,)`` (quaternion sign free)."""
        if poses.shape != self.poses.shape or not np.allclose(q_start, self.q_start, atol=tol):
            return False
        dots = np.abs(np.sum(poses[:, 3:] * self.poses[:, 3:], axis=1))
        same_place = np.allclose(poses[:, :3], self.poses[:, :3], atol=tol)
        return bool(same_place and np.all(dots > 1 - tol))


@dataclass
class Roadmap:
    """A GSn roadmap with module-2 links.

    Attributes:
        vertices: (N, 7 + nq) ambient GSn states.
        edges: (E, 2) vertex index pairs joined by a GSn motion.
        links: (L, 2) vertex index pairs joined by a transfer-regrasp sequence.
        planner: name of the OMPL planner that built it.
        scenario_key: hash of the models it belongs to (hand, object, obstacles, friction).
        build: how it was built (the learning phase's statistics,
            :class:`~dexplan.planning.roadmap.learning.BuildStats` as a mapping), or empty.
    """

    vertices: FloatArray
    edges: np.ndarray
    links: np.ndarray
    planner: str
    scenario_key: str
    build: dict[str, Any] = field(default_factory=dict)

    @property
    def n_vertices(self) -> int:
        """Number of vertices."""
        return len(self.vertices)

    def components(self, with_links: bool = True) -> tuple[int, np.ndarray]:
        """Connected components (:func:`connected_components`): ``(count, labels (N,))``."""
        pairs = [self.edges]
        if with_links and len(self.links):
            pairs.append(self.links)
        e = np.vstack(pairs).astype(np.int64).reshape(-1, 2)
        labels, sizes = connected_components(self.n_vertices, e)
        return len(sizes), labels

    def add_vertex(self, x: FloatArray) -> int:
        """Append a vertex; returns its index."""
        self.vertices = np.vstack([self.vertices, x[None]])
        return self.n_vertices - 1

    def add_link(self, a: int, b: int) -> None:
        """Record a module-2 link between vertices a and b."""
        self.links = np.vstack([self.links, [[a, b]]]).astype(np.int64)

    def shortest_path(self, source: int, targets: list[int]) -> list[int] | None:
        """Vertex sequence from ``source`` to the nearest of ``targets`` (object-pose metric)."""
        e = np.vstack([self.edges, self.links]) if len(self.links) else self.edges
        if len(e) == 0 or not targets:
            return None
        e = np.asarray(e, dtype=np.int64).reshape(-1, 2)
        w = pose_distances(self.vertices[e[:, 0]], self.vertices[e[:, 1]]) + 1e-9
        n = self.n_vertices
        g = coo_matrix(
            (
                np.concatenate([w, w]),
                (np.concatenate([e[:, 0], e[:, 1]]), np.concatenate([e[:, 1], e[:, 0]])),
            ),
            shape=(n, n),
        ).tocsr()
        dist, pred = dijkstra(g, indices=source, return_predecessors=True)
        best = min(targets, key=lambda t: dist[t])
        if not np.isfinite(dist[best]):
            return None
        path = [best]
        while path[-1] != source:
            path.append(int(pred[path[-1]]))
        return path[::-1]

    def path_states(self, ids: list[int], geodesic: Geodesic | None = None) -> FloatArray:
        """States along a vertex path: GSn edges densified by ``geodesic``, links as they are.

        Args:
            ids: vertex indices, consecutive ones joined by an edge or a link.
            geodesic: ``(a, b) -> (K, n)`` states of the GSn motion a -> b (ends
                included), or None when it cannot give one; None keeps the vertices.

        Returns:
            (M, 7 + nq) states. Without densification the object would move on
            the chord between two GSn states, which need not clear the obstacles
            the GSn motion clears.
        """
        links = {tuple(sorted(pair)) for pair in self.links.tolist()}
        out = [self.vertices[ids[0]]]
        for a, b in itertools.pairwise(ids):
            if geodesic is not None and tuple(sorted((a, b))) not in links:
                states = geodesic(self.vertices[a], self.vertices[b])
                if states is not None:
                    out.extend(states[1:])
                    continue
            out.append(self.vertices[b])
        return np.array(out)

    # ------------------------------------------------------------------ files
    def save(self, path: str | Path) -> None:
        """Write the roadmap to ``path`` (``.npz``, :data:`ROADMAP_FORMAT`), atomically.

        A reader never sees a half-written file: the archive is written next to
        ``path`` and renamed over it once complete.
        """
        path = Path(path)
        fields: dict[str, Any] = {
            "format": ROADMAP_FORMAT,
            "planner": self.planner,
            "scenario_key": self.scenario_key,
        }
        if self.build:
            fields["build"] = dict(self.build)
        meta = json.dumps(fields, sort_keys=True)
        with atomic_output(path, "roadmap") as tmp, open(tmp, "wb") as fh:
            np.savez_compressed(
                fh,
                vertices=np.asarray(self.vertices, dtype=np.float64),
                edges=np.asarray(self.edges, dtype=np.int64).reshape(-1, 2),
                links=np.asarray(self.links, dtype=np.int64).reshape(-1, 2),
                meta=np.array(meta),
            )

    @classmethod
    def load(
        cls, path: str | Path, scenario_key: str | None = None, *, ambient_dim: int | None = None
    ) -> Roadmap:
        """Read and validate a roadmap file (see :func:`read_roadmap_arrays` for the checks).

        Args:
            path: a ``.npz`` file written by :meth:`save`.
            scenario_key: when given, refuse a roadmap built for other models.
            ambient_dim: when given, the vertex width the hand needs (7 + nq).

        Raises:
            RoadmapFileError: missing, unreadable or malformed file (the message
                names the array or field), or a roadmap of other models. It is a
                :class:`~dexplan.core.errors.PlanFileError`.
        """
        path = Path(path)
        where = shorten(str(path))
        vertices, edges, links, meta = read_roadmap_arrays(path, ambient_dim=ambient_dim)
        if scenario_key is not None and meta["scenario_key"] != scenario_key:
            raise RoadmapFileError(
                f"{where}: roadmap was built for other models (hand, object, obstacles or "
                "friction differ)"
            )
        return cls(
            vertices, edges, links, meta["planner"], meta["scenario_key"], meta.get("build", {})
        )


@dataclass(frozen=True)
class GsnResult:
    """Outcome of module 1 (+ module 2) for one query.

    Attributes:
        path: (K, 7 + nq) GSn states from start to goal, or None.
        roadmap: the roadmap (with start and goal vertices added).
        stats: planner and module-2 figures.
        message: detail when there is no path.
        links: the module-2 links made for this query, with their reductions.
    """

    path: FloatArray | None
    roadmap: Roadmap
    stats: dict[str, Any] = field(default_factory=dict)
    message: str = ""
    links: tuple[LinkReduction, ...] = ()


Geodesic = Callable[[FloatArray, FloatArray], FloatArray | None]
"""``(a, b) -> (K, n)`` states of the GSn motion from a to b, or None."""

ROUND_ITERATIONS = 50
"""Planner iterations of a tree planner's first module-1 round (doubling per round)."""

ROUND_MILESTONES = 4
"""Roadmap size after a PRM-family planner's first module-1 round (doubling per round)."""

CHART_RANGE = 0.5
"""Default ``range`` of tree planners on the contact chart (planning units)."""

GEODESIC_MOTIONS = True
"""Whether module 1 on meshes adds the section VI motion to OMPL's (:func:`geodesic_fallback`)."""

R_N_SAMPLERS = frozenset({"BITstar", "InformedRRTstar", "SORRTstar"})
"""Planners whose informed samplers treat the space as R^n (no projection): they
get the chart without unit-sphere rows, where every point of the bounds is a state."""


def pose_distance(a: FloatArray, b: FloatArray, length: float = 0.05) -> float:
    """Object-pose distance of two states: translation / length + rotation angle."""
    return float(np.linalg.norm(a[:3] - b[:3])) / length + quat_angle(a[3:7], b[3:7])


def pose_distances(a: FloatArray, b: FloatArray, length: float = 0.05) -> FloatArray:
    """:func:`pose_distance` of broadcast arrays of states ``(..., 7 + nq)``: ``(...)``.

    The angle is ``2 acos |<qa, qb>|`` of the normalised quaternions (q and -q
    are the same orientation).
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    dp = np.linalg.norm(a[..., :3] - b[..., :3], axis=-1)
    qa = a[..., 3:POSE_DIM] / np.linalg.norm(a[..., 3:POSE_DIM], axis=-1, keepdims=True)
    qb = b[..., 3:POSE_DIM] / np.linalg.norm(b[..., 3:POSE_DIM], axis=-1, keepdims=True)
    dot = np.clip(np.abs(np.sum(qa * qb, axis=-1)), 0.0, 1.0)
    return dp / length + 2.0 * np.arccos(dot)


def scenario_key(ctx: PlanningContext) -> str:
    """Hash of the models a roadmap depends on (the scenario identity, models only).

    The hand enters by its URDF text too, so a builtin hand whose model
    changes between versions does not reuse old roadmaps.
    """
    payload = json.dumps(
        {
            "models": scenario_description(ctx.scenario, models_only=True),
            "urdf": hashlib.sha256(ctx.hand.urdf_xml.encode()).hexdigest(),
        },
        sort_keys=True,
    )
    return hashlib.sha256(payload.encode()).hexdigest()[:16]


def constraint_spec(ctx: PlanningContext, space: str) -> ConstraintSpec:
    """The GSn constraint for OMPL, with coordinates scaled so steps mean something.

    Positions are scaled by ``1 / (2 * characteristic length)``: an object move
    of a fingertip-contact's worth of arc counts like a 0.05 rad rotation.
    """
    gsn = ctx.gsn
    scale = np.ones(gsn.ambient_dim)
    scale[:3] = 1.0 / (2.0 * ctx.obj.characteristic_length)
    return ConstraintSpec(
        ambient_dim=gsn.ambient_dim,
        co_dim=gsn.co_dim,
        function=gsn.function,
        jacobian=gsn.jacobian,
        lower=gsn.lower,
        upper=gsn.upper,
        tolerance=1e-5,
        space=space,
        scale=scale,
        delta=0.15,
    )


def orientation_projection() -> ProjectionSpec:
    """KPIECE grid projection: the object's orientation (canonical quaternion x, y, z).

    Reorientation is what the task is about, so cells split the rotation group;
    0.1 per cell is about 11 degrees.
    """

    def project(x: FloatArray) -> FloatArray:
        q = x[3:7]
        return -q[:3] if q[3] < 0 else q[:3]

    return ProjectionSpec(
        3, project, cell_sizes=np.full(3, 0.1), lower=-np.ones(3), upper=np.ones(3)
    )


def explore_gsn(
    ctx: PlanningContext,
    query: GsnQuery,
    planner: str,
    *,
    params: Mapping[str, Any] | None = None,
    space: str = "projected",
    seed: int = 1,
    deadline: float,
    module2: bool = True,
    on_round: Callable[[str, Mapping[str, int]], None] | None = None,
) -> GsnResult:
    """Module 1 (+ module 2 when needed): a GSn path from the start to the goal region.

    The paper's single-query scheme: the OMPL planner grows its roadmap in
    rounds; after each round without a path, module 2 tries a few
    transfer-regrasp links between the start's component and the goal
    region's, and the query stops as soon as they are connected. With
    ``module2=False`` the OMPL planner alone runs until the deadline.

    Rounds are counted in work, not time, so the same seed gives the same
    path whenever the deadline does not cut the search short: tree planners
    run :data:`ROUND_ITERATIONS` planner iterations (doubling each round); the
    PRM family, whose own ``solve`` is multi-threaded and time-sliced, grows
    its roadmap single-threaded to :data:`ROUND_MILESTONES` milestones
    (doubling), after which start and goal are connected into it and the
    roadmap is searched.

    ``on_round(module, counts)`` is called after each module-1 round
    (``"module1"``: rounds, nodes, edges, components) and each module-2 pass
    (``"module2"``: attempts, links), so a caller can show the search as it runs.
    """
    t0 = time.perf_counter()
    report = on_round or (lambda _module, _counts: None)
    problem = _query_problem(ctx, query, planner, params, space, seed)
    key = scenario_key(ctx)
    stats: dict[str, Any] = {"module2_attempts": 0, "module2_links": 0, "module2_time_s": 0.0}
    iterations, milestones, rounds = ROUND_ITERATIONS, ROUND_MILESTONES, 0
    links: list[LinkReduction] = []  # every pass's, for the planner to reuse
    while True:
        rounds += 1
        roadmap, starts, path, status = _module1_round(
            ctx, problem, query, planner, key, deadline, iterations, milestones
        )
        stats.update(
            {
                "gsn_status": "exact" if path is not None else status,
                "gsn_rounds": rounds,
                "gsn_time_s": time.perf_counter() - t0,
                "roadmap_nodes": roadmap.n_vertices,
                "roadmap_edges": len(roadmap.edges),
                "components": roadmap.components()[0],
            }
        )
        if isinstance(problem, PlanningProblem):
            tried, joined, _ = problem.fallback_motions
            stats.update(geodesic_motion_attempts=tried, geodesic_motion_edges=joined)
        names = ("rounds", "gsn_rounds"), ("nodes", "roadmap_nodes"), ("edges", "roadmap_edges")
        report("module1", {k: int(stats[v]) for k, v in (*names, ("components", "components"))})
        if path is not None:
            return GsnResult(path, roadmap, stats, links=tuple(links))
        iterations *= 2
        milestones *= 2
        if not module2:
            if time.perf_counter() >= deadline - 0.05:
                return GsnResult(None, roadmap, stats, "no GSn path within the time limit")
            continue
        start = starts[0] if starts else roadmap.add_vertex(query.start)
        linked = _module2_pass(
            ctx,
            roadmap,
            query,
            start,
            deadline,
            stats,
            _geodesic(problem),
            links,
            MODULE2_WAYPOINTS if planner in WAYPOINT_PLANNERS else 0,
        )
        stats["gsn_time_s"] = time.perf_counter() - t0
        report(
            "module2",
            {"attempts": int(stats["module2_attempts"]), "links": int(stats["module2_links"])},
        )
        if linked.path is not None or time.perf_counter() >= deadline - 0.05:
            return linked


def _module2_pass(
    ctx: PlanningContext,
    roadmap: Roadmap,
    query: GsnQuery,
    start: int,
    deadline: float,
    stats: dict[str, Any],
    geodesic: Geodesic,
    links: list[LinkReduction],
    waypoints: int = 0,
) -> GsnResult:
    """Module 2 of a single query: a few links from the start's component towards the goal.

    Attempts start within :data:`MODULE2_SHARE` of the time left, so that
    module 1 grows its roadmap again when the links fail; an attempt that
    has started runs to its end (or the query's deadline). A many-DOF hand's
    link takes seconds: cut at the share's end, allegro_cube's first links
    stopped at 34 of 40 steps after 17 s, and the next pass started again.
    """
    t_now = time.perf_counter()
    link_by = t_now + MODULE2_SHARE * max(0.0, deadline - t_now)
    return link_query(
        ctx,
        roadmap,
        query,
        start,
        link_by,
        stats,
        max_attempts=4,
        geodesic=geodesic,
        links=links,
        waypoints=waypoints,
    )


def gsn_problem(
    ctx: PlanningContext,
    planner: str,
    params: Mapping[str, Any] | None,
    space: str,
    seed: int,
) -> PlanningProblem:
    """The OMPL problem over GSn: the constraint, the validity checker and the RLG sampler.

    On meshes the PRM family joins milestones with the paper's section VI
    motion where OMPL's projected one fails (:func:`geodesic_fallback`).
    """
    return PlanningProblem(
        constraint_spec(ctx, space),
        ctx.validity.is_valid,
        planner=planner,
        params=dict(params or {}),
        valid_sampler=ctx.sampler.sample,
        check_sampled_states=False,  # the sampler returns checked states
        projection=orientation_projection(),
        seed=seed,
        motion_fallback=geodesic_fallback(ctx) if planner in MULTI_QUERY_PLANNERS else None,
    )


def geodesic_fallback(ctx: PlanningContext) -> GeodesicFallback | None:
    """Module 1's second GSn motion on a mesh: contacts along surface geodesics, or None.

    None for the primitives and meshes without geodesics (the projected
    motion is then the only one), for hands with redundant fingers (more
    than 3 joints: their IK's free joint is tabulated, so the motion would
    end beside ``b``'s joints, not on them, and never join), and when
    :data:`GEODESIC_MOTIONS` is off.
    """
    if not GEODESIC_MOTIONS:
        return None
    if any(len(ix) > 3 for ix in ctx.hand.finger_q_index):
        return None
    paths = ContactPaths(ctx.obj)
    return GeodesicFallback(ctx.transitions, ctx.validity, paths) if paths.active else None


def _query_problem(
    ctx: PlanningContext,
    query: GsnQuery,
    planner: str,
    params: Mapping[str, Any] | None,
    space: str,
    seed: int,
) -> PlanningProblem | ChartProblem:
    """The OMPL problem of a query, with its start and goal.

    Tree planners search the contact chart (:func:`chart_problem`) when it
    represents the start state; the PRM family (which draws the RLG
    sampler's states) and unrepresentable starts use :func:`gsn_problem`.
    """

    def distance(x: FloatArray) -> float:
        return query.goal_test(x)[1]

    if planner not in MULTI_QUERY_PLANNERS:
        charted = chart_problem(ctx, planner, params, space, seed, query.start)
        if charted is not None:
            charted.set_query(query.start, distance, 1.0, query.goal_sampler)
            return charted
    problem = gsn_problem(ctx, planner, params, space, seed)
    problem.set_start(query.start)
    problem.set_goal(GoalSpec(distance=distance, threshold=1.0, sample=query.goal_sampler))
    return problem


def chart_problem(
    ctx: PlanningContext,
    planner: str,
    params: Mapping[str, Any] | None,
    space: str,
    seed: int,
    start: FloatArray,
) -> ChartProblem | None:
    """The OMPL problem over GSn's contact chart (:mod:`dexplan.planning.gsn.chart`), or None.

    None when rays from the object's origin do not parameterise its surface,
    or when the chart does not map the start state back onto itself (within
    1e-7). Planners with a ``range`` get :data:`CHART_RANGE` unless ``params``
    sets one. Planners of :data:`CAPPED_PLANNERS` get direction caps
    (:func:`direction_caps`) when the capped chart represents the start.
    """
    if not ContactChart.applies(ctx.gsn):
        return None
    spheres = planner not in R_N_SAMPLERS
    chart = ContactChart(ctx.gsn, ctx.validity.is_valid, spheres=spheres)
    if chart.round_trip_error(start) > 1e-7:
        return None
    if planner in CAPPED_PLANNERS:
        caps = direction_caps(ctx, chart, start, CAP_HALF_ANGLE)
        if caps is not None:
            capped = ContactChart(ctx.gsn, ctx.validity.is_valid, spheres=spheres, caps=caps)
            if capped.represents(start):
                chart = capped
    problem = PlanningProblem(
        chart.constraint_spec(1.0 / (2.0 * ctx.obj.characteristic_length), space),
        chart.is_valid_chart,
        planner=planner,
        params=dict(params or {}),
        projection=orientation_projection(),
        seed=seed,
    )
    if "range" not in (params or {}) and "range" in problem.parameters():
        problem.set_param("range", CHART_RANGE)
    return ChartProblem(chart, problem)


CAPPED_PLANNERS = frozenset({"BITstar", "InformedRRTstar", "SORRTstar", "FMT", "BFMT"})
"""Planners whose chart keeps each finger's direction within a cap (:class:`DirectionCaps`).

Their states come only from the space's uniform sampler (FMT and BFMT: a
batch drawn up front) or an informed one over the same bounds, so the
fraction of uniform chart states that are valid grasps decides how fast they
search. On cube_post (docs/gsn_chart.md) 5 of 10,000 uniform chart states
were valid; caps of 75 degrees about each finger's mean direction raised it
to about 1 %, and keep 89 % of the RLG sampler's valid states.
"""

CAP_HALF_ANGLE = math.radians(75.0)
"""Half angle of the chart's direction caps (rad)."""

CAP_SAMPLES = 16
"""RLG states whose contact directions (with the start's) centre the chart's caps."""


def direction_caps(
    ctx: PlanningContext, chart: ContactChart, start: FloatArray, half_angle: float
) -> DirectionCaps | None:
    """Caps about each finger's mean chart direction, over the start and RLG states.

    The mean of the start's directions and those of up to
    :data:`CAP_SAMPLES` states of the RLG sampler (valid grasps anywhere in
    the workspace): where the hand's fingers touch objects in this scene.
    None when a finger's directions scatter so that their mean is shorter
    than 0.2 (no cap about it would keep its states).
    """
    states = [start, *rlg_states(ctx, CAP_SAMPLES, ctx.deadline.at)]
    k = chart.k
    dirs = np.array([chart.to_chart(x)[POSE_DIM : POSE_DIM + 3 * k].reshape(k, 3) for x in states])
    mean = dirs.mean(axis=0)
    length = np.linalg.norm(mean, axis=1, keepdims=True)
    if np.any(length < 0.2):
        return None
    return DirectionCaps(mean / length, half_angle)


def _module1_round(
    ctx: PlanningContext,
    problem: PlanningProblem | ChartProblem,
    query: GsnQuery,
    planner: str,
    key: str,
    deadline: float,
    iterations: int,
    milestones: int,
) -> tuple[Roadmap, list[int], FloatArray | None, str]:
    """One round of module 1: grow the OMPL planner's graph, look for a path.

    Returns:
        ``(roadmap, start vertex ids, path or None, OMPL status)``.
    """
    remaining = max(0.05, deadline - time.perf_counter())
    if problem.is_multi_query:
        problem.grow_roadmap(remaining, max_milestones=milestones)
        res = problem.solve(1e-6)  # only connects start and goal milestones into it
    else:
        res = problem.solve(remaining, max_iterations=iterations)
    data = problem.planner_data()
    roadmap = Roadmap(
        np.asarray(data.vertices, dtype=float).reshape(-1, ctx.gsn.ambient_dim),
        np.asarray(data.edges, dtype=np.int64).reshape(-1, 2),
        np.zeros((0, 2), dtype=np.int64),
        planner,
        key,
    )
    starts = [int(i) for i in np.asarray(data.start_ids, dtype=int)]
    path = None
    if res.solved and res.path is not None and len(res.path):
        path = np.asarray(res.path)
    elif problem.is_multi_query and starts:
        path = _roadmap_path(problem, roadmap, starts[0], query)
    return roadmap, starts, path, res.status


def _roadmap_path(
    problem: PlanningProblem, roadmap: Roadmap, start: int, query: GsnQuery
) -> FloatArray | None:
    """Shortest roadmap path from ``start`` into the goal region, densified on GSn.

    None when there is none, or when a roadmap edge is not a valid motion in
    the travel direction (projection is direction-dependent; see MEASURED.md).
    """
    goals = [i for i, x in enumerate(roadmap.vertices) if query.goal_test(x)[0]]
    ids = roadmap.shortest_path(start, goals) if goals else None
    if ids is None:
        return None
    checked = problem.check_path(roadmap.vertices[ids], interpolate=True)
    return np.asarray(checked.path) if checked.path_valid else None


def _geodesic(problem: PlanningProblem | ChartProblem) -> Geodesic:
    """GSn motions of a roadmap's edges, re-checked in travel direction."""

    def states(a: FloatArray, b: FloatArray) -> FloatArray | None:
        checked = problem.check_path(np.stack([a, b]), interpolate=True)
        return np.asarray(checked.path) if checked.path_valid else None

    return states


def object_move_free(ctx: PlanningContext, a: FloatArray, b: FloatArray) -> bool:
    """True when the object alone can move straight from a's pose to b's (no obstacle)."""
    s = ctx.transitions.settings
    return straight_move_ok(
        a[:POSE_DIM],
        b[:POSE_DIM],
        lambda p: not ctx.world.object_collides(p),
        s.max_step_m,
        s.max_step_rad,
    )


def try_link(ctx: PlanningContext, a: FloatArray, b_pose: FloatArray) -> bool:
    """Module-2 link test: can transfers and regrasps carry the object from a to b's pose?"""
    return link_reduction(ctx, a, b_pose).result.success


def link_reduction(
    ctx: PlanningContext, a: FloatArray, b_pose: FloatArray, via: Sequence[FloatArray] = ()
) -> LinkReduction:
    """The module-2 link attempt from state ``a`` to the object pose ``b_pose: (7,)``.

    The object moves straight (the poses as the planner's reduction
    densifies them: unit quaternions, ``b_pose`` on ``a``'s hemisphere) and
    finger gaits carry it from ``a``'s grasp, or, with ``via`` states
    ``(7 + nq,)`` at ``a``'s object pose, from the grasp of the first of them
    the hand can regrasp onto with the object fixed
    (:func:`~dexplan.planning.local.reduction.regrasps_onto`).
    """
    tr = ctx.transitions
    s = tr.settings
    ends = np.array([a[:POSE_DIM], b_pose], dtype=float)
    ends[:, 3:] /= np.linalg.norm(ends[:, 3:], axis=1, keepdims=True)
    if float(np.dot(ends[0, 3:], ends[1, 3:])) < 0.0:
        ends[1, 3:] = -ends[1, 3:]
    dense = densify_poses(ends, s.max_step_m, s.max_step_rad)
    q, grasp = a[POSE_DIM:], grasp_from_state(tr, a[:POSE_DIM], a[POSE_DIM:])
    settings = ReductionSettings()
    moves: list[Segment] = []
    if len(via):
        for x in via:
            target = grasp_from_state(tr, x[:POSE_DIM], x[POSE_DIM:])
            moved = regrasps_onto(tr, dense[0], q, grasp, target, settings.same_contact_m)
            if moved is not None:
                moves, q, grasp = moved
                break
        else:
            why = f"no regrasps onto any of {len(via)} other start grasps"
            return LinkReduction(dense, q.copy(), ReductionResult(False, (), 0, why))
    red = reduce_object_path(tr, dense, q, grasp, settings)
    if moves:
        red = dataclasses.replace(red, segments=(*moves, *red.segments))
    return LinkReduction(dense, a[POSE_DIM:].copy(), red)


def link_query(
    ctx: PlanningContext,
    roadmap: Roadmap,
    query: GsnQuery,
    start: int,
    deadline: float,
    stats: dict[str, Any],
    max_attempts: int | None = None,
    geodesic: Geodesic | None = None,
    links: list[LinkReduction] | None = None,
    waypoints: int = 0,
) -> GsnResult:
    """Module 2: join the start's component to the goal region with links, then search.

    Goal vertices are the roadmap vertices in the goal region, plus sampled
    goal states when there are none. Component pairs are tried nearest first
    (object-pose distance); every successful link merges two components. The
    path's GSn edges are densified with ``geodesic`` when given.

    Each attempt runs on a random stream of its own (the context's seed and
    the attempt's number), so a link's regrasps do not depend on how many
    attempts came before within a pass the clock ended. Every attempt from
    the start after the query's first one first regrasps onto another
    sampled start grasp (allegro_cube: the gaits from some start grasps
    stall within a few degrees whatever the landings, from others they turn
    the cube in seconds). Links into the goal region end on
    ``query.goal_pose`` when given. Successful links are appended to
    ``links`` (the result carries them all).

    When no candidate can be tried (no other vertex, or the object alone
    cannot move straight to any: an obstacle in the way) and ``waypoints``
    is positive, up to that many RLG states join the roadmap once, as
    vertices of their own, so that links can go round the obstacle through
    their object poses (BFMT's roadmap holds only its trees, often just the
    start: on cube_post the straight turn is blocked by the post and module
    2 had nothing else to link to).
    """
    links = [] if links is None else links
    t0 = time.perf_counter()
    goals = [i for i, x in enumerate(roadmap.vertices) if query.goal_test(x)[0]]
    while not goals and time.perf_counter() < deadline:
        g = query.goal_sampler()
        if g is not None:
            goals.append(roadmap.add_vertex(g))
    goal_set = set(goals)
    path_ids = None
    attempts = 0
    seeded = waypoints <= 0
    while time.perf_counter() < deadline:
        path_ids = roadmap.shortest_path(start, goals) if goals else None
        if path_ids is not None:
            break
        if not goals:
            break
        src, dst, order = _link_candidates(roadmap, start, goals)
        tried = attempts
        linked = False
        for flat in order:
            if max_attempts is not None and attempts >= max_attempts:
                break
            a, b = src[flat // len(dst)], dst[flat % len(dst)]
            if not object_move_free(ctx, roadmap.vertices[a], roadmap.vertices[b]):
                continue  # the object alone cannot make this move
            attempts += 1
            stats["module2_attempts"] += 1
            n = int(stats["module2_attempts"])
            ctx.reseed_local_planners(ctx.seed, 3, n)
            to_goal = query.goal_pose is not None and int(b) in goal_set
            b_pose = query.goal_pose if to_goal else roadmap.vertices[b][:POSE_DIM]
            # after the first, attempts from the start begin by regrasping onto
            # another start grasp: gaits that stall do so from some grasps
            via = _other_grasps(ctx, roadmap.vertices[a], n) if a == start and n > 1 else []
            link = link_reduction(ctx, roadmap.vertices[a], b_pose, via)
            if link.result.success:
                links.append(link)
                roadmap.add_link(int(a), int(b))
                stats["module2_links"] += 1
                linked = True
                break
            if time.perf_counter() >= deadline:
                break
        budget_left = max_attempts is None or attempts < max_attempts
        if not linked and attempts == tried and budget_left and not seeded:
            seeded = True  # nothing could be tried: waypoints round the obstacle, once
            added = rlg_states(ctx, waypoints, deadline)
            for x in added:
                roadmap.add_vertex(x)
            stats["module2_waypoints"] = stats.get("module2_waypoints", 0) + len(added)
            continue
        if not linked:
            break
    if path_ids is None and goals:
        # a link made as the time ran out (an attempt runs to its end)
        path_ids = roadmap.shortest_path(start, goals)
    stats["module2_time_s"] += time.perf_counter() - t0
    stats["components_after_links"] = roadmap.components()[0]
    if path_ids is None:
        return GsnResult(
            None, roadmap, stats, "start and goal are not connected in GSn", tuple(links)
        )
    return GsnResult(roadmap.path_states(path_ids, geodesic), roadmap, stats, links=tuple(links))


#: Other start grasps a module-2 attempt may regrasp onto before its gaits.
OTHER_GRASPS = 8


def rlg_states(ctx: PlanningContext, count: int, deadline: float) -> list[FloatArray]:
    """Up to ``count`` valid GSn states ``(7 + nq,)`` of the RLG sampler.

    At most ``4 * count`` draws, none at or past ``deadline``
    (``time.perf_counter()``); used for the chart's caps and module 2's
    waypoints.
    """
    out: list[FloatArray] = []
    for _ in range(4 * count):
        if len(out) >= count or time.perf_counter() >= deadline:
            break
        x = ctx.sampler.sample()
        if x is not None:
            out.append(x)
    return out


def _other_grasps(ctx: PlanningContext, x: FloatArray, attempt: int) -> list[FloatArray]:
    """Other valid states at ``x``'s object pose, from a stream of the attempt's own."""
    rng = np.random.default_rng([ctx.seed, 4, attempt])
    return ctx.sampler.samples_at_pose(x[:POSE_DIM], OTHER_GRASPS, rng)


def _link_candidates(
    roadmap: Roadmap, start: int, goals: list[int]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Module-2 link candidates from the start's component, best first.

    Pairs are ranked by link length plus how far the far end still is from
    the goal: links straight into a goal component come first, links into
    other components (merged on the way, as in the paper) next.

    Returns:
        ``(src, dst, order)``: the start component's vertices, the other
        vertices, and the first 64 pairs as flat indices into
        ``len(src) x len(dst)``.
    """
    _, labels = roadmap.components()
    src = np.flatnonzero(labels == labels[start])
    dst = np.flatnonzero(labels != labels[start])
    if len(dst) == 0:
        return src, dst, np.zeros(0, dtype=np.int64)
    goal_v = roadmap.vertices[goals[0]]
    to_goal = np.array([pose_distance(roadmap.vertices[b], goal_v) for b in dst])
    to_goal[np.isin(labels[dst], labels[goals])] = 0.0
    d = np.array(
        [[pose_distance(roadmap.vertices[a], roadmap.vertices[b]) for b in dst] for a in src]
    )
    d = d + to_goal[None, :]
    return src, dst, np.argsort(d, axis=None)[:64]
