"""Backends that run a sweep's tasks, each in a fresh process: a local pool, or Ray.

The local pool starts one process per run (``forkserver`` by default, with the
planning modules preloaded; ``spawn`` on request), at most ``jobs`` at a time.
On a Ray cluster (``"local"`` starts one in-process) each run is a Ray task in
a fresh worker process too (``max_calls=1``), so a seed gives the same plan
whichever backend ran it, for the planners that are deterministic. Either
way a run that overruns its hard wall-clock limit is killed and recorded as
``killed``, and a worker that dies as ``crash``.
"""

from __future__ import annotations

import multiprocessing
import os
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection
from multiprocessing.connection import wait as wait_connections
from multiprocessing.context import ForkServerContext, SpawnContext
from multiprocessing.process import BaseProcess
from types import ModuleType
from typing import Any, Protocol, TypeVar

from dexplan.bench.records import RunRecord, failure_record
from dexplan.bench.schema import RunStatus, StartMethod
from dexplan.bench.tasks import RunTask
from dexplan.bench.worker import PRELOAD, child_main, execute_run
from dexplan.core.errors import InvalidInputError
from dexplan.core.ray_cluster import RayAddressKind, check_listening, join_ray, parse_ray_address


@dataclass(frozen=True)
class BenchProgress:
    """What a sweep reports to its progress callback after each finished run.

    Attributes:
        done: runs finished in this call (new runs only).
        total: runs to do in this call (finished ones excluded).
        skipped: runs already in the database, not run again.
        record: the record of the run that just finished (None for the first call).
    """

    done: int
    total: int
    skipped: int
    record: RunRecord | None = None


ProgressCallback = Callable[[BenchProgress], None]
OnResult = Callable[[RunTask, RunRecord], None]
"""Called with each finished run's task and record, in the order they finish."""


def default_run_timeout(time_limit: float) -> float:
    """Hard wall-clock limit of one run: planning, verification and process start-up."""
    return max(3.0 * time_limit, time_limit + 120.0)


@dataclass(frozen=True)
class _Job:
    """A run in flight: its task and when it started (``time.monotonic``)."""

    task: RunTask
    started: float


Handle = TypeVar("Handle")
"""What a backend knows a run in flight by (a pipe, a Ray object reference)."""


class _Backend(Protocol[Handle]):
    """Starts runs, says which have finished, collects their records, kills overruns."""

    def start(self, task: RunTask) -> Handle: ...

    def ready(self, handles: list[Handle]) -> list[Handle]: ...

    def collect(self, handle: Handle, task: RunTask) -> RunRecord: ...

    def kill(self, handle: Handle) -> None: ...


def _drive(
    tasks: Sequence[RunTask],
    window: int,
    on_result: OnResult,
    run_timeout: Callable[[RunTask], float],
    backend: _Backend[Handle],
) -> None:
    """Keep ``window`` runs in flight until all are done; kill those that overrun."""
    pending = deque(tasks)
    active: dict[Handle, _Job] = {}
    while pending or active:
        while pending and len(active) < window:
            task = pending.popleft()
            active[backend.start(task)] = _Job(task, time.monotonic())
        for handle in backend.ready(list(active)):
            job = active.pop(handle)
            on_result(job.task, backend.collect(handle, job.task))
        now = time.monotonic()
        for handle, job in list(active.items()):
            limit = run_timeout(job.task)
            if now - job.started > limit:
                backend.kill(handle)
                del active[handle]
                message = f"run exceeded {limit:.0f} s wall clock"
                on_result(job.task, failure_record(job.task, RunStatus.KILLED, message))


# ------------------------------------------------------------------ local processes


def _mp_context(start_method: StartMethod | str) -> ForkServerContext | SpawnContext:
    """The multiprocessing context of a start method, its fork server preloaded.

    Raises:
        InvalidInputError: not ``forkserver`` or ``spawn``.
    """
    if start_method not in tuple(StartMethod):
        raise InvalidInputError(
            f"start method must be 'forkserver' or 'spawn', got {start_method!r}"
        )
    # Python 3.11's fork server starts with `python -c` and keeps the working
    # folder first on sys.path (it ignores the parent's path): a folder named
    # `dexplan` there would shadow the installed package in every worker
    os.environ.setdefault("PYTHONSAFEPATH", "1")
    if start_method == StartMethod.SPAWN:
        return multiprocessing.get_context("spawn")
    ctx = multiprocessing.get_context("forkserver")
    # imports happen once in the server; every run still forks a fresh process
    ctx.set_forkserver_preload(list(PRELOAD))
    return ctx


