"""Run records: what one run produces, from a worker or from a failure.

A record is a :class:`~typing.TypedDict`: typed for the code that fills and
reads it, and a plain dict for what it crosses on its way (the worker's pipe,
Ray, SQLite, the CSV writer), so the database and CSV columns are its keys.
:class:`RunRow` is what the database gives back (every column of
:data:`~dexplan.bench.schema.CSV_COLUMNS` plus the resume key);
:class:`RunRecord`, what a run returns, adds its progress and the planner's
statistics.
"""

from __future__ import annotations

import hashlib
import json
import math
import socket
from collections.abc import Mapping, Sequence
from dataclasses import fields
from typing import Any, TypedDict, cast

from dexplan.bench.schema import (
    CSV_COLUMNS,
    OMPL_STATUS_OF,
    PLAN_STATUSES,
    QUALITY_COLUMNS,
    REDUCTION_METHODS,
    RunStatus,
)
from dexplan.bench.tasks import RunTask
from dexplan.execution.quality import PlanQuality
from dexplan.planning.stats import PlanStats


class RunRow(TypedDict):
    """One stored run: the resume key, then the columns of ``runs.csv``.

    Figures a run did not produce are None (an empty CSV cell, SQL NULL).
    The columns are described with :data:`~dexplan.bench.schema.RUN_COLUMNS`
    and :data:`~dexplan.bench.schema.IDENTITY_COLUMNS`.
    """

    key: str
    # identity (dexplan_runs)
    scenario: str
    scenario_hash: str
    planner: str
    time_limit: float
    status_name: str | None
    message: str
    plan_sha256: str | None
    backend: str | None
    host: str | None
    code: str | None
    # OMPL Benchmark's columns
    time: float | None
    memory: float | None
    status: int | None
    solved: int
    correct_solution: int | None
    graph_states: int | None
    graph_motions: int | None
    solution_segments: int | None
    # dexplan's columns
    seed: int
    plan_status: int | None
    cpu_time: float | None
    gsn_time: float | None
    reduction_time: float | None
    verify_time: float | None
    verify_violations: int | None
    plan_verify_ratio: float | None
    components: int | None
    graph_nodes: int | None
    module2_attempts: int | None
    module2_links: int | None
    geodesic_motion_edges: int | None
    reduction_attempts: int | None
    reduction_method: int | None
    regrasps: int | None
    transfers: int | None
    waypoints: int | None
    object_path_m: float | None
    object_path_rad: float | None
    joint_travel_rad: float | None
    execution_time_s: float | None
    rotation_per_transfer_deg_median: float | None
    rotation_per_transfer_deg_min: float | None
    rotation_per_transfer_deg_max: float | None
    regrasps_without_progress: int | None
    weakest_hold: float | None
    worst_torque_ratio: float | None
    max_grip_force_n: float | None
    quality_time: float | None
    states_checked: int | None
    states_valid: int | None
    rejected_bounds: int | None
    rejected_joint_limits: int | None
    rejected_collision: int | None
    rejected_force_closure: int | None
    sampler_attempts: int | None
    sampler_valid: int | None
    wall_time: float | None


class RunRecord(RunRow):
    """What one run returns: a :class:`RunRow` with its progress and statistics.

    Attributes:
        progress: ``[(seconds, stage), ...]``, stage a
            :class:`dexplan.planning.progress.Stage` value.
        stats: the planner's statistics (:meth:`PlanStats.as_dict`, JSON-ready).
    """

    progress: list[tuple[float, int]]
    stats: dict[str, Any]


# the record types and the schema's columns must name the same fields
assert set(RunRow.__annotations__) == {"key", *CSV_COLUMNS}, "RunRow out of step with the schema"
assert set(QUALITY_COLUMNS) <= {f.name for f in fields(PlanQuality)}, "no PlanQuality field"


