"""Settings of the GSn sampler, and the defaults that depend on the hand and the object.

:class:`SamplerSettings` leaves some fields None: :func:`resolved_settings`
fills them in for a hand (fingers of more than 3 joints, or where faces
alone cannot hold, :mod:`.contact_kinds`), and :func:`combines_pairwise`
says whether three fingers' pools are combined pairwise
(:func:`~dexplan.planning.gsn.combinations.combine_pools_pairwise`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from dexplan.model.hand.hand import Hand

__all__ = ["SamplerSettings", "combines_pairwise", "long_fingers", "resolved_settings"]


@dataclass(frozen=True)
class SamplerSettings:
    """Settings of :class:`GraspSampler`.

    Attributes:
        candidates: surface points drawn per finger and attempt.
        candidate_edges: edge points drawn with them when ``edge_contacts``
            is on (shapes with edges).
        edge_contacts: sample fingertips on the object's edges too; None:
            for fingers of more than 3 joints, and wherever faces alone
            cannot hold (:mod:`.contact_kinds`; the paper hand holds boxes
            on faces, where edges double the regrasps of a box turn).
        vertex_contacts: sample fingertips on the object's vertices (box
            corners) too, ``candidate_vertices`` and ``pool_vertices`` of
            them; None: wherever faces alone cannot hold (the hands that
            need edges for their fingers' shape, the Allegro, hold on edges).
        max_attempts: attempts per :meth:`GraspSampler.sample` call before None.
        tip_clearance: minimum gap between two fingertip spheres (m).
        min_facing: minimum cosine between a candidate's outward normal and
            the direction to the finger's base (links stay clear of the object).
        balance_pool: reachable candidates compared for normal balance.
        per_finger: sample per finger first (pools of collision-free
            per-finger IK solutions, then combinations); False: the RLG
            steps above, contacts placed finger after finger.
        pool_size: per-finger solutions kept in a pool.
        pool_candidates: surface points drawn per finger for a pool.
        pool_edges: edge points (normals inside the edge's cone) drawn with
            them when ``edge_contacts`` is on, on shapes that have edges (boxes).
        candidate_vertices: vertex points drawn with the ``candidates`` when
            ``vertex_contacts`` is on (shapes with vertices).
        pool_vertices: vertex points (normals inside the corner's cone) drawn
            with the ``pool_candidates`` when ``vertex_contacts`` is on.
        solutions_per_contact: IK solutions (random among those within
            limits) collision-checked per candidate contact.
        combinations: grasps combined from one set of pools and checked
            before a new object pose is drawn (sample() returns at the first
            valid one). None: 96 for hands with fingers of more than 3
            joints, 40 otherwise (see ``grasps_per_pose``).
        combination_draws: random combinations ranked to choose those.
        joint_margin: pool solutions keep this far (rad) from joint limits
            (transfers stop short of them, ``TransitionSettings.joint_margin``).
        grasps_per_pose: with random poses (:meth:`GraspSampler.sample`),
            up to this many valid grasps are returned, one per call, from the
            ranked combinations of a pose before a new pose is drawn (1: a
            new pose every call). None: 64 for hands with fingers of more
            than 3 joints, whose pools are costly (more combinations and
            grasps a pose give more valid grasps a second, and their plans
            are no worse), 2 otherwise: a roadmap gains more from distinct
            object poses than from a faster sampler, since checking its
            motions costs far more than sampling (with many grasps a pose
            the roadmap planners solve fewer queries in a fixed time).
        pairwise: combine three contact fingers' pools by the pairwise test
            of :func:`~dexplan.planning.gsn.combinations.combine_pools_pairwise`
            (every 2-finger subgrasp's line inside both friction cones, all
            triples enumerated) instead of random draws; None: wherever faces
            alone cannot hold with three contact fingers (the cube of a
            3-finger hand, where random draws rarely meet the narrow bands).
        check_batch: ranked combinations whose force closure is computed in
            one batch; a pose is left after a batch with no valid grasp. The
            normal-balance ranking puts a pose's valid grasps first (a pose
            whose first batch holds none almost never has one later), so
            this halves the force-closure work for a few per cent fewer
            valid grasps.
    """

    candidates: int = 48
    candidate_edges: int = 12
    edge_contacts: bool | None = None
    vertex_contacts: bool | None = None
    max_attempts: int = 50
    tip_clearance: float = 0.004
    min_facing: float = -0.3
    balance_pool: int = 6
    per_finger: bool = True
    pool_size: int = 24
    pool_candidates: int = 256
    pool_edges: int = 64
    candidate_vertices: int = 8
    pool_vertices: int = 64
    solutions_per_contact: int = 3
    combinations: int | None = None
    combination_draws: int = 4000
    joint_margin: float = 0.03
    grasps_per_pose: int | None = None
    check_batch: int = 24
    pairwise: bool | None = None


def long_fingers(hand: Hand) -> bool:
    """Whether some finger of ``hand`` has more than 3 joints (redundant for a contact)."""
    return max(len(idx) for idx in hand.finger_q_index) > 3


def resolved_settings(
    settings: SamplerSettings, hand: Hand, faces_only: bool
) -> tuple[SamplerSettings, int, int, bool]:
    """``settings`` with the hand-dependent defaults (None fields) filled in.

    Where faces alone cannot hold (``faces_only``) and ``edge_contacts`` is
    automatic, pools draw as many edge points as face points, keep 64
    solutions and rank 16000 draws: a valid grasp then needs edges with
    normals in a narrow band for two fingers at once (a TriFinger on its cube:
    none in 250 combined grasps at the start pose without, 2 to 3 with).

    Returns:
        ``(settings, combinations, grasps_per_pose, edges)``: the filled-in
        values also as plain values.
    """
    long = long_fingers(hand)
    combinations = (96 if long else 40) if settings.combinations is None else settings.combinations
    per_pose = (64 if long else 2) if settings.grasps_per_pose is None else settings.grasps_per_pose
    filled = replace(settings, combinations=combinations, grasps_per_pose=per_pose)
    if settings.edge_contacts is None and faces_only and not long:
        filled = replace(
            filled,
            pool_edges=max(filled.pool_edges, filled.pool_candidates),
            pool_size=max(filled.pool_size, 64),
            combination_draws=max(filled.combination_draws, 16000),
        )
    edges = long or faces_only if settings.edge_contacts is None else settings.edge_contacts
    return filled, combinations, per_pose, edges


def combines_pairwise(
    settings: SamplerSettings, contacts: int, subgrasps: bool, faces_only: bool
) -> bool:
    """Whether grasps are combined pairwise (:func:`combine_pools_pairwise`).

    Only three contact fingers whose 2-finger subgrasps must hold can be;
    by default only where faces alone cannot hold (elsewhere, on spheres
    and the paper hand's boxes, the balance-ranked draws already find valid
    grasps first, and the plans they give are left as they were).
    """
    usable = contacts == 3 and subgrasps
    return usable and (faces_only if settings.pairwise is None else settings.pairwise)
