"""Planning in the grasp subspace: OMPL adapter, GSn space, samplers, roadmaps.

The :mod:`dexplan.planning.ompl` package is the only part of dexplan that imports
``ompl``; the other planning modules hand it plain NumPy callables.
"""

__all__ = [
    "context",
    "deadline",
    "diagnostics",
    "gsn",
    "local",
    "ompl",
    "planner",
    "progress",
    "roadmap",
    "start",
    "stats",
]
