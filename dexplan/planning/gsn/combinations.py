"""Grasps combined from per-finger pools, ranked by how well their normals balance.

A pool holds, per contact finger, collision-free IK solutions to sampled
contacts at one object pose (:meth:`~dexplan.planning.gsn.sampler.GraspSampler.finger_pools`).
:func:`combine_pools` draws random combinations (one pool entry per finger),
drops those whose fingertips come too close, ranks the rest by normal balance
and keeps those the half-space test does not rule out.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from dexplan.core.pose import quat_to_matrix
from dexplan.core.typing import FloatArray, IntArray
from dexplan.model.hand.hand import Hand
from dexplan.planning.gsn.space import POSE_DIM

#: Of a pose's combination draws, those best balanced, this many per combination
#: kept (:attr:`~dexplan.planning.gsn.sampler.SamplerSettings.combinations`), get
#: the half-space test; the rest are dropped unranked: few draws pass the test,
#: and valid grasps rank near the top of the balance order.
RANKED_PER_COMBINATION = 4

#: One finger's pool: fingertip centres ``(P, 3)`` and outward normals ``(P, 3)``
#: (world frame), and the finger's joints ``(P, m)``.
FingerPool = tuple[FloatArray, FloatArray, FloatArray]


@dataclass(frozen=True)
class Combinations:
    """Grasps combined from one pose's per-finger pools (:func:`combine_pools`).

    Attributes:
        states: ambient states ``(7 + nq,)``, most promising first.
        points_obj: (M, k, 3) their contact points, object frame (contact
            fingers in ``GraspSubspace.contact_ids`` order).
        normals_in_obj: (M, k, 3) inward unit surface normals there, object frame.
    """

    states: list[FloatArray]
    points_obj: FloatArray
    normals_in_obj: FloatArray

    def __len__(self) -> int:
        return len(self.states)


def combine_pools(
    pose_xyzquat: FloatArray,
    pools: dict[int, FingerPool],
    hand: Hand,
    rng: np.random.Generator,
    *,
    draws: int,
    tip_clearance: float,
    count: int,
    cannot_hold: Callable[[FloatArray], np.ndarray],
) -> Combinations:
    """Grasps combined from per-finger pools, most promising first (validity not checked).

    Draws ``draws`` random combinations (one pool entry per contact finger),
    drops those whose fingertips come closer than ``2 r + tip_clearance``,
    and sorts the rest by normal balance (:func:`_balance`). Of the best
    ``RANKED_PER_COMBINATION * count``, those ``cannot_hold`` does not rule
    out are kept, best first, duplicates dropped. Free fingers get random
    joint values.

    Args:
        pose_xyzquat: (7,) the object pose, world frame, XYZW.
        pools: per contact finger, its pool at that pose.
        hand: the hand.
        rng: random generator (the draws, then the free fingers' joints).
        draws: random combinations ranked.
        tip_clearance: minimum gap between two fingertip spheres (m).
        count: combinations returned at most.
        cannot_hold: ``(M, k, 3)`` outward normals to ``(M,)`` True where a
            required (sub)grasp cannot be force closure (the half-space test).

    Returns:
        Up to ``count`` ambient states ``(7 + nq,)`` and their contacts.
    """
    fingers = list(pools)
    sizes = np.array([len(pools[i][0]) for i in fingers])
    pick = (rng.random((draws, len(fingers))) * sizes).astype(np.int64)
    pick = pick[_apart(pools, fingers, pick, 2 * hand.fingertip_radius + tip_clearance)]
    # per finger (M, 3) arrays: sums and norms of small stacked axes are slow
    each = [pools[i][1][pick[:, j]] for j, i in enumerate(fingers)]
    score = _balance(each)
    # only the best-balanced draws are worth the half-space test: the
    # valid grasps rank first
    best = np.arange(len(score))
    keep = RANKED_PER_COMBINATION * count
    if len(score) > keep:
        best = np.sort(np.argpartition(score, keep)[:keep])
    pick, score = pick[best], score[best]
    normals = np.stack([n_j[best] for n_j in each], axis=1)
    held = ~cannot_hold(normals)
    pick, normals, score = pick[held], normals[held], score[held]
    rows = _distinct_best(pick, score, count)
    return _combined(pose_xyzquat, pools, fingers, pick[rows], normals[rows], hand, rng)


def combine_pools_pairwise(
    pose_xyzquat: FloatArray,
    pools: dict[int, FingerPool],
    hand: Hand,
    rng: np.random.Generator,
    *,
    mu: float,
    tip_clearance: float,
    count: int,
) -> Combinations:
    """Every 3-finger combination whose 2-finger subgrasps can be force closure, best first.

    For three contact fingers whose 2-finger subgrasps must each be force
    closure, the random draws of :func:`combine_pools` rarely meet the
    condition where it is narrow (a cube: two fingers on edges with normals
    in a band of a few degrees). Two soft-finger contacts are force closure
    only if the line through them lies strictly inside both friction cones
    (Nguyen 1988), a pairwise condition: it is tested for every pair of pool
    entries of every two fingers (``P^2`` per pair, one array each), and
    every triple whose three pairs pass is kept (``P^3`` booleans, no
    sampling). The test uses the round cone of half-angle ``atan(mu)``, which
    contains the planner's linearised pyramid, so it never drops a grasp the
    force-closure quality would accept. Triples rank by their worst pair: the
    largest angle between a contact's inward normal and the line to the
    other contact (the most central first).

    Args:
        pose_xyzquat: (7,) the object pose, world frame, XYZW.
        pools: three contact fingers' pools at that pose.
        hand: the hand.
        rng: random generator (the free fingers' joints).
        mu: friction coefficient.
        tip_clearance: minimum gap between two fingertip spheres (m).
        count: combinations returned at most.

    Returns:
        Up to ``count`` ambient states ``(7 + nq,)`` and their contacts.
    """
    fingers = list(pools)
    if len(fingers) != 3:
        raise ValueError(f"pairwise combinations need 3 contact fingers, got {len(fingers)}")
    gap = 2 * hand.fingertip_radius + tip_clearance
    r = hand.fingertip_radius
    worst = {
        (a, b): _pair_angles(pools[fingers[a]], pools[fingers[b]], r, gap)
        for a, b in ((0, 1), (0, 2), (1, 2))
    }
    half = float(np.arctan(mu))
    # (Pa, Pb, Pc): the worst of the three pairs' angles
    total = np.maximum(
        np.maximum(worst[0, 1][:, :, None], worst[0, 2][:, None, :]), worst[1, 2][None, :, :]
    )
    flat = np.flatnonzero(total < half)
    if len(flat) > count:
        flat = flat[np.argpartition(total.ravel()[flat], count)[:count]]
    flat = flat[np.argsort(total.ravel()[flat], kind="stable")]
    pick = np.stack(np.unravel_index(flat, total.shape), axis=1).astype(np.int64)
    normals = np.stack([pools[i][1][pick[:, j]] for j, i in enumerate(fingers)], axis=1)
    return _combined(pose_xyzquat, pools, fingers, pick, normals, hand, rng)


def _pair_angles(pool_a: FingerPool, pool_b: FingerPool, radius: float, gap: float) -> FloatArray:
    """``(Pa, Pb)`` per pair of entries, the larger angle (rad) between a normal and the line.

    For each entry of ``pool_a`` and of ``pool_b`` (fingertip centres and
    outward normals, world frame), the contacts are the centres less
    ``radius`` along the normals; the angle is that between a contact's
    inward normal and the line to the other contact, the larger of the two.
    Pairs whose fingertip centres are closer than ``gap`` get pi (never kept).
    """
    (t_a, n_a, _), (t_b, n_b, _) = pool_a, pool_b
    d = (t_b - radius * n_b)[None, :, :] - (t_a - radius * n_a)[:, None, :]
    length = np.linalg.norm(d, axis=2)
    u = d / np.maximum(length, 1e-12)[..., None]
    cos_a = -np.einsum("abk,ak->ab", u, n_a)  # inward normal of a: -n_a
    cos_b = np.einsum("abk,bk->ab", u, n_b)  # line b -> a is -u; inward -n_b
    angle = np.arccos(np.clip(np.minimum(cos_a, cos_b), -1.0, 1.0))
    apart = np.linalg.norm(t_a[:, None] - t_b[None], axis=2) >= gap
    return np.asarray(np.where(apart & (length > 1e-9), angle, np.pi))


def _apart(
    pools: dict[int, FingerPool], fingers: list[int], pick: IntArray, gap: float
) -> np.ndarray:
    """(M,) True where the picked fingertip centres ``pick: (M, k)`` are ``gap`` apart or more.

    Each pair of pools' distances is computed once, then looked up.
    """
    ok = np.ones(len(pick), dtype=bool)
    for a in range(len(fingers)):
        for b in range(a + 1, len(fingers)):
            ta, tb = pools[fingers[a]][0], pools[fingers[b]][0]
            apart = np.linalg.norm(ta[:, None] - tb[None], axis=2) >= gap
            ok &= apart[pick[:, a], pick[:, b]]
    return ok


def _balance(each: list[FloatArray]) -> FloatArray:
    """Normal balance ``(M,)`` of grasps with outward normals ``each[j]: (M, 3)`` per finger.

    The largest, over the grasp's (k-1)-finger subgrasps, length of the mean
    outward normal (0 when the normals of every subgrasp cancel, which force
    closure of every subgrasp needs on a sphere); for k < 3 the grasp's own.
    """
    k = len(each)
    total = np.sum(each, axis=0)
    if k >= 3:
        # subgrasp without finger j: (total - n_j) / (k - 1)
        worst = np.zeros(len(total))
        for n_j in each:
            d = total - n_j
            np.maximum(worst, np.einsum("ij,ij->i", d, d), out=worst)
        return np.asarray(np.sqrt(worst) / (k - 1))
    return np.asarray(np.sqrt(np.einsum("ij,ij->i", total, total)) / max(k, 1))


def _distinct_best(pick: IntArray, score: FloatArray, count: int) -> list[int]:
    """Rows of ``pick`` by ascending ``score``, duplicates dropped, ``count`` at most."""
    rows: list[int] = []
    seen: set[bytes] = set()
    for row in np.argsort(score, kind="stable"):
        key = pick[row].tobytes()
        if key in seen:
            continue
        seen.add(key)
        if len(rows) >= count:
            break
        rows.append(int(row))
    return rows


def _combined(
    pose_xyzquat: FloatArray,
    pools: dict[int, FingerPool],
    fingers: list[int],
    pick: IntArray,
    n_w: FloatArray,
    hand: Hand,
    rng: np.random.Generator,
) -> Combinations:
    """The states and contacts of the chosen combinations ``pick: (M, k)``.

    ``n_w: (M, k, 3)`` their outward normals, world frame. Free fingers get
    random joint values (one draw for all, as one per grasp would give).
    """
    q = rng.uniform(hand.lower, hand.upper, size=(len(pick), len(hand.lower)))
    for j, i in enumerate(fingers):
        q[:, hand.finger_q_index[i]] = pools[i][2][pick[:, j]]
    states = np.empty((len(pick), POSE_DIM + q.shape[1]))
    states[:, :POSE_DIM] = pose_xyzquat[:POSE_DIM]
    states[:, POSE_DIM:] = q
    R = quat_to_matrix(pose_xyzquat[3:7] / np.linalg.norm(pose_xyzquat[3:7]))
    tips_w = np.stack([pools[i][0][pick[:, j]] for j, i in enumerate(fingers)], axis=1)
    points = (tips_w - hand.fingertip_radius * n_w - pose_xyzquat[:3]) @ R
    k = len(fingers)
    return Combinations(list(states), points.reshape(-1, k, 3), -(n_w @ R).reshape(-1, k, 3))
