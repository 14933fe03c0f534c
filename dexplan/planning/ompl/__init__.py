"""Generic adapter between NumPy callables and OMPL constrained planning.

This package is the only part of dexplan that imports :mod:`ompl`. Everything
else hands it plain callables on NumPy vectors; the modules follow OMPL's seams:

- :mod:`~dexplan.planning.ompl.registry`: planners by name (:data:`PLANNERS`,
  their :class:`PlannerTraits`), their parameters, :func:`check_planner`;
- :mod:`~dexplan.planning.ompl.spaces`: :class:`ConstraintSpec` (``f(x) = 0``
  with an analytic Jacobian and ambient bounds) as an ``ob.Constraint`` in a
  projected, atlas or tangent-bundle state space, :class:`ProjectionSpec` for the
  KPIECE family, bounds and the scaled planning coordinates ``y = x * scale``;
- :mod:`~dexplan.planning.ompl.callbacks`: the validity checker, the valid-state
  sampler, :class:`GoalSpec` goal regions and termination conditions;
- :mod:`~dexplan.planning.ompl.error_sink`: the error sink that keeps Python
  exceptions out of OMPL's C++ frames;
- :mod:`~dexplan.planning.ompl.motions`: a second motion where OMPL's fails;
- :mod:`~dexplan.planning.ompl.problem_space`: a problem's constrained space built
  with its callbacks, its states, motions and re-checked paths;
- :mod:`~dexplan.planning.ompl.problem`: :class:`PlanningProblem` (solve, grow a
  roadmap, re-check paths in travel direction, read the planner's graph);
- :mod:`~dexplan.planning.ompl.results`: :class:`SolveResult`, :class:`PathCheck`,
  :class:`RoadmapData`;
- :mod:`~dexplan.planning.ompl.joint_path`: :func:`plan_joint_path`, unconstrained
  paths in a box (a free finger's joint space);
- :mod:`~dexplan.planning.ompl.runtime`: OMPL's log level and global seed.

Binding facts this package is built around (ompl 2.0.1 PyPI wheel, nanobind),
each written down in the module it concerns:

- ``Constraint`` callbacks get read-only/writable NumPy views, ~3.3 us a Python
  override; states are read by ``state[i]``, written by ``state.copy(list)``,
  never freed from Python (:mod:`~dexplan.planning.ompl.spaces`);
- no binding releases the GIL: PRM's checker thread must never enter Python, so
  the PRM family gets one C++ goal state and a C++ time limit
  (:mod:`~dexplan.planning.ompl.callbacks`);
- no state-sampler hook: ``StateSpace.setStateSamplerAllocator`` is not bound
  and a Python ``allocDefaultStateSampler`` override is never called, on a
  constrained space or on the ambient space inside it; only
  ``setValidStateSamplerAllocator`` (the PRM family) takes a Python sampler;
- ``Planner.params()`` is not bound, ``AORRTC`` is not registered
  (:mod:`~dexplan.planning.ompl.registry`);
- ``RNG.setSeed`` reseeds the global seed generator even after use
  (:mod:`~dexplan.planning.ompl.runtime`; determinism:
  :class:`PlanningProblem`).
"""

from __future__ import annotations

from dexplan.planning.ompl.callbacks import GoalSpec
from dexplan.planning.ompl.joint_path import plan_joint_path
from dexplan.planning.ompl.problem import PlanningProblem
from dexplan.planning.ompl.registry import (
    MULTI_QUERY_PLANNERS,
    PLANNER_NOTES,
    PLANNERS,
    UNSUPPORTED_PLANNERS,
    PlannerTraits,
    available_planners,
    check_planner,
    planner_traits,
)
from dexplan.planning.ompl.results import PathCheck, RoadmapData, SolveResult
from dexplan.planning.ompl.runtime import get_log_level, set_log_level
from dexplan.planning.ompl.spaces import ConstraintSpec, ProjectionSpec

__all__ = [
    "MULTI_QUERY_PLANNERS",
    "PLANNERS",
    "PLANNER_NOTES",
    "UNSUPPORTED_PLANNERS",
    "ConstraintSpec",
    "GoalSpec",
    "PathCheck",
    "PlannerTraits",
    "PlanningProblem",
    "ProjectionSpec",
    "RoadmapData",
    "SolveResult",
    "available_planners",
    "check_planner",
    "get_log_level",
    "plan_joint_path",
    "planner_traits",
    "set_log_level",
]
