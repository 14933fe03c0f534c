"""GSn in the paper's own coordinates: object pose and one contact direction per finger.

The ompl 2.0.1 wheel cannot give a tree planner (RRT, RRTConnect, the KPIECE
family, FMT, BITstar...) a Python state sampler: ``StateSpace.setStateSamplerAllocator``
is not bound, and Python overrides of ``allocDefaultStateSampler`` are ignored,
on the constrained space and on its ambient ``RealVectorStateSpace`` alike
(the override is never called). Those planners drew uniform ambient
states of ``(object pose, hand joints)`` and projected them onto GSn, which on
a box mostly fails. This module gives them coordinates in which every uniform
sample already is a GSn configuration: the **contact chart**

    y = [x, y, z, qx, qy, qz, qw, d_1 (3), ..., d_k (3), q_free..., 0]

object position and quaternion, then for each contact finger a direction
``d_i`` in the world (palm) frame, then the joints of the fingers not in
contact (none on GSn), then a pinned coordinate. Quaternion and directions
are normalised by the map, so any point of the box bounds is a chart state.
The constraint rows (``spheres=True``, the default) are the pinned
coordinate, ``|quat|^2 - 1`` and ``|d_i|^2 - 1``: a product of spheres, onto
which OMPL's Newton projection converges from any point but the origin, so
every projected sample is a chart state. With ``spheres=False`` the pinned
coordinate is the only row; its bounds (+-1e-12) lie inside the projection
tolerance, so even samples that are never projected (the informed samplers
of BITstar, InformedRRTstar and SORRTstar treat the space as R^n) are chart
states. Motions are OMPL's discrete geodesics between chart states; a
geodesic walks from its start, so a -> b and b -> a pass through different
projected states and their validity may differ (near the force-closure
boundary): :meth:`ChartProblem.check_path` travels a segment valid only the
other way along the reversed reverse geodesic.

A chart state maps to an ambient GSn state (:meth:`ContactChart.to_ambient`):
the fingertip-sphere centre of finger i is where the ray from the object's
origin along ``d_i`` (taken to the object frame) meets the offset surface
``{p : sdf(p) = r}`` (r the tip radius), found by safeguarded Newton steps
from outside (monotone on convex objects: the signed distance is convex
along a ray); the finger's joints are its IK solution nearest the hand's
neutral posture. The offset surface of a box has rounded edges of radius
r, so the map is continuous across edges (the fingertip rolls over the
edge). Directions are in the world frame by default, so a pure rotation of
the object keeps the fingertips near where they are (the contacts slide),
as reorientation needs. The ambient state then goes to the
usual validity checker (bounds, joint limits, collisions, force closure).

The inverse (:meth:`ContactChart.to_chart`) reads the pose and each fingertip
centre's direction from the object's origin. It is exact for offset surfaces
star-shaped from the origin (every primitive, convex meshes) whose states use
the nearest-neutral IK branch; a caller checks
:meth:`ContactChart.round_trip_error` on its start state and falls back to the
ambient space when the chart cannot represent it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from dexplan.core.errors import InvalidInputError
from dexplan.core.pose import quat_to_matrix
from dexplan.core.typing import FloatArray
from dexplan.planning.gsn.space import POSE_DIM, GraspSubspace
from dexplan.planning.ompl import (
    ConstraintSpec,
    GoalSpec,
    PathCheck,
    PlanningProblem,
    RoadmapData,
    SolveResult,
)

__all__ = [
    "GOAL_POOL",
    "RAY_ITERATIONS",
    "RAY_TOLERANCE",
    "ChartProblem",
    "ContactChart",
    "DirectionCaps",
]

RAY_ITERATIONS = 40
"""Newton/bisection steps allowed to find one fingertip centre on a ray."""

RAY_TOLERANCE = 1e-10
"""|sdf(p) - r| (m) at which a fingertip centre on a ray is accepted."""

GOAL_POOL = 10
"""Goal states drawn per query; later goal requests reuse them in turn."""

_CACHE_MAX = 200_000
"""Chart states whose ambient image is kept (tree vertices are read every round)."""

_PIN_BOUND = 1e-12
"""Bound of the pinned coordinate: every ambient sample is within tolerance of f = 0."""

_SPHERE_BOUND = 1.05
"""Bound of a unit-vector coordinate when the chart constrains it (+-1 is reached)."""

_MIN_NORM = 1e-3
"""Quaternions and directions shorter than this do not map (no direction)."""


@dataclasses.dataclass(frozen=True, eq=False)
class DirectionCaps:
    """Each contact finger's chart direction kept within a spherical cap.

    A chart direction is then stored in the cap's own frame (its axis the
    third coordinate) and bounded by the box ``|e_x|, |e_y| <= sin a``,
    ``e_z >= cos a``: exactly the cap for the unit directions of a chart
    with sphere rows; a chart without them (R^n samplers) normalises box
    points, whose directions reach ``atan(sqrt(2) tan a)`` from the axis
    (79 degrees for 75).

    Attributes:
        centres: ``(k, 3)`` unit axes of the caps, in the chart's direction
            frame (world when ``world_directions``), one per contact finger.
        half_angle: the caps' half angle (rad), in (0, pi].
    """

    centres: FloatArray
    half_angle: float

    def frames(self) -> FloatArray:
        """``(k, 3, 3)`` rotations whose third column is each cap's axis."""
        out = np.empty((len(self.centres), 3, 3))
        for i, z in enumerate(self.centres):
            z = z / np.linalg.norm(z)
            helper = np.eye(3)[int(np.argmin(np.abs(z)))]
            x = np.cross(helper, z)
            x /= np.linalg.norm(x)
            out[i] = np.column_stack([x, np.cross(z, x), z])
        return out


