"""Roadmaps (paper, section V): module 1, module 2, the roadmap file, multi-query.

- :mod:`~dexplan.planning.roadmap.graph`: the :class:`~dexplan.planning.roadmap.graph.Roadmap`
  (vertices, GSn edges, module-2 links), its components and paths;
- :mod:`~dexplan.planning.roadmap.file`: the roadmap file, read and checked;
- :mod:`~dexplan.planning.roadmap.search`: a GSn query and its result;
- :mod:`~dexplan.planning.roadmap.problems`: the OMPL problems of module 1;
- :mod:`~dexplan.planning.roadmap.module1`: a single query's GSn exploration;
- :mod:`~dexplan.planning.roadmap.module2`: links between components (one link loop);
- :mod:`~dexplan.planning.roadmap.queries`: queries answered on a saved roadmap;
- :mod:`~dexplan.planning.roadmap.learning`: the learning phase (a goal-free roadmap);
- :mod:`~dexplan.planning.roadmap.tasks`: the learning phase in parallel tasks.

The submodules are not imported here: :mod:`~dexplan.planning.roadmap.graph`
and :mod:`~dexplan.planning.roadmap.file` load without OMPL.
"""

__all__ = [
    "file",
    "graph",
    "learning",
    "module1",
    "module2",
    "problems",
    "queries",
    "search",
    "tasks",
]