def empty_record(task: RunTask) -> RunRecord:
    """The record of a run before it ran: its identity, unsolved, no figures."""
    rec = cast(RunRecord, dict.fromkeys(CSV_COLUMNS))  # every figure None until a run sets it
    rec["scenario"] = task.scenario.name
    rec["scenario_hash"] = task.scenario_hash
    rec["planner"] = task.planner
    rec["seed"] = task.seed
    rec["time_limit"] = task.time_limit
    rec["key"] = task.key
    rec["solved"] = 0
    rec["message"] = ""
    rec["host"] = socket.gethostname()
    rec["progress"] = []
    rec["stats"] = {}
    return rec


def set_status(rec: RunRecord, status: RunStatus | str) -> None:
    """Set a record's status (a :class:`RunStatus`) and the fields it decides."""
    status = RunStatus(status)
    rec["status_name"] = status
    rec["plan_status"] = PLAN_STATUSES.index(status)
    rec["status"] = OMPL_STATUS_OF[status]
    rec["solved"] = int(status == RunStatus.SOLVED)


def failure_record(task: RunTask, status: RunStatus, message: str) -> RunRecord:
    """The record of a run that produced no result (``crash``, ``killed``, ``error``)."""
    rec = empty_record(task)
    set_status(rec, status)
    rec["message"] = message
    return rec


def segments_sha256(segments: Sequence[Mapping[str, Any]]) -> str:
    """SHA-256 of a plan's segments (plan-file dicts): equal plans, equal hashes."""
    text = json.dumps(list(segments), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def fill_stats(rec: RunRecord, stats: PlanStats) -> None:
    """Copy the planner's statistics into a record's columns."""
    rec["time"] = stats.time_s
    rec["cpu_time"] = stats.cpu_time_s
    rec["gsn_time"] = stats.gsn_time_s
    rec["reduction_time"] = stats.reduction_time_s
    rec["graph_states"] = stats.roadmap_nodes
    rec["graph_motions"] = stats.roadmap_edges
    rec["components"] = stats.components
    rec["graph_nodes"] = stats.graph_nodes
    rec["module2_attempts"] = stats.module2_attempts
    rec["module2_links"] = stats.module2_links
    rec["geodesic_motion_edges"] = stats.geodesic_motion_edges
    rec["reduction_attempts"] = stats.reduction_attempts
    rec["regrasps"] = stats.regrasps
    rec["transfers"] = stats.transfers
    rec["waypoints"] = stats.waypoints
    rec["object_path_m"] = stats.object_path_m
    rec["object_path_rad"] = stats.object_path_rad
    rec["joint_travel_rad"] = stats.joint_travel_rad
    method = stats.reduction_method
    known = method in REDUCTION_METHODS
    rec["reduction_method"] = REDUCTION_METHODS.index(method) if known else None
    if rec["regrasps"] is not None and rec["transfers"] is not None:
        rec["solution_segments"] = int(rec["regrasps"]) + int(rec["transfers"])
    validity = stats.validity
    rec["states_checked"] = validity.get("checked")
    rec["states_valid"] = validity.get("valid")
    rejected = validity.get("rejected") or {}
    rec["rejected_bounds"] = rejected.get("bounds")
    rec["rejected_joint_limits"] = rejected.get("joint_limits")
    rec["rejected_collision"] = rejected.get("collision")
    rec["rejected_force_closure"] = rejected.get("force_closure")
    rec["sampler_attempts"] = stats.sampler.get("attempts")
    rec["sampler_valid"] = stats.sampler.get("valid")


def fill_quality(rec: RunRecord, quality: PlanQuality, time_s: float | None) -> None:
    """Copy a plan's quality figures into a record's columns (and its ``stats``)."""
    table = quality.as_dict()  # non-finite figures as None, as the database stores them
    columns = cast("dict[str, Any]", rec)  # the columns by name
    for name in QUALITY_COLUMNS:
        columns[name] = table[name]
    rec["quality_time"] = time_s
    rec["stats"]["quality"] = jsonable({**table, "time_s": time_s})


def jsonable(value: Any) -> Any:
    """A JSON-ready copy of a value (numpy scalars and arrays as Python, nan/inf as None)."""
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    if hasattr(value, "item") and not hasattr(value, "__len__"):
        return value.item()
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