class ContactChart:
    """The contact chart of a grasp subspace: chart states ``y`` <-> ambient states ``x``.

    Args:
        gsn: the grasp subspace (its hand, object, contact fingers and bounds).
        is_valid: ``is_valid(x) -> bool``, the ambient validity checker.
        spheres: constrain quaternion and directions to unit length (for
            planners that project their samples); False leaves only the
            pinned row (for samplers that treat the space as R^n).
        world_directions: directions in the world (palm) frame, so that a
            fixed direction under an object rotation slides the contact and
            keeps the finger in place; False: in the object frame (a fixed
            direction is a rigid transfer).
        caps: keep each contact finger's direction within a cap (see
            :class:`DirectionCaps`), or None for the whole sphere.

    Raises:
        InvalidInputError: the object-frame origin is not inside the object (rays
            from it would not cross the surface once); use :meth:`applies`
            first.
    """

    def __init__(
        self,
        gsn: GraspSubspace,
        is_valid: Callable[[FloatArray], Any],
        *,
        spheres: bool = True,
        world_directions: bool = True,
        caps: DirectionCaps | None = None,
    ) -> None:
        if not self.applies(gsn):
            raise InvalidInputError("the object-frame origin is not inside the object")
        self.gsn = gsn
        self.is_valid = is_valid
        hand = gsn.hand
        self.contact_ids = tuple(gsn.contact_ids)
        self.free_ids = tuple(i for i in range(hand.n_fingers) if i not in self.contact_ids)
        self._free_q = np.array(
            [j for i in self.free_ids for j in hand.finger_q_index[i]], dtype=np.int64
        )
        self.k = len(self.contact_ids)
        self.spheres = bool(spheres)
        self.world_directions = bool(world_directions)
        self.co_dim = 2 + self.k if self.spheres else 1
        self.dim = POSE_DIM + 3 * self.k + len(self._free_q) + 1
        self._radius = float(hand.fingertip_radius)
        self._t_max = float(gsn.obj.bounding_radius) + self._radius + 1e-3
        self._neutral = np.asarray(hand.neutral, dtype=np.float64)
        self._cache: dict[bytes, FloatArray | None] = {}
        self.stats = {"maps": 0, "ray_failures": 0, "ik_failures": 0}
        self.caps = caps
        self._frames: FloatArray | None = None
        if caps is not None:
            top = math.pi if self.spheres else 0.5 * math.pi  # R^n: the box must avoid 0
            if (
                np.shape(caps.centres) != (self.k, 3)
                or not np.all(np.isfinite(caps.centres))
                or np.any(np.linalg.norm(caps.centres, axis=1) < 0.5)
                or not 0.0 < caps.half_angle <= top
            ):
                raise InvalidInputError(
                    f"caps need ({self.k}, 3) finite unit centres and a half angle in "
                    f"(0, {top:.4g}], got {np.shape(caps.centres)} and {caps.half_angle!r}"
                )
            self._frames = caps.frames()

    @staticmethod
    def applies(gsn: GraspSubspace) -> bool:
        """Whether rays from the object-frame origin can parameterise contacts."""
        return float(gsn.obj.signed_distance(np.zeros(3))) < 0.0

    # ---------------------------------------------------------------- layout
    def bounds(self) -> tuple[FloatArray, FloatArray]:
        """``(lower, upper)`` of chart states: the GSn bounds of the pose and free joints."""
        g, hand = self.gsn, self.gsn.hand
        one = _SPHERE_BOUND if self.spheres else 1.0
        d_lo, d_up = np.full(3 * self.k, -one), np.full(3 * self.k, one)
        if self.caps is not None:  # the cap's frame: |e_x|, |e_y| <= sin, e_z >= cos
            angle = self.caps.half_angle
            side = one * (math.sin(angle) if angle < 0.5 * math.pi else 1.0)
            cap_lo = np.tile([-side, -side, math.cos(angle)], self.k)
            cap_up = np.tile([side, side, one], self.k)
            d_lo, d_up = cap_lo, cap_up
        lo = np.concatenate([g.lower[:POSE_DIM], d_lo, hand.lower[self._free_q], [-_PIN_BOUND]])
        up = np.concatenate([g.upper[:POSE_DIM], d_up, hand.upper[self._free_q], [_PIN_BOUND]])
        if self.spheres:
            lo[3:POSE_DIM], up[3:POSE_DIM] = -_SPHERE_BOUND, _SPHERE_BOUND
        return lo, up

    def function(self, y: FloatArray) -> FloatArray:
        """Constraint rows: the pinned coordinate, then ``|quat|^2 - 1``, ``|d_i|^2 - 1``."""
        if not self.spheres:
            return y[-1:]
        f = np.empty(self.co_dim)
        f[0] = y[-1]
        quat = y[3:POSE_DIM]
        f[1] = quat @ quat - 1.0
        d = y[POSE_DIM : POSE_DIM + 3 * self.k].reshape(self.k, 3)
        f[2:] = np.einsum("ij,ij->i", d, d) - 1.0
        return f

    def jacobian(self, y: FloatArray) -> FloatArray:
        """Constraint Jacobian ``(co_dim, dim)`` (analytic)."""
        J = np.zeros((self.co_dim, self.dim))
        J[0, -1] = 1.0
        if self.spheres:
            J[1, 3:POSE_DIM] = 2.0 * y[3:POSE_DIM]
            for row in range(self.k):
                c = POSE_DIM + 3 * row
                J[2 + row, c : c + 3] = 2.0 * y[c : c + 3]
        return J

    def constraint_spec(
        self, scale_position: float, space: str = "projected", delta: float = 0.15
    ) -> ConstraintSpec:
        """The chart as an OMPL constraint; positions scaled by ``scale_position``."""
        lo, up = self.bounds()
        scale = np.ones(self.dim)
        scale[:3] = scale_position
        return ConstraintSpec(
            ambient_dim=self.dim,
            co_dim=self.co_dim,
            function=self.function,
            jacobian=self.jacobian,
            lower=lo,
            upper=up,
            tolerance=1e-9,
            # callers pass the space name as a plain str; ConstraintSpec checks it
            space=space,  # type: ignore[arg-type]
            scale=scale,
            delta=delta,
        )

    # ------------------------------------------------------------------ maps
    def tip_centres(self, dirs: FloatArray) -> FloatArray | None:
        """Fingertip centres ``(k, 3)`` (object frame) on the offset surface along ``dirs``.

        Newton steps on ``g(t) = sdf(t d) - r`` from ``t_max`` (outside), kept
        inside the bracket ``[lo, hi]`` with ``g(lo) < 0 < g(hi)`` by bisection.

        Returns:
            The centres, or None when a ray did not converge.
        """
        obj, r = self.gsn.obj, self._radius
        k = len(dirs)
        lo = np.zeros(k)
        hi = np.full(k, self._t_max)
        t = hi.copy()
        for _ in range(RAY_ITERATIONS):
            d, grad = obj.signed_distance_and_gradient(t[:, None] * dirs)
            g = np.atleast_1d(d) - r
            if np.all(np.abs(g) < RAY_TOLERANCE):
                return t[:, None] * dirs
            grad = np.asarray(grad).reshape(k, 3)
            below = g < 0.0
            lo = np.where(below, t, lo)
            hi = np.where(below, hi, t)
            slope = np.einsum("ij,ij->i", grad, dirs)
            with np.errstate(divide="ignore", invalid="ignore"):
                step = t - g / slope
            ok = (slope > 1e-9) & (step > lo) & (step < hi)
            t = np.where(np.abs(g) < RAY_TOLERANCE, t, np.where(ok, step, 0.5 * (lo + hi)))
        self.stats["ray_failures"] += 1
        return None

    def to_ambient(self, y: FloatArray) -> FloatArray | None:
        """The ambient GSn state ``(7 + nq,)`` of a chart state, or None (no IK, no ray).

        Cached: OMPL asks for the same state's validity, distance and vertex data.
        """
        key = y.tobytes()
        if key in self._cache:
            return self._cache[key]
        x = self._map(np.asarray(y, dtype=np.float64))
        if len(self._cache) >= _CACHE_MAX:
            self._cache.clear()
        self._cache[key] = x
        return x

    def _map(self, y: FloatArray) -> FloatArray | None:
        self.stats["maps"] += 1
        hand = self.gsn.hand
        qn = math.sqrt(float(y[3:POSE_DIM] @ y[3:POSE_DIM]))
        d = y[POSE_DIM : POSE_DIM + 3 * self.k].reshape(self.k, 3)
        dn = np.linalg.norm(d, axis=1)
        if qn < _MIN_NORM or np.any(dn < _MIN_NORM):
            return None
        quat = y[3:POSE_DIM] / qn
        R = quat_to_matrix(quat)
        dirs = d / dn[:, None]
        if self._frames is not None:
            dirs = np.einsum("kij,kj->ki", self._frames, dirs)
        tips = self.tip_centres(dirs @ R if self.world_directions else dirs)
        if tips is None:
            return None
        world = tips @ R.T + y[:3]
        q = self._neutral.copy()
        if len(self._free_q):
            q[self._free_q] = y[POSE_DIM + 3 * self.k : -1]
        for row, i in enumerate(self.contact_ids):
            sol = hand.finger_ik_fast(i, world[row], self._neutral)
            if sol is None:
                self.stats["ik_failures"] += 1
                return None
            q[hand.finger_q_index[i]] = sol
        return np.concatenate([y[:3], quat, q])

    def to_chart(self, x: FloatArray) -> FloatArray:
        """The chart state of an ambient GSn state (pose, tip-centre directions, free joints)."""
        x = np.asarray(x, dtype=np.float64)
        if self.world_directions:
            tips = self.gsn.hand.fingertip_positions(x[POSE_DIM:])[list(self.contact_ids)] - x[:3]
        else:
            tips = self.gsn.fingertips_object_frame(x)[list(self.contact_ids)]
        dirs = tips / np.linalg.norm(tips, axis=1, keepdims=True)
        if self._frames is not None:
            dirs = np.einsum("kji,kj->ki", self._frames, dirs)
        quat = x[3:POSE_DIM] / np.linalg.norm(x[3:POSE_DIM])
        free = x[POSE_DIM:][self._free_q]
        return np.concatenate([x[:3], quat, dirs.reshape(-1), free, [0.0]])

    def represents(self, x: FloatArray, tol: float = 1e-7) -> bool:
        """Whether ambient ``x`` round-trips within ``tol`` and its chart state is in bounds."""
        if self.round_trip_error(x) > tol:
            return False
        lo, up = self.bounds()
        y = self.to_chart(x)
        return bool(np.all(y >= lo) and np.all(y <= up))

    def round_trip_error(self, x: FloatArray) -> float:
        """Largest coordinate change of ``x -> to_chart -> to_ambient`` (inf when it fails)."""
        back = self.to_ambient(self.to_chart(x))
        if back is None:
            return math.inf
        return float(np.max(np.abs(back - np.asarray(x, dtype=np.float64))))

    def is_valid_chart(self, y: FloatArray) -> bool:
        """Validity of a chart state: it maps (rays, IK) and its ambient state is valid."""
        x = self.to_ambient(y)
        return x is not None and bool(self.is_valid(x))

    def path_to_ambient(self, ys: FloatArray) -> FloatArray | None:
        """Ambient states ``(K, 7 + nq)`` of chart states ``(K, dim)``, or None if one fails."""
        out = []
        for y in np.asarray(ys, dtype=np.float64):
            x = self.to_ambient(y)
            if x is None:
                return None
            out.append(x)
        return np.array(out).reshape(-1, self.gsn.ambient_dim)


