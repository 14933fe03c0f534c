"""The local planners' counters: what the transfers and regrasps of one query did."""

from __future__ import annotations

from typing import NotRequired, TypedDict

__all__ = ["LocalCounts", "new_counts"]


class LocalCounts(TypedDict):
    """Counters shared by the transfer, regrasp and landing planners of one query.

    A plain dict at run time: the plan's statistics carry it as it is (with
    the ``local_`` prefix), in this key order.

    Attributes:
        transfers: transfer paths planned.
        regrasp_attempts: regrasps tried.
        regrasps: regrasps planned.
        landing_checks: landing contacts checked.
        weak_holds: releases refused because the remaining fingers' hold was too weak.
        backtracks: reductions that stepped back to an earlier grasp.
        transit_planned: free-finger moves handed to the OMPL transit planner.
        transit_planned_found: of those, the ones it found a path for.
    """

    transfers: int
    regrasp_attempts: int
    regrasps: int
    landing_checks: int
    weak_holds: int
    backtracks: int
    transit_planned: NotRequired[int]
    transit_planned_found: NotRequired[int]


def new_counts() -> LocalCounts:
    """Every always-present counter at zero."""
    return {
        "transfers": 0,
        "regrasp_attempts": 0,
        "regrasps": 0,
        "landing_checks": 0,
        "weak_holds": 0,
        "backtracks": 0,
    }
