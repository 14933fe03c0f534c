"""Run records: the flat dict one run produces, from a worker or from a failure.

A record has every key of :data:`~dexplan.bench.schema.CSV_COLUMNS`, plus
``key`` (the resume key), ``progress`` (``[(seconds, stage), ...]``) and
``stats`` (the planner's statistics, JSON-ready).
"""

from __future__ import annotations

import hashlib
import json
import math
import socket
from collections.abc import Mapping, Sequence
from typing import Any

from dexplan.bench.schema import CSV_COLUMNS, OMPL_STATUS_OF, PLAN_STATUSES, REDUCTION_METHODS
from dexplan.bench.tasks import RunTask
from dexplan.planning.stats import PlanStats


def empty_record(task: RunTask) -> dict[str, Any]:
    """The record of a run before it ran: its identity, unsolved, no figures."""
    rec: dict[str, Any] = dict.fromkeys(CSV_COLUMNS)
    rec.update(
        scenario=task.scenario.name,
        scenario_hash=task.scenario_hash,
        planner=task.planner,
        seed=task.seed,
        time_limit=task.time_limit,
        key=task.key,
        solved=0,
        message="",
        host=socket.gethostname(),
        progress=[],
        stats={},
    )
    return rec


def set_status(rec: dict[str, Any], status: str) -> None:
    """Set a record's status (a :data:`PLAN_STATUSES` name) and the fields it decides."""
    rec["status_name"] = status
    rec["plan_status"] = PLAN_STATUSES.index(status)
    rec["status"] = OMPL_STATUS_OF[status]
    rec["solved"] = int(status == "solved")


def failure_record(task: RunTask, status: str, message: str) -> dict[str, Any]:
    """The record of a run that produced no result (``crash``, ``killed``, ``error``)."""
    rec = empty_record(task)
    set_status(rec, status)
    rec["message"] = message
    return rec


def segments_sha256(segments: Sequence[Mapping[str, Any]]) -> str:
    """SHA-256 of a plan's segments (plan-file dicts): equal plans, equal hashes."""
    text = json.dumps(list(segments), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def fill_stats(rec: dict[str, Any], stats: PlanStats) -> None:
    """Copy the planner's statistics into a record's columns."""
    rec["time"] = stats.time_s
    rec["gsn_time"] = stats.gsn_time_s
    rec["reduction_time"] = stats.reduction_time_s
    rec["graph_states"] = stats.roadmap_nodes
    rec["graph_motions"] = stats.roadmap_edges
    for name in (
        "components",
        "graph_nodes",
        "module2_attempts",
        "module2_links",
        "geodesic_motion_edges",
        "reduction_attempts",
        "regrasps",
        "transfers",
        "waypoints",
        "object_path_m",
        "object_path_rad",
        "joint_travel_rad",
    ):
        rec[name] = getattr(stats, name)
    method = stats.reduction_method
    known = method in REDUCTION_METHODS
    rec["reduction_method"] = REDUCTION_METHODS.index(method) if known else None
    if rec["regrasps"] is not None and rec["transfers"] is not None:
        rec["solution_segments"] = int(rec["regrasps"]) + int(rec["transfers"])
    validity = stats.validity
    rec["states_checked"] = validity.get("checked")
    rec["states_valid"] = validity.get("valid")
    rejected = validity.get("rejected") or {}
    for reason in ("bounds", "joint_limits", "collision", "force_closure"):
        rec[f"rejected_{reason}"] = rejected.get(reason)
    rec["sampler_attempts"] = stats.sampler.get("attempts")
    rec["sampler_valid"] = stats.sampler.get("valid")


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