class ChartProblem:
    """A :class:`PlanningProblem` over the contact chart, seen in ambient GSn states.

    It answers what module 1 asks of a problem (:meth:`solve`,
    :meth:`planner_data`, :meth:`check_path`) with ambient ``(7 + nq,)``
    states, so roadmaps, module 2 and the reduction never see chart states.
    Start, goal states and goal samples are converted with
    :meth:`ContactChart.to_chart`; OMPL's returned path is re-checked in
    travel direction in chart coordinates, densified there, then mapped.

    Args:
        chart: the contact chart.
        problem: the OMPL problem over the chart (its validity checker is
            :meth:`ContactChart.is_valid_chart`).
    """

    def __init__(self, chart: ContactChart, problem: PlanningProblem) -> None:
        self.chart = chart
        self.problem = problem
        self._start: FloatArray | None = None
        self._checked: dict[bytes, bool] = {}

    @property
    def is_multi_query(self) -> bool:
        """Whether the planner keeps a roadmap across queries (PRM family)."""
        return self.problem.is_multi_query

    def set_query(
        self,
        start: FloatArray,
        distance: Callable[[FloatArray], float],
        threshold: float,
        sample: Callable[[], FloatArray | None],
    ) -> None:
        """Set the start (ambient) and the goal region (ambient distance and sampler)."""
        chart = self.chart

        def chart_distance(y: FloatArray) -> float:
            x = chart.to_ambient(y)
            return math.inf if x is None else float(distance(x))

        pool: list[FloatArray] = []
        turn = [0]

        def chart_sample() -> FloatArray | None:
            # RRT's goal bias asks for a goal state on every biased iteration:
            # the first GOAL_POOL draws are kept and handed out in turn.
            if len(pool) >= GOAL_POOL:
                turn[0] += 1
                return pool[turn[0] % len(pool)]
            x = sample()
            if x is None:
                return None
            pool.append(chart.to_chart(x))
            return pool[-1]

        self._start = np.array(start, dtype=np.float64)
        self.problem.set_start(chart.to_chart(start))
        self.problem.set_goal(GoalSpec(chart_distance, threshold, sample=chart_sample))

    def grow_roadmap(self, time_limit: float, max_milestones: int | None = None) -> int:
        """:meth:`PlanningProblem.grow_roadmap`."""
        return self.problem.grow_roadmap(time_limit, max_milestones=max_milestones)

    def solve(self, time_limit: float, *, max_iterations: int | None = None) -> SolveResult:
        """:meth:`PlanningProblem.solve`, the path and waypoints as ambient states."""
        res = self.problem.solve(time_limit, max_iterations=max_iterations)
        if res.path is None:
            return res
        path = self.chart.path_to_ambient(res.path)
        waypoints = None if res.waypoints is None else self.chart.path_to_ambient(res.waypoints)
        if path is None:
            return dataclasses.replace(
                res, status="path_invalid", solved=False, path_valid=False, path=None
            )
        if self._start is not None:  # the start itself, not its round trip (<= 1e-7 away)
            path[0] = self._start
            if waypoints is not None:
                waypoints[0] = self._start
        return dataclasses.replace(res, path=path, waypoints=waypoints)

    def planner_data(self) -> RoadmapData:
        """The planner's graph with ambient vertices.

        OMPL's ``ConstrainedMotionValidator`` does not check a motion's end
        state, so a tree may hold states the chart cannot map (a finger out
        of reach) or invalid ones: those vertices and their edges are left
        out (module 2 links from vertices, the roadmap keeps them).
        """
        data = self.problem.planner_data()
        dim = self.chart.gsn.ambient_dim
        mapped = [self.chart.to_ambient(y) for y in np.asarray(data.vertices, dtype=np.float64)]
        keep = np.array([x is not None and self._valid(x) for x in mapped], dtype=bool)
        new_id = np.cumsum(keep) - 1
        edges = np.asarray(data.edges, dtype=np.int64).reshape(-1, 2)
        edges = new_id[edges[keep[edges].all(axis=1)]] if len(edges) else edges
        vertices = np.array([x for x, k in zip(mapped, keep, strict=True) if k]).reshape(-1, dim)

        def ids(a: Any) -> Any:
            a = np.asarray(a, dtype=np.int64)
            return new_id[a[keep[a]]]

        starts = ids(data.start_ids)
        if self._start is not None and len(starts):
            vertices[starts] = self._start
        return RoadmapData(
            vertices=vertices,
            edges=edges.reshape(-1, 2),
            start_ids=starts,
            goal_ids=ids(data.goal_ids),
        )

    def _valid(self, x: FloatArray) -> bool:
        """The validity of a vertex's ambient state, remembered (vertices recur each round)."""
        key = x.tobytes()
        if key not in self._checked:
            self._checked[key] = bool(self.chart.is_valid(x))
        return self._checked[key]

    def check_path(self, waypoints: object, *, interpolate: bool = True) -> PathCheck:
        """Re-check ambient waypoints in travel direction along chart motions.

        The waypoints must be chart-representable (:meth:`ContactChart.to_chart`
        of each maps back to it): the check is made on the chart states.
        """
        ys = np.array([self.chart.to_chart(x) for x in np.asarray(waypoints, dtype=np.float64)])
        checked = self.problem.check_path(ys, interpolate=interpolate)
        given = np.asarray(waypoints, dtype=np.float64)
        path = self.chart.path_to_ambient(checked.path)
        if path is None:
            return dataclasses.replace(checked, path=given, waypoints=given, path_valid=False)
        return dataclasses.replace(checked, path=path, waypoints=given)
