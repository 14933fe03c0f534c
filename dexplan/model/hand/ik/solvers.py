"""Which inverse-kinematics solver each finger of a hand gets, found once per hand.

:class:`FingerSolvers` detects, per finger, the closed forms its structure
allows (:class:`PlanarFingerIK`, :class:`SplitFingerIK`,
:class:`OffsetFingerIK`, :class:`PlanarPairIK`) and its vectorised chain
(:class:`FingerChain`); a finger with none is solved by damped least squares.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import pinocchio as pin

from dexplan.core.typing import FloatArray, IntArray
from dexplan.model.hand.ik.chain import FingerChain
from dexplan.model.hand.ik.offset import OffsetFingerIK
from dexplan.model.hand.ik.planar import PlanarFingerIK
from dexplan.model.hand.ik.planar_pair import PlanarPairIK
from dexplan.model.hand.ik.split import SplitFingerIK

__all__ = ["FingerSolvers"]


@dataclass(frozen=True)
class FingerSolvers:
    """Per finger, its IK solvers and vectorised chain (None where it has none).

    Attributes:
        analytic: closed-form IK of a planar 3-joint finger.
        chains: vectorised forward kinematics (revolute fingers).
        split: closed forms of a redundant 4-joint finger (a grid for the redundancy).
        offset: closed forms of offset 3-joint and planar 2-joint fingers.
    """

    analytic: tuple[PlanarFingerIK | None, ...]
    chains: tuple[FingerChain | None, ...]
    split: tuple[SplitFingerIK | None, ...]
    offset: tuple[OffsetFingerIK | PlanarPairIK | None, ...]

    @classmethod
    def detect(
        cls,
        model: pin.Model,
        finger_q_index: Sequence[IntArray],
        tip_frame_ids: Sequence[int],
        lower: FloatArray,
        upper: FloatArray,
        neutral: FloatArray,
    ) -> FingerSolvers:
        """The closed forms a hand's fingers allow.

        Args:
            model: the hand's Pinocchio model.
            finger_q_index: per finger, its joints' indexes in ``q``.
            tip_frame_ids: per finger, its fingertip frame.
            lower: (nq,) the joints' lower limits.
            upper: (nq,) their upper limits.
            neutral: (nq,) the configuration the planar test starts from.
        """
        data = model.createData()  # its own: a caller may be between an FK and its reads
        analytic = tuple(
            PlanarFingerIK.detect(model, data, idx, fid, lower, upper, neutral)
            for idx, fid in zip(finger_q_index, tip_frame_ids, strict=True)
        )
        chains = tuple(FingerChain.from_model(model, fid) for fid in tip_frame_ids)
        split: list[SplitFingerIK | None] = []
        # every branch in closed form: offset 3-joint (TriFinger), planar 2-joint (Dex3)
        offset: list[OffsetFingerIK | PlanarPairIK | None] = []
        for i, idx in enumerate(finger_q_index):
            lo_f, hi_f, chain = lower[idx], upper[idx], chains[i]
            planar = analytic[i] is not None
            split.append(None if planar else SplitFingerIK.detect(chain, lo_f, hi_f))
            other = planar or split[i] is not None
            found = None if other else OffsetFingerIK.detect(chain, lo_f, hi_f)
            offset.append(found or PlanarPairIK.detect(chain, lo_f, hi_f))
        return cls(analytic, chains, tuple(split), tuple(offset))