class _ProcessPool:
    """One process per run, its record sent back through a pipe (the handle)."""

    def __init__(self, ctx: ForkServerContext | SpawnContext) -> None:
        self.ctx = ctx
        self.procs: dict[Connection, BaseProcess] = {}

    def start(self, task: RunTask) -> Connection:
        recv, send = self.ctx.Pipe(duplex=False)
        proc = self.ctx.Process(target=child_main, args=(task, send), daemon=True)
        proc.start()
        send.close()
        self.procs[recv] = proc
        return recv

    def ready(self, handles: list[Connection]) -> list[Connection]:
        return [c for c in wait_connections(handles, timeout=0.5) if isinstance(c, Connection)]

    def collect(self, handle: Connection, task: RunTask) -> RunRecord:
        proc = self.procs.pop(handle)
        try:
            rec = handle.recv()
        except (EOFError, OSError):
            proc.join(5.0)
            message = f"worker process died (exit code {proc.exitcode})"
            rec = failure_record(task, RunStatus.CRASH, message)
        handle.close()
        proc.join(10.0)
        if proc.is_alive():
            proc.kill()
            proc.join()
        return rec

    def kill(self, handle: Connection) -> None:
        proc = self.procs.pop(handle)
        proc.kill()
        proc.join()
        handle.close()

    def kill_all(self) -> None:
        """Kill the runs still in flight (a sweep stopped by an exception)."""
        for handle in list(self.procs):
            self.kill(handle)


def run_local(
    tasks: Sequence[RunTask],
    jobs: int,
    on_result: OnResult,
    *,
    start_method: StartMethod | str,
    run_timeout: Callable[[RunTask], float],
) -> None:
    """Run each task in its own process, at most ``jobs`` at a time.

    Args:
        tasks: the runs.
        jobs: processes at a time.
        on_result: called with each finished run's task and record.
        start_method: ``forkserver`` or ``spawn``.
        run_timeout: hard wall-clock seconds of a task before it is killed.

    Raises:
        InvalidInputError: an unknown start method.
    """
    pool = _ProcessPool(_mp_context(start_method))
    try:
        _drive(tasks, jobs, on_result, run_timeout, pool)
    finally:
        pool.kill_all()


# ------------------------------------------------------------------ Ray


def check_ray_address(address: str) -> None:
    """Check ``--ray``'s form, and that a cluster answers at ``HOST:PORT``, before any work.

    Raises:
        InvalidInputError: a form Ray does not accept, or nothing listening there.
    """
    addr = parse_ray_address(address)
    if addr.kind in (RayAddressKind.GCS, RayAddressKind.CLIENT):
        check_listening(addr)


class _RayTasks:
    """One Ray task per run, in a fresh worker process (``max_calls=1``).

    Its handles are Ray object references, untyped as Ray itself.
    """

    def __init__(self, ray: ModuleType) -> None:
        self.ray = ray
        self.remote = ray.remote(num_cpus=1, max_calls=1, max_retries=0)(execute_run)

    def start(self, task: RunTask) -> Any:
        return self.remote.remote(task)

    def ready(self, handles: list[Any]) -> list[Any]:
        ready, _ = self.ray.wait(handles, num_returns=1, timeout=0.5)
        return list(ready)

    def collect(self, handle: Any, task: RunTask) -> RunRecord:
        try:
            rec: RunRecord = self.ray.get(handle)
        except Exception as exc:  # worker died or the task was lost
            return failure_record(task, RunStatus.CRASH, f"Ray task failed: {type(exc).__name__}")
        return rec

    def kill(self, handle: Any) -> None:
        self.ray.cancel(handle, force=True)


def run_ray(
    tasks: Sequence[RunTask],
    address: str,
    jobs: int | None,
    on_result: OnResult,
    *,
    run_timeout: Callable[[RunTask], float],
) -> None:
    """Run each task as a Ray task in a fresh worker process (``max_calls=1``).

    Args:
        tasks: the runs.
        address: the cluster (``"local"``: start one in-process).
        jobs: runs at a time (None: the cluster's CPUs).
        on_result: called with each finished run's task and record.
        run_timeout: hard wall-clock seconds of a task before it is cancelled.

    Raises:
        DependencyError: Ray is not installed.
        InvalidInputError: no cluster can be started or joined.
    """
    ray, started_here = join_ray(address, num_cpus=jobs)
    try:
        window = jobs or max(1, int(ray.cluster_resources().get("CPU", 1)))
        _drive(tasks, window, on_result, run_timeout, _RayTasks(ray))
    finally:
        if started_here:
            ray.shutdown()
