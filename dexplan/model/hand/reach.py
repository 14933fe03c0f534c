"""Where a fingertip centre can be: voxels filled by forward kinematics.

A cheap test before inverse kinematics: a candidate contact whose fingertip
centre lies outside a finger's reach voxels is not solved for. The voxels
hold the fingertip centres of random configurations (fixed seed), dilated by
one voxel, and are tested on :data:`REACH_CHECK` fresh configurations kept
0.02 rad inside the limits: while more than :data:`REACH_MISSES` of those
fall outside, the samples double (up to :data:`REACH_MAX_DOUBLINGS` times),
then the voxels grow by half (up to :data:`REACH_MAX_VOXEL`). :data:`REACH_SAMPLES`
4 mm voxels pass on the paper, three-finger and Allegro hands; a finger
with a large workspace needs more: the TriFinger's (a lower link turning a
full circle, 0.6 m across) missed 52 % of reachable targets with them,
which cut its transfers to a few degrees and emptied its pools and
landings; its fingers now get 80,000 samples in 9 to 13.5 mm voxels.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from dexplan.core.typing import FloatArray

#: Random configurations whose fingertips fill a finger's reach voxels.
REACH_SAMPLES = 20000
#: Reach voxel edge (m), before any growth.
REACH_VOXEL = 0.004
#: Fresh configurations (kept 0.02 rad inside the limits) that test a finger's voxels.
REACH_CHECK = 20000
#: Most of them the voxels may miss.
REACH_MISSES = 2
#: Most doublings of the samples before the voxels grow.
REACH_MAX_DOUBLINGS = 2
#: Largest voxel edge (m) the growth goes to.
REACH_MAX_VOXEL = 0.016


def reach_samples(finger: int, lower: FloatArray, upper: FloatArray) -> FloatArray:
    """:data:`REACH_SAMPLES` random joint values ``(K, m)`` of ``finger`` (seeded by its index).

    Args:
        finger: finger index (the seed is ``1000 + finger``).
        lower: (m,) the finger's lower joint limits.
        upper: (m,) its upper joint limits.
    """
    rng = np.random.default_rng(1000 + finger)
    return rng.uniform(lower, upper, size=(REACH_SAMPLES, len(lower)))


@dataclass(frozen=True)
class ReachVoxels:
    """Voxels (world frame) a finger's fingertip centre reaches.

    Attributes:
        origin: (3,) corner of voxel (0, 0, 0), world frame.
        size: voxel edge (m).
        occupied: (I, J, K) True where a sampled fingertip centre lies in
            the voxel or one of its 26 neighbours.
    """

    origin: FloatArray
    size: float
    occupied: np.ndarray

    @classmethod
    def from_tips(cls, tips: FloatArray, size: float = REACH_VOXEL) -> ReachVoxels:
        """The voxels (edge ``size``, m) of ``tips: (K, 3)`` (world frame), dilated by one."""
        origin = tips.min(axis=0) - 2 * size
        ijk = np.floor((tips - origin) / size).astype(np.int64)
        grid = np.zeros(tuple(ijk.max(axis=0) + 3), dtype=bool)
        grid[tuple(ijk.T)] = True
        # each occupied voxel and its 26 neighbours (the grid has a free border):
        # the 3 x 3 x 3 box is three one-voxel dilations, one along each axis
        # (the same voxels as scipy's binary_dilation with that structure, a
        # twentieth of its time)
        for axis in range(3):
            lo = [slice(None)] * 3
            hi = [slice(None)] * 3
            lo[axis], hi[axis] = slice(None, -1), slice(1, None)
            src = grid.copy()
            grid[tuple(hi)] |= src[tuple(lo)]
            grid[tuple(lo)] |= src[tuple(hi)]
        return cls(origin, size, grid)

    def contains(self, tips: FloatArray) -> np.ndarray:
        """(N,) True where fingertip centres ``tips: (N, 3)`` (world frame) lie in a voxel."""
        ijk = np.floor((tips - self.origin) / self.size).astype(np.int64)
        inside = np.all((ijk >= 0) & (ijk < np.array(self.occupied.shape)), axis=1)
        out = np.zeros(len(tips), dtype=bool)
        out[inside] = self.occupied[tuple(ijk[inside].T)]
        return out


def grown_voxels(
    tips_of: Callable[[FloatArray], FloatArray], finger: int, lower: FloatArray, upper: FloatArray
) -> ReachVoxels:
    """A finger's reach voxels, grown until they miss few fresh fingertip centres.

    Args:
        tips_of: joint values ``(K, m)`` to fingertip centres ``(K, 3)``, world frame.
        finger: finger index (seeds the samples).
        lower: (m,) the finger's lower joint limits.
        upper: (m,) its upper joint limits.
    """
    q = reach_samples(finger, lower, upper)
    tips = tips_of(q)
    margin = np.minimum(0.02, 0.25 * (upper - lower))
    check = tips_of(
        np.random.default_rng(2000 + finger).uniform(
            lower + margin, upper - margin, size=(REACH_CHECK, len(lower))
        )
    )
    size, doublings = REACH_VOXEL, 0
    voxels = ReachVoxels.from_tips(tips, size)
    while int(np.count_nonzero(~voxels.contains(check))) > REACH_MISSES:
        if doublings < REACH_MAX_DOUBLINGS:
            rng = np.random.default_rng([1000 + finger, doublings + 1])
            tips = np.vstack(
                [tips, tips_of(rng.uniform(lower, upper, size=(len(tips), len(lower))))]
            )
            doublings += 1
        elif size * 1.5 <= REACH_MAX_VOXEL:
            size *= 1.5
        else:
            break
        voxels = ReachVoxels.from_tips(tips, size)
    return voxels
