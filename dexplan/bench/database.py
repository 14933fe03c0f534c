"""The benchmark database: SQLite in Planner Arena's schema, plus dexplan's bookkeeping.

Also the facts stored with the runs: the host's CPU, dexplan's version and a
fingerprint of the planning code (:func:`code_fingerprint`).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import platform
import socket
import sqlite3
from collections.abc import Iterable, Mapping
from datetime import datetime
from importlib import metadata
from pathlib import Path
from typing import Any, cast

from dexplan import __version__
from dexplan.bench.records import RunRecord, RunRow, jsonable
from dexplan.bench.schema import (
    IDENTITY_COLUMNS,
    OMPL_STATUSES,
    PLAN_STATUSES,
    REDUCTION_METHODS,
    RUN_COLUMNS,
    SCHEMA,
    VIEWS,
)
from dexplan.core.errors import InvalidInputError
from dexplan.model.scenario import Scenario, scenario_description

_NOT_PLANNING = frozenset({"bench", "cli", "viz"})
"""Top-level modules and packages of dexplan that no plan depends on."""


def _is_planning_source(relative: Path) -> bool:
    """Whether a source file (relative to the package) can change a plan.

    ``relative.parts[0]`` is the top-level module or package, so every file
    of the ``viz`` package (``viz/scene.py``, ...) is excluded with it.
    """
    return Path(relative.parts[0]).stem not in _NOT_PLANNING


def code_fingerprint() -> str:
    """SHA-256 (16 hex digits) of the dexplan sources a plan depends on.

    Every module but the benchmark package, the CLI and the viewer package
    ``viz``: runs with equal fingerprints ran the same planning code.
    """
    root = Path(__file__).resolve().parent.parent
    h = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        if not _is_planning_source(path.relative_to(root)):
            continue
        h.update(str(path.relative_to(root)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def _cpuinfo() -> str:
    """The CPU model and core count, as ``experiments.cpuinfo``."""
    model = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{model} ({os.cpu_count()} cores)"


def _dexplan_version() -> str:
    """The installed dexplan version (the source tree's when not installed)."""
    try:
        return metadata.version("dexplan")
    except metadata.PackageNotFoundError:
        return __version__


class BenchDatabase:
    """A benchmark database in Planner Arena's schema (plus dexplan's bookkeeping).

    Opening creates the tables that are missing and adds missing ``runs``
    columns, so an existing database (from an earlier sweep, or written by
    ``ompl_benchmark_statistics.py``) is extended, never rewritten. Every
    :meth:`add_run` is one committed transaction.

    Args:
        path: SQLite file (created if missing).
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        try:
            self.conn = sqlite3.connect(str(self.path), timeout=60.0)
        except sqlite3.Error as exc:
            raise InvalidInputError(f"cannot open database {str(self.path)!r}: {exc}") from exc
        self.conn.execute("PRAGMA foreign_keys = ON")
        try:
            self._create_schema()
        except sqlite3.DatabaseError as exc:
            self.conn.close()
            raise InvalidInputError(
                f"{str(self.path)!r} is not a usable benchmark database: {exc}"
            ) from exc

    def __enter__(self) -> BenchDatabase:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Close the connection (everything is committed already)."""
        self.conn.close()

    def _columns(self, table: str) -> list[str]:
        return [row[1] for row in self.conn.execute(f"PRAGMA table_info({table})")]

    def _create_schema(self) -> None:
        c = self.conn
        c.executescript(SCHEMA)
        have = set(self._columns("runs"))
        for name, kind in RUN_COLUMNS:
            if name not in have:
                c.execute(f"ALTER TABLE runs ADD {name} {kind}")
        if "code" not in self._columns("dexplan_runs"):  # databases of dexplan < 0.1.1
            c.execute("ALTER TABLE dexplan_runs ADD code TEXT")
        if "stage" not in self._columns("progress"):
            c.execute("ALTER TABLE progress ADD stage INTEGER")
        enums = [("status", i, d) for i, d in enumerate(OMPL_STATUSES)]
        enums += [("plan status", i, d) for i, d in enumerate(PLAN_STATUSES)]
        enums += [("reduction method", i, d) for i, d in enumerate(REDUCTION_METHODS)]
        c.executemany("INSERT OR IGNORE INTO enums VALUES (?, ?, ?)", enums)
        for name, sql in VIEWS.items():
            c.execute(f"DROP VIEW IF EXISTS {name}")
            c.execute(f"CREATE VIEW {name} AS {sql}")
        c.commit()

    def experiment_id(
        self, scenario: Scenario, digest: str, time_limit: float, runcount: int
    ) -> int:
        """The ``experiments`` row of (scenario, hash, time limit), created if missing."""
        c = self.conn
        row = c.execute(
            "SELECT experimentid FROM dexplan_experiments "
            "WHERE scenario=? AND scenario_hash=? AND time_limit=?",
            (scenario.name, digest, float(time_limit)),
        ).fetchone()
        if row is not None:
            c.execute(
                "UPDATE experiments SET runcount=MAX(COALESCE(runcount, 0), ?) WHERE id=?",
                (runcount, row[0]),
            )
            c.commit()
            return int(row[0])
        setup = json.dumps(
            {"scenario": scenario_description(scenario), "scenario_hash": digest},
            sort_keys=True,
            indent=1,
            default=str,
        )
        cur = c.execute(
            "INSERT INTO experiments (name, totaltime, timelimit, memorylimit, runcount, "
            "version, hostname, cpuinfo, date, seed, setup) VALUES (?,?,?,?,?,?,?,?,?,?,?)",
            (
                scenario.name,
                0.0,
                float(time_limit),
                0.0,
                runcount,
                f"dexplan {_dexplan_version()}",
                socket.gethostname(),
                _cpuinfo(),
                datetime.now().isoformat(timespec="seconds"),
                "per run",
                setup,
            ),
        )
        exp_id = int(cur.lastrowid or 0)
        c.execute(
            "INSERT INTO dexplan_experiments VALUES (?,?,?,?)",
            (exp_id, scenario.name, digest, float(time_limit)),
        )
        c.commit()
        return exp_id

    def planner_id(self, planner: str, scenario: Scenario) -> int:
        """The ``plannerConfigs`` row of a planner with the scenario's settings."""
        items = {"space": scenario.planner.space, **dict(scenario.planner.params)}
        settings = "".join(f"{k} = {v}\n;" for k, v in sorted(items.items()))
        name = f"geometric_{planner}"
        c = self.conn
        row = c.execute(
            "SELECT id FROM plannerConfigs WHERE name=? AND settings=?", (name, settings)
        ).fetchone()
        if row is not None:
            return int(row[0])
        cur = c.execute("INSERT INTO plannerConfigs VALUES (?,?,?)", (None, name, settings))
        c.commit()
        return int(cur.lastrowid or 0)

    def finished_keys(self) -> set[str]:
        """Resume keys of the runs already stored."""
        return {row[0] for row in self.conn.execute("SELECT key FROM dexplan_runs")}

    def add_run(self, rec: RunRecord, experiment_id: int, planner_id: int) -> int:
        """Store one run (``runs``, ``progress``, ``dexplan_runs``) in one transaction.

        Returns:
            The ``runs.id`` of the new row.
        """
        names = [name for name, _ in RUN_COLUMNS]
        columns: Mapping[str, object] = rec  # the columns by name, as SQL takes them
        values = [_sql_value(columns.get(name)) for name in names]
        c = self.conn
        with c:  # one transaction: all of it or nothing
            cur = c.execute(
                f"INSERT INTO runs (experimentid, plannerid, {', '.join(names)}) "
                f"VALUES (?, ?, {', '.join('?' * len(names))})",
                [experiment_id, planner_id, *values],
            )
            run_id = int(cur.lastrowid or 0)
            c.executemany(
                "INSERT OR IGNORE INTO progress (runid, time, stage) VALUES (?,?,?)",
                [(run_id, float(t), int(s)) for t, s in rec.get("progress") or []],
            )
            c.execute(
                "INSERT INTO dexplan_runs (runid, key, scenario, scenario_hash, planner, seed, "
                "time_limit, status, message, plan_sha256, backend, host, finished, stats_json, "
                "code) VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)",
                (
                    run_id,
                    rec["key"],
                    rec["scenario"],
                    rec["scenario_hash"],
                    rec["planner"],
                    int(rec["seed"]),
                    float(rec["time_limit"]),
                    rec.get("status_name"),
                    rec.get("message") or "",
                    rec.get("plan_sha256"),
                    rec.get("backend"),
                    rec.get("host"),
                    datetime.now().isoformat(timespec="seconds"),
                    json.dumps(jsonable(rec.get("stats") or {}), sort_keys=True),
                    rec.get("code"),
                ),
            )
            c.execute(
                "UPDATE experiments SET totaltime = COALESCE(totaltime, 0) + ? WHERE id=?",
                (float(rec.get("wall_time") or 0.0), experiment_id),
            )
        return run_id

    def records(self, keys: Iterable[str] | None = None) -> list[RunRow]:
        """Stored runs as flat records, in run order.

        A record holds :data:`~dexplan.bench.schema.CSV_COLUMNS` plus ``key``.

        Args:
            keys: resume keys to return (None: every run).
        """
        names = [name for name, _ in RUN_COLUMNS]
        sql = (
            "SELECT d.key, d.scenario, d.scenario_hash, d.planner, d.time_limit, d.status, "
            "d.message, d.plan_sha256, d.backend, d.host, d.code, "
            + ", ".join(f"r.{n}" for n in names)
            + " FROM dexplan_runs d JOIN runs r ON r.id = d.runid ORDER BY r.id"
        )
        wanted = None if keys is None else set(keys)
        fields = ("key", *IDENTITY_COLUMNS, *names)
        out: list[RunRow] = []
        for row in self.conn.execute(sql):
            if wanted is not None and row[0] not in wanted:
                continue
            out.append(cast(RunRow, dict(zip(fields, row, strict=True))))
        return out

    def counts(self) -> dict[str, int]:
        """Row counts of the Planner Arena tables and dexplan's."""
        tables = ("experiments", "plannerConfigs", "enums", "runs", "progress", "dexplan_runs")
        return {
            t: int(self.conn.execute(f"SELECT COUNT(*) FROM {t}").fetchone()[0]) for t in tables
        }


def _sql_value(value: Any) -> int | float | str | None:
    """A record value as SQLite stores it (bools as 0/1, nan and inf as NULL)."""
    if value is None:
        return None
    if isinstance(value, bool):
        return int(value)
    if hasattr(value, "item"):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None  # as ompl_benchmark_statistics.py stores nan and inf
    return value
