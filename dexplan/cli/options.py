"""The options of each command, read once from argparse into frozen dataclasses.

The parser (:mod:`dexplan.cli.main`) makes an ``argparse.Namespace``; the
dispatcher turns it into the command's options here, at the boundary, and the
command modules (:mod:`dexplan.cli.commands`) take only these typed records.
This module imports nothing heavy: ``dexplan --help`` reads the choices below.
"""

from __future__ import annotations

import argparse
import math
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

from dexplan.core.errors import InvalidInputError

__all__ = [
    "BenchOptions",
    "ExportOptions",
    "GoalKind",
    "InfoOptions",
    "PlanOptions",
    "PlannersOptions",
    "Reduction",
    "ReplayLoops",
    "ReplayOptions",
    "RoadmapBuildOptions",
    "RoadmapInfoOptions",
    "ScenariosOptions",
    "ShowOptions",
    "StartMethod",
    "VerifyOptions",
    "parse_params",
]


class Reduction(StrEnum):
    """``plan --reduction``: how a GSn path becomes transfers and regrasps.

    The planner's own list (``dexplan.planning.planner.REDUCTIONS``); repeated
    here because importing the planner would load OMPL and Pinocchio for
    ``dexplan --help``.
    """

    AUTO = "auto"
    GAITS = "gaits"
    EDGES = "edges"


class GoalKind(StrEnum):
    """``plan --goal-kind``: what ``--random-goals`` draws.

    The goals' own list (``dexplan.model.scenario.goals.GoalKind``); repeated
    here because importing the scenario package would load SciPy and the
    grasp model for ``dexplan --help``.
    """

    ORIENTATION = "orientation"
    POSE = "pose"


class StartMethod(StrEnum):
    """``bench --start-method``: how the local pool starts its worker processes.

    The sweep's own list (``dexplan.bench.schema.StartMethod``); repeated here
    because importing :mod:`dexplan.bench` would load the planner for
    ``dexplan --help``.
    """

    FORKSERVER = "forkserver"
    SPAWN = "spawn"


def parse_params(items: Sequence[str] | None) -> tuple[tuple[str, Any], ...]:
    """``--param NAME=VALUE`` options as ``(name, value)`` pairs, values read as TOML scalars.

    ``range=0.1`` gives 0.1, ``intermediate_states=true`` True, ``num_samples=500``
    500; a value TOML does not read as a number or boolean stays text (OMPL's
    parameter check then says what it must be). A later NAME replaces an earlier one.

    Raises:
        InvalidInputError: an item without ``=`` or without a name.
    """
    out: dict[str, Any] = {}
    for item in items or ():
        name, sep, text = item.partition("=")
        name, text = name.strip(), text.strip()
        if not sep or not name or not text:
            raise InvalidInputError(f"--param must be NAME=VALUE, got {item!r}")
        try:
            value: Any = tomllib.loads(f"v = {text}")["v"]
        except tomllib.TOMLDecodeError:
            value = text
        if isinstance(value, float) and not math.isfinite(value):
            raise InvalidInputError(f"--param {name} must be finite, got {text!r}")
        if not isinstance(value, bool | int | float | str):
            value = text  # an array or table: OMPL parameters are scalars
        out[name] = value
    return tuple(out.items())


@dataclass(frozen=True)
class PlannersOptions:
    """``dexplan planners``: all registered planners, or the named ones."""

    names: tuple[str, ...]

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> PlannersOptions:
        """The options of a parsed ``planners`` command line."""
        return cls(names=tuple(args.names))


@dataclass(frozen=True)
class InfoOptions:
    """``dexplan info``: the hand to describe (builtin name, scenario or URDF file)."""

    hand: str

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> InfoOptions:
        """The options of a parsed ``info`` command line."""
        return cls(hand=args.hand)


@dataclass(frozen=True)
class ScenariosOptions:
    """``dexplan scenarios``: no options (it lists the builtin scenarios)."""

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> ScenariosOptions:
        """The options of a parsed ``scenarios`` command line."""
        return cls()


