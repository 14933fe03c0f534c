"""Resolution and search settings of the transfer and regrasp planners."""

from __future__ import annotations

from dataclasses import dataclass

from dexplan.model.grasp.rolling import ContactMotion


@dataclass(frozen=True)
class TransitionSettings:
    """Resolution and search settings of the local planners.

    Attributes:
        max_step_m: largest object translation or fingertip move between
            waypoints (m); the plan verifier allows 1 cm.
        max_step_rad: largest object rotation or joint change between
            waypoints (rad); the verifier allows 0.05.
        joint_margin: transfers stop this far (rad) from joint limits.
        lift_height: fingertip clearance above the surface before moving (m).
        landing_candidates: surface points sampled when choosing a landing.
        landing_edges: edge points (normals inside the edge's cone) added to
            them on shapes with edges (boxes): held on two opposite faces, a
            finger gets onto a third face only by way of an edge.
        landing_vertices: vertex points (normals inside the corner's cone)
            added too, on shapes with vertices (boxes); the planning context
            sets them where faces alone cannot hold.
        landing_reachable: of those, the ones the finger reaches now that
            are scored (the first ``landing_reachable``, in sampling order).
        via_points: random via points tried for a free-finger move.
        tip_clearance: minimum gap between fingertip spheres (m).
        follow_stride: pose stride when scoring how long a landing can be followed.
        transit_planner: OMPL planner for a free-finger move that neither the
            straight line nor a via point clears (None: no such fallback).
        transit_time: its time cap (s).
        transit_iterations: its iteration cap (the answer depends on the seed only
            when this cap, not the time, stops it).
        landing_solutions: IK solutions (nearest first) tried for a
            collision-free landing configuration when the nearest collides
            (redundant fingers have many: branches times the free-joint grid).
        posture_options: other postures of a redundant finger tried, one
            tracking step away, when a transfer step collides.
        landing_alignment: landings of a redundant finger need an IK solution
            whose last link is within ``acos(landing_alignment)`` of the
            inward normal (its side would touch the surface otherwise);
            None: no such filter. Non-redundant fingers are not filtered.
        tracked_landings: landing candidates (best IK-only follow scores
            first) whose follow is re-scored by tracking the finger along the
            rest of the motion with its links collision-checked against the
            palm, the object and the obstacles (:meth:`.FingerFollower.track_score`);
            0: IK-only scores.
        tracked_landings_simple: ``tracked_landings`` for non-redundant
            fingers (one posture per IK branch): their IK-only score already
            follows the finger's own motion and misses only link collisions,
            so fewer are tracked (each costs a force-closure check and a track).
        contact_motion: how transfers move the contacts: fixed on the object
            (the paper's; the fingertips slide) or rolling
            (:mod:`.rolling_transfer`).
    """

    max_step_m: float = 0.008
    max_step_rad: float = 0.04
    joint_margin: float = 0.02
    lift_height: float = 0.008
    landing_candidates: int = 600
    landing_edges: int = 300
    landing_vertices: int = 0
    via_points: int = 96
    tip_clearance: float = 0.004
    follow_stride: int = 2
    transit_planner: str | None = "RRTConnect"
    transit_time: float = 1.0
    transit_iterations: int = 200
    landing_solutions: int = 8
    posture_options: int = 6
    landing_alignment: float | None = 0.4
    tracked_landings: int = 16
    landing_reachable: int = 96
    tracked_landings_simple: int = 8
    contact_motion: ContactMotion = ContactMotion.FIXED
