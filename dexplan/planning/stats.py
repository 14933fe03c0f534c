"""Statistics of one query, typed: what each stage did and how long it took."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from dexplan.core.errors import DexplanError


@dataclass(frozen=True)
class PlanStats:
    """Figures of a query, for the plan file, the CLI and benchmarks.

    Times are seconds of the query's own clock (``time_s`` from the start of
    :func:`~dexplan.planning.planner.plan` to its result). ``None`` means the
    query ended before the stage that measures the field.

    Attributes:
        planner: OMPL planner name. seed: random seed. time_limit: seconds.
        time_s: the whole query (wall clock). cpu_time_s: the processor
            time of the same span (this process's; unlike ``time_s``, it
            does not grow when other jobs share the cores).
        gsn_time_s: module 1 and 2.
        reduction_time_s: the reduction to transfers and regrasps.
        verify_time_s: the final verification.
        gsn_status: how module 1 ended (``exact``, ``roadmap``, an OMPL status).
        gsn_rounds: module-1 rounds. roadmap_nodes, roadmap_edges: its size.
        components: GSn connected components; components_after_links: after
            module-2 links merged some.
        module2_attempts, module2_links, module2_time_s: module 2's work.
        module2_waypoints: RLG states module 2 added as vertices when it had
            no link to try (an obstacle blocking every straight move).
        geodesic_motion_attempts, geodesic_motion_edges: module 1's section
            VI motions (meshes, PRM family) tried where OMPL's motion failed,
            and the roadmap edges they joined.
        goal_samples: valid states the goal sampler returned.
        reduction_method: ``gaits`` or ``edges`` (the one that made the plan).
        reduction_attempts: reduction attempts made (of the last GSn path).
        reduction_from_link: the plan's transfers and regrasps are those of the
            module-2 link that reached the goal along the same trajectory
            (reused, not reduced again).
        explorations: GSn paths module 1 found and the reductions tried
            (more than 1 when every reduction of a path failed early; see
            :data:`~dexplan.planning.planner.EXPLORE_AGAIN`).
        object_poses_shortcut: poses of the shortcut object trajectory.
        transfers, regrasps: segments of the plan. graph_nodes: segments + 1.
        waypoints: waypoints of the plan.
        object_path_m, object_path_rad: length of the object's path.
        joint_travel_rad: the hand joints' total travel (sum over waypoints
            and joints of the absolute change, rad).
        local: counters of the local planners (transfers tried, landings checked...).
        sampler: the sampler's counters. validity: the validity checker's counters.
    """

    planner: str
    seed: int
    time_limit: float
    time_s: float = 0.0
    cpu_time_s: float | None = None
    gsn_time_s: float | None = None
    reduction_time_s: float | None = None
    verify_time_s: float | None = None
    gsn_status: str | None = None
    gsn_rounds: int | None = None
    roadmap_nodes: int | None = None
    roadmap_edges: int | None = None
    components: int | None = None
    components_after_links: int | None = None
    module2_attempts: int = 0
    module2_links: int = 0
    module2_time_s: float = 0.0
    module2_waypoints: int = 0
    geodesic_motion_attempts: int = 0
    geodesic_motion_edges: int = 0
    goal_samples: int | None = None
    reduction_method: str | None = None
    reduction_attempts: int | None = None
    reduction_from_link: bool = False
    explorations: int | None = None
    object_poses_shortcut: int | None = None
    transfers: int | None = None
    regrasps: int | None = None
    graph_nodes: int | None = None
    waypoints: int | None = None
    object_path_m: float | None = None
    object_path_rad: float | None = None
    joint_travel_rad: float | None = None
    local: Mapping[str, int] = field(default_factory=dict)
    sampler: Mapping[str, Any] = field(default_factory=dict)
    validity: Mapping[str, Any] = field(default_factory=dict)

    @classmethod
    def from_mapping(cls, figures: Mapping[str, Any]) -> PlanStats:
        """Build from the planner's running tally (``local_*`` keys go to ``local``).

        Raises:
            DexplanError: a figure with no field (a planner bug, not bad input).
        """
        names = {f.name for f in dataclasses.fields(cls)}
        known = {k: v for k, v in figures.items() if k in names}
        local = {k[len("local_") :]: v for k, v in figures.items() if k.startswith("local_")}
        extra = sorted(set(figures) - set(known) - {f"local_{k}" for k in local})
        if extra:
            raise DexplanError(f"PlanStats has no field for {extra}")
        return cls(**known, local={**known.get("local", {}), **local})

    def as_dict(self) -> dict[str, Any]:
        """The plan file's ``stats`` object (``local`` flattened to ``local_*``)."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        out.pop("local")
        out.update({f"local_{k}": v for k, v in self.local.items()})
        out["sampler"], out["validity"] = dict(self.sampler), dict(self.validity)
        return {k: v for k, v in out.items() if v is not None}
