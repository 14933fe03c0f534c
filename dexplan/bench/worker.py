"""One run, in a worker process of its own: plan, read the verifier's verdict, return a record.

A solved run's record also holds the plan's quality figures
(:mod:`dexplan.execution.quality`), computed after the query: its ``time``
leaves them out, its ``wall_time`` counts them (``quality_time``).

Each run gets a fresh process (OMPL's random generator is process-global and
PRM solves with two threads, so runs that share a process are neither
independent nor reproducible). The fork server imports this module and the
planner once (:data:`PRELOAD`), so every forked run starts with them loaded.
"""

from __future__ import annotations

import os
import resource
import signal
import time
from multiprocessing.connection import Connection
from pathlib import Path

from dexplan.api import plan
from dexplan.bench.records import (
    RunRecord,
    empty_record,
    fill_quality,
    fill_stats,
    jsonable,
    segments_sha256,
    set_status,
)
from dexplan.bench.schema import PLAN_STATUSES, RunStatus
from dexplan.bench.tasks import RunTask
from dexplan.planning.progress import ProgressEvent, Stage

PRELOAD: tuple[str, ...] = (__name__, "dexplan.planning.planner")
"""Modules a fork server imports once, before it forks the workers."""


def execute_run(task: RunTask) -> RunRecord:
    """Plan one run, time ``dexplan verify`` on its plan, and return its record.

    Meant to run in a fresh process (see the module docstring). Never raises:
    an exception becomes a record with status ``error``.

    Returns:
        The run's record.
    """
    t_wall = time.perf_counter()
    rec = empty_record(task)
    events: list[tuple[float, int]] = [(0.0, 0)]
    try:
        t0 = time.perf_counter()

        def on_event(event: ProgressEvent) -> None:
            events.append((time.perf_counter() - t0, int(event.stage)))

        # the planner runs the plan-file verifier itself (once): a plan that
        # fails it comes back as invalid_plan, with its violations
        planned = plan(
            task.scenario,
            planner=task.planner,
            seed=task.seed,
            time_limit=task.time_limit,
            progress=on_event,
        )
        result = planned.result
        stats = result.stats
        rec["stats"] = jsonable(stats.as_dict())
        rec["message"] = result.message
        fill_stats(rec, stats)
        known = result.status in PLAN_STATUSES
        set_status(rec, RunStatus(result.status) if known else RunStatus.ERROR)
        if result.solved or result.violations:
            rec["verify_time"] = stats.verify_time_s
            rec["correct_solution"] = int(result.solved)
            rec["verify_violations"] = len(result.violations)
            verify_time, plan_time = rec["verify_time"], rec["time"]
            if verify_time and plan_time is not None:
                rec["plan_verify_ratio"] = plan_time / verify_time
        if planned.quality is not None:  # solved: the quality figures, after the query
            fill_quality(rec, planned.quality, planned.quality_time_s)
        if result.solved:
            base = task.scenario.base_dir
            rec["plan_sha256"] = segments_sha256(planned.to_document(base)["segments"])
            if task.plan_dir is not None:
                name = f"{task.scenario.name}_{task.planner}_seed{task.seed}.json"
                planned.save(Path(task.plan_dir) / name)
        events.append((time.perf_counter() - t0, int(Stage.DONE)))
    except Exception as exc:  # a run that raises is a data point, not the end of a sweep
        set_status(rec, RunStatus.ERROR)
        rec["message"] = f"{type(exc).__name__}: {exc}"
    rec["memory"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    rec["wall_time"] = time.perf_counter() - t_wall
    rec["progress"] = events
    return rec


def child_main(task: RunTask, conn: Connection) -> None:
    """Worker process entry: run, send the record, exit without interpreter teardown."""
    # Ctrl-C reaches the whole process group: the parent stops the sweep and kills
    # the workers; a worker must not turn it into a failed run of its own
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        rec = execute_run(task)
        conn.send(rec)
        conn.close()
    finally:
        # nanobind (ompl) reports "leaked instances" at interpreter exit; skip it
        os._exit(0)
