"""The wall-clock deadline of one query, shared by every stage that can take long.

The planner sets it once; the sampler, the goal sampler, the local planners
and the reductions read it, so a time limit holds on every hand and in every
stage (start grasp, module 1 rounds, module 2, reduction, smoothing), not only
in OMPL's own ``solve``. An expired deadline makes a stage give up with its
usual "not found" answer; it never raises.
"""

from __future__ import annotations

import math
import os
import time

#: The environment variable that makes every query's time budget k times shorter.
SLOWDOWN_ENV = "DEXPLAN_SLOWDOWN"


def budget(seconds: float) -> float:
    """The part of a ``seconds`` time limit a query may spend: all of it, unless slowed.

    With ``DEXPLAN_SLOWDOWN=k`` (a number >= 1) a query gets ``seconds / k``:
    what it would get done on a machine k times slower. CI runs the test
    suite so, to show that no test depends on the machine's speed. Any other
    value is ignored.
    """
    try:
        k = float(os.environ.get(SLOWDOWN_ENV, "1"))
    except ValueError:
        return seconds
    return seconds / k if math.isfinite(k) and k >= 1.0 else seconds


class Deadline:
    """A ``time.perf_counter()`` instant after which work stops (default: never).

    Attributes:
        at: the instant, ``math.inf`` for no deadline.
    """

    __slots__ = ("at",)

    def __init__(self, at: float = math.inf) -> None:
        self.at = at

    @classmethod
    def after(cls, seconds: float) -> Deadline:
        """A deadline ``seconds`` from now."""
        return cls(time.perf_counter() + seconds)

    def expired(self) -> bool:
        """True once the instant has passed."""
        return time.perf_counter() >= self.at

    def remaining(self) -> float:
        """Seconds left (negative once expired, ``inf`` for no deadline)."""
        return self.at - time.perf_counter()
