"""Inverse kinematics of serial fingers, one module per solver.

- :mod:`.planar` (:class:`PlanarFingerIK`): closed form for an abduction
  joint followed by a planar 2R chain (3 joints).
- :mod:`.split` (:class:`SplitFingerIK`): the same closed form after fixing
  at most one free joint, vectorised over targets; 4-joint fingers resolve
  the free joint on a grid (see ``docs/hands.md``, "IK and redundancy").
- :mod:`.offset` (:class:`OffsetFingerIK`): closed form for 3 joints with
  offset axes; :mod:`.planar_pair` (:class:`PlanarPairIK`): 2 parallel joints.
- :mod:`.numeric` (:func:`batch_dls`, :func:`finger_dls`): damped least
  squares for any revolute chain, batched or one target with restarts.
- :mod:`.chain` (:class:`FingerChain`): vectorised forward kinematics and
  position Jacobian of a revolute finger.
- :mod:`.solvers` (:class:`FingerSolvers`): which of these each finger of a
  hand gets.

Frames: everything is in the world (= palm) frame. ``q`` arrays hold one
finger's joints in chain order (root to tip), which is also the order of
``Hand.finger_q_index[i]``.
"""

from dexplan.model.hand.ik.branches import BRANCH_SEEDS, branch_solutions
from dexplan.model.hand.ik.chain import FingerChain
from dexplan.model.hand.ik.numeric import IKResult, batch_dls, finger_dls
from dexplan.model.hand.ik.offset import OffsetFingerIK
from dexplan.model.hand.ik.planar import PlanarFingerIK, nearest_branch, planar_branches
from dexplan.model.hand.ik.planar_pair import PlanarPairIK
from dexplan.model.hand.ik.solvers import FingerSolvers
from dexplan.model.hand.ik.split import (
    SAMPLE_GRID,
    TRACK_DELTAS,
    TRACK_MAX_STEP,
    TRACK_RESOLUTION,
    SplitFingerIK,
)

__all__ = [
    "BRANCH_SEEDS",
    "SAMPLE_GRID",
    "TRACK_DELTAS",
    "TRACK_MAX_STEP",
    "TRACK_RESOLUTION",
    "FingerChain",
    "FingerSolvers",
    "IKResult",
    "OffsetFingerIK",
    "PlanarFingerIK",
    "PlanarPairIK",
    "SplitFingerIK",
    "batch_dls",
    "branch_solutions",
    "finger_dls",
    "nearest_branch",
    "planar_branches",
]