@dataclass(frozen=True)
class PlanOptions:
    """``dexplan plan``: one query, or many goals (``--goals``, ``--random-goals``).

    Attributes:
        scenario: scenario TOML (None: the paper's sphere).
        planner, seed, time_limit: overrides of the scenario's (None: its own).
        output: plan file, or with many goals their folder (None: the default).
        save_roadmap, load_roadmap: roadmap ``.npz`` files.
        reduction: GSn path to transfers and regrasps.
        rrd, debug_rrd: Rerun recordings of the plan and of the rejected states.
        quiet: no progress on stderr.
        goals: a TOML file of goals; random_goals: how many to draw instead.
        goal_kind: what random goals vary.
        params: ``--param`` planner parameters, over the scenario's ``[planner] params``.
    """

    scenario: str | None
    planner: str | None
    seed: int | None
    time_limit: float | None
    output: str | None
    save_roadmap: str | None
    load_roadmap: str | None
    reduction: Reduction
    rrd: str | None
    debug_rrd: str | None
    quiet: bool
    goals: str | None
    random_goals: int | None
    goal_kind: GoalKind
    params: tuple[tuple[str, Any], ...] = ()

    @property
    def many_goals(self) -> bool:
        """Whether ``plan`` answers several queries."""
        return self.goals is not None or self.random_goals is not None

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> PlanOptions:
        """The options of a parsed ``plan`` command line."""
        return cls(
            scenario=args.scenario,
            planner=args.planner,
            seed=args.seed,
            time_limit=args.time_limit,
            output=args.output,
            save_roadmap=args.save_roadmap,
            load_roadmap=args.load_roadmap,
            reduction=Reduction(args.reduction),
            rrd=args.rrd,
            debug_rrd=args.debug_rrd,
            quiet=args.quiet,
            goals=args.goals,
            random_goals=args.random_goals,
            goal_kind=GoalKind(args.goal_kind),
            params=parse_params(args.param),
        )


@dataclass(frozen=True)
class RoadmapBuildOptions:
    """``dexplan roadmap build``: the learning phase's settings and output.

    Attributes:
        scenario: scenario TOML (None: the paper's sphere).
        time, nodes: the budget, seconds or module-1 nodes (exactly one is set).
        planner, seed: OMPL roadmap planner and random seed.
        link_attempts: most module-2 link attempts (None: the default).
        jobs, ray: local processes, or a Ray cluster address, for a build in tasks.
        output: roadmap file (.npz).
        quiet: no progress on stderr.
    """

    scenario: str | None
    time: float | None
    nodes: int | None
    planner: str
    seed: int
    link_attempts: int | None
    jobs: int | None
    ray: str | None
    output: str
    quiet: bool

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> RoadmapBuildOptions:
        """The options of a parsed ``roadmap build`` command line."""
        return cls(
            scenario=args.scenario,
            time=args.time,
            nodes=args.nodes,
            planner=args.planner,
            seed=args.seed,
            link_attempts=args.link_attempts,
            jobs=args.jobs,
            ray=args.ray,
            output=args.output,
            quiet=args.quiet,
        )


@dataclass(frozen=True)
class RoadmapInfoOptions:
    """``dexplan roadmap info``: the roadmap file to describe."""

    roadmap: str

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> RoadmapInfoOptions:
        """The options of a parsed ``roadmap info`` command line."""
        return cls(roadmap=args.roadmap)


@dataclass(frozen=True)
class VerifyOptions:
    """``dexplan verify``: the plan file, and how many violations to print."""

    plan: str
    max_violations: int
    #: ``--package-dir``: folders ``package://`` mesh URIs resolve in first
    package_dirs: tuple[str, ...] = ()

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> VerifyOptions:
        """The options of a parsed ``verify`` command line."""
        return cls(
            plan=args.plan,
            max_violations=args.max_violations,
            package_dirs=tuple(args.package_dirs),
        )


