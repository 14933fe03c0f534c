"""dexplan: dexterous in-hand manipulation planning in the n-finger grasp subspace.

After Saut, Sahbani and Perdereau, "A Global Approach for Dexterous Manipulation
Planning Using Paths in n-fingers Grasp Subspace" (ICARCV 2006).

Front door (:mod:`dexplan.api`): ``dexplan.plan(scenario, planner=..., params=...,
seed=..., time_limit=...)`` returns a :class:`~dexplan.api.Plan` with
``.save(path)`` and ``.to_document()``; ``dexplan.load_scenario(path)``;
``dexplan.verify(path)``.
"""

from __future__ import annotations

from typing import Any

from dexplan.core.errors import DexplanError

__version__ = "0.1.0"

__all__ = [
    "DexplanError",
    "Plan",
    "RoadmapPlanner",
    "__version__",
    "load_scenario",
    "plan",
    "verify",
]

_API = ("Plan", "RoadmapPlanner", "load_scenario", "plan", "verify")


def __getattr__(name: str) -> Any:
    # the front door (dexplan.api) loads OMPL, Pinocchio and coal, 2.8 s of wall time
    # against 0.01 s for `import dexplan` (measured with `python -X importtime` and
    # `time` on the 2-core development machine): only on use, because every
    # `import dexplan.<sub>` and the CLI's start run this module first
    if name in _API:
        from dexplan import api

        globals().update({n: getattr(api, n) for n in _API})  # once: no more lookups here
        return getattr(api, name)
    raise AttributeError(f"module 'dexplan' has no attribute {name!r}")
