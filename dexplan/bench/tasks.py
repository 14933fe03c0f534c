"""The runs of a sweep: scenarios resolved and hashed, run tasks and their resume keys.

A run is one (scenario, planner, seed, time limit). Its resume key names the
scenario by name and content hash (:func:`scenario_hash`), so a sweep run again
skips what is already stored, and an edited scenario is run afresh.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path

from dexplan.bench.schema import DEFAULT_BASELINE
from dexplan.core.errors import InvalidInputError, PlannerError, ScenarioError
from dexplan.model.scenario import (
    Scenario,
    builtin_scenario_folder,
    load_scenario,
    resolve_scenario_path,
    scenario_hash,
)
from dexplan.planning.ompl import available_planners


def resolve_scenario(arg: str | Path) -> Scenario:
    """Load a scenario from a TOML path, or a builtin scenario by name.

    Args:
        arg: a scenario file, or the name of a builtin scenario (``paper_sphere``).

    Raises:
        ScenarioError: no such file or builtin scenario, or an invalid scenario.
    """
    return load_scenario(resolve_scenario_path(arg))


@dataclass(frozen=True)
class RunTask:
    """One run of a sweep: a scenario solved by one planner with one seed.

    Attributes:
        scenario: the problem.
        scenario_hash: :func:`scenario_hash` of it.
        planner: OMPL planner name.
        seed: random seed.
        time_limit: seconds for the plan() call.
        plan_dir: folder to write the plan JSON to (None: don't).
    """

    scenario: Scenario
    scenario_hash: str
    planner: str
    seed: int
    time_limit: float
    plan_dir: str | None = None

    @property
    def key(self) -> str:
        """Resume key: scenario name and hash, planner, seed, time limit."""
        return run_key(
            self.scenario.name, self.scenario_hash, self.planner, self.seed, self.time_limit
        )


def run_key(scenario: str, digest: str, planner: str, seed: int, time_limit: float) -> str:
    """The resume key of a run (``name@hash/planner/seed/time limit``)."""
    return f"{scenario}@{digest}/{planner}/{int(seed)}/{float(time_limit)!r}"


def scenario_files(arg: str | Path) -> list[str | Path]:
    """A sweep's scenario argument: a folder gives its ``*.toml`` files (sorted by name).

    A builtin folder's name (``suite``) names that folder.

    Raises:
        ScenarioError: a folder without scenario files.
    """
    path = Path(arg)
    if not path.is_dir():
        builtin = builtin_scenario_folder(str(arg))
        if builtin is None:
            return [arg]
        path = builtin
    files = sorted(path.glob("*.toml"))
    if not files:
        raise ScenarioError(f"scenario folder {str(arg)!r} holds no .toml file")
    return list(files)


class PlannerWord(StrEnum):
    """Words of a sweep's planner list that stand for planners."""

    ALL = "all"
    """Every registered planner."""
    DEFAULT = "default"
    """Each scenario's own planner (its ``[planner] name``)."""


def parse_planners(planners: str | Sequence[str]) -> list[str]:
    """Planner names from a list or a comma-separated string, stripped, without repeats.

    ``all`` stands for every registered planner (:func:`available_planners`,
    in its order); ``default`` for each scenario's own planner.

    Raises:
        InvalidInputError: no planner name.
    """
    names = planners.split(",") if isinstance(planners, str) else list(planners)
    out: list[str] = []
    for name in (str(n).strip() for n in names):
        for one in available_planners() if name == PlannerWord.ALL else [name]:
            if one and one not in out:
                out.append(one)
    if not out:
        raise InvalidInputError(f"--planners: give at least one planner name, got {planners!r}")
    return out


def validate_sweep(
    planners: Sequence[str],
    seeds: int,
    time_limit: float | None,
    *,
    first_seed: int = 1,
    jobs: int | None = None,
    baseline: str | None = DEFAULT_BASELINE,
) -> None:
    """Check a sweep's arguments before any work.

    Raises:
        InvalidInputError: seeds < 1, first seed < 0, time limit not > 0, jobs < 1.
        PlannerError: an unknown planner or baseline.
    """
    if isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 1:
        raise InvalidInputError(f"--seeds must be an integer >= 1, got {seeds!r}")
    if isinstance(first_seed, bool) or not isinstance(first_seed, int) or first_seed < 0:
        raise InvalidInputError(f"--first-seed must be an integer >= 0, got {first_seed!r}")
    if time_limit is not None and not (
        isinstance(time_limit, int | float) and math.isfinite(time_limit) and time_limit > 0
    ):
        raise InvalidInputError(f"--time-limit must be a finite number > 0, got {time_limit!r}")
    if jobs is not None and (isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1):
        raise InvalidInputError(f"--jobs must be an integer >= 1, got {jobs!r}")
    valid = available_planners()
    for name in [*planners, *([baseline] if baseline else [])]:
        if name not in valid and name != PlannerWord.DEFAULT:
            raise PlannerError(f"unknown planner {name!r}; valid planners: {', '.join(valid)}")


def make_tasks(
    scenarios: Sequence[Scenario],
    planners: Sequence[str],
    seeds: Iterable[int],
    time_limit: float | None = None,
    plan_dir: str | Path | None = None,
) -> list[RunTask]:
    """The runs of a sweep, seed-major (a partial sweep covers every planner).

    Args:
        scenarios: problems.
        planners: planner names.
        seeds: random seeds.
        time_limit: seconds per run (None: each scenario's own).
        plan_dir: folder to write plans to (None: don't write them).
    """
    digests = [scenario_hash(s) for s in scenarios]
    out = []
    for seed in seeds:
        for scenario, digest in zip(scenarios, digests, strict=True):
            limit = float(scenario.planner.time_limit if time_limit is None else time_limit)
            for planner in scenario_planners(scenario, planners):
                out.append(
                    RunTask(
                        scenario,
                        digest,
                        planner,
                        int(seed),
                        limit,
                        None if plan_dir is None else str(plan_dir),
                    )
                )
    return out


def scenario_planners(scenario: Scenario, planners: Sequence[str]) -> list[str]:
    """The planners a scenario is run with: ``default`` is its own, without repeats."""
    out: list[str] = []
    for name in planners:
        one = scenario.planner.name if name == PlannerWord.DEFAULT else name
        if one not in out:
            out.append(one)
    return out