@dataclass(frozen=True)
class BenchOptions:
    """``dexplan bench``: the sweep (see :func:`dexplan.bench.run_benchmark`).

    Attributes:
        scenarios: scenario files, folders of them, or builtin names.
        planners: comma-separated planner names, ``all`` or ``default``.
        seeds, first_seed: seeds per planner and the first one.
        time_limit: seconds per run (None: each scenario's).
        jobs, ray: parallel runs, or a Ray cluster address.
        output: output folder.
        baseline: planner compared with (None: no ratios).
        plots, save_plans: write PNG plots; write every plan.
        start_method: how local worker processes start.
        run_timeout: hard wall-clock seconds per run (None: the default).
        quiet: no progress on stderr.
        params: ``--param`` planner parameters, for every planner of the sweep.
    """

    scenarios: tuple[str, ...]
    planners: str
    seeds: int
    first_seed: int
    time_limit: float | None
    jobs: int | None
    ray: str | None
    output: str
    baseline: str | None
    plots: bool
    save_plans: bool
    start_method: StartMethod
    run_timeout: float | None
    quiet: bool
    params: tuple[tuple[str, Any], ...] = ()

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> BenchOptions:
        """The options of a parsed ``bench`` command line (``--baseline none``: None)."""
        return cls(
            scenarios=tuple(args.scenarios),
            planners=args.planners,
            seeds=args.seeds,
            first_seed=args.first_seed,
            time_limit=args.time_limit,
            jobs=args.jobs,
            ray=args.ray,
            output=args.output,
            baseline=None if args.baseline.lower() == "none" else args.baseline,
            plots=not args.no_plots,
            save_plans=args.save_plans,
            start_method=StartMethod(args.start_method),
            run_timeout=args.run_timeout,
            quiet=args.quiet,
            params=parse_params(args.param),
        )


@dataclass(frozen=True)
class ShowOptions:
    """``dexplan show``: what to show, and where to save it instead (None: open it)."""

    source: str
    save: str | None
    roadmap: str | None
    plan: str | None
    #: ``--package-dir``: folders ``package://`` mesh URIs resolve in first
    package_dirs: tuple[str, ...] = ()

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> ShowOptions:
        """The options of a parsed ``show`` command line."""
        return cls(
            source=args.source,
            save=args.save,
            roadmap=args.roadmap,
            plan=args.plan,
            package_dirs=tuple(args.package_dirs),
        )


@dataclass(frozen=True)
class ExportOptions:
    """``dexplan export``: the plan, the trajectory file and what overrides the plan's.

    Attributes:
        plan: plan JSON file.
        output: trajectory file (.json or .csv).
        rate: samples per second.
        mass: object mass, kg (None: the plan's).
        gravity: gravity (3,), m/s^2, world frame (None: the plan's).
        max_object_speed, max_object_angular_speed, max_acceleration: timing
            limits, m/s, rad/s and rad/s^2 (None: the defaults).
        package_dirs: ``--package-dir``: folders ``package://`` mesh URIs resolve in first.
    """

    plan: str
    output: str
    rate: float
    mass: float | None
    gravity: tuple[float, float, float] | None
    max_object_speed: float | None
    max_object_angular_speed: float | None
    max_acceleration: float | None
    package_dirs: tuple[str, ...] = ()

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> ExportOptions:
        """The options of a parsed ``export`` command line."""
        g = args.gravity
        return cls(
            plan=args.plan,
            output=args.output,
            rate=args.rate,
            mass=args.mass,
            gravity=None if g is None else (g[0], g[1], g[2]),
            max_object_speed=args.max_object_speed,
            max_object_angular_speed=args.max_object_angular_speed,
            max_acceleration=args.max_acceleration,
            package_dirs=tuple(args.package_dirs),
        )


class ReplayLoops(StrEnum):
    """``replay --loop``: which loops to replay (``dexplan.execution.replay.result.Loop``).

    Repeated here because importing the replay would load Pinocchio for
    ``dexplan --help``.
    """

    BOTH = "both"
    CLOSED = "closed"
    OPEN = "open"


@dataclass(frozen=True)
class ReplayOptions:
    """``dexplan replay``: the plan, the physics settings and an optional recording."""

    plan: str
    gravity: bool
    rate: float
    loops: ReplayLoops
    rrd: str | None
    #: ``--package-dir``: folders ``package://`` mesh URIs resolve in first
    package_dirs: tuple[str, ...] = ()

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> ReplayOptions:
        """The options of a parsed ``replay`` command line (``--open-loop`` is ``--loop open``)."""
        return cls(
            plan=args.plan,
            gravity=args.gravity,
            rate=args.rate,
            loops=ReplayLoops.OPEN if args.open_loop else ReplayLoops(args.loop),
            rrd=args.rrd,
            package_dirs=tuple(args.package_dirs),
        )
