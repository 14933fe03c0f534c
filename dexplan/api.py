"""The Python front door: plan a scenario, save the plan, verify plan files.

Everything a script needs, re-exported by ``dexplan`` itself::

    import dexplan

    p = dexplan.plan("scenarios/paper_sphere.toml", planner="KPIECE1", seed=3)
    if p.solved:
        for seg in p.segments:
            print(seg.kind, seg.finger, len(seg.waypoints))
        p.save("plan.json")
        assert dexplan.verify("plan.json").ok

This is the layer above planning and the plan file: the planner never imports
the plan-file module; :func:`plan` hands it the plan-file verifier, so a plan
that fails the independent check is returned as ``invalid_plan``, never as
solved. A solved plan then gets its quality figures
(:mod:`dexplan.execution.quality`, the verifier's report reused), which its
plan file carries as ``stats.quality``.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import numpy as np

from dexplan.core.errors import InvalidInputError
from dexplan.core.segments import Segment
from dexplan.core.typing import FloatArray
from dexplan.execution.quality import PlanQuality, QualityLevel, plan_quality
from dexplan.model.hand.hand import Hand
from dexplan.model.scenario import (
    GoalSpec,
    Scenario,
    checked_scenario,
    default_scenario,
    load_scenario,
)
from dexplan.planfile import (
    VerifyReport,
    build_plan_document,
    read_plan,
    verify_plan,
    write_plan,
)
from dexplan.planning.context import build_hand, learning_context
from dexplan.planning.path_plan import plan_path as _plan_path
from dexplan.planning.planner import PlanResult
from dexplan.planning.planner import plan as _plan
from dexplan.planning.progress import PlanStatus, Progress
from dexplan.planning.roadmap.graph import Roadmap, scenario_key
from dexplan.planning.roadmap.learning import BuildSettings, BuildStats, build_roadmap

__all__ = ["Plan", "RoadmapPlanner", "load_scenario", "plan", "plan_path", "verify"]


@dataclass(frozen=True)
class Plan:
    """A query's outcome with the models it was made for.

    Attributes:
        result: the planner's :class:`~dexplan.planning.planner.PlanResult`
            (status, segments, statistics, roadmap, diagnostics).
        scenario: the scenario planned.
        hand: the hand model used.
        quality: the solved plan's quality figures
            (:class:`~dexplan.execution.quality.PlanQuality`), None when not computed.
        quality_time_s: seconds spent on them (not in ``result.stats.time_s``).
    """

    result: PlanResult
    scenario: Scenario
    hand: Hand
    quality: PlanQuality | None = None
    quality_time_s: float | None = None

    @property
    def status(self) -> PlanStatus:
        """How the query ended."""
        return self.result.status

    @property
    def solved(self) -> bool:
        """True when a verified plan was found."""
        return self.result.solved

    @property
    def segments(self) -> tuple[Segment, ...]:
        """The transfer and regrasp segments (empty unless solved or invalid)."""
        return self.result.segments

    def to_document(self, out_dir: str | Path = ".") -> dict[str, Any]:
        """The ``dexplan-plan/2`` document (mesh paths relative to ``out_dir``).

        Its ``stats`` are the planner's, plus the ``quality`` table when computed
        (:meth:`PlanQuality.as_dict` and ``time_s``, the seconds it took).
        """
        doc = build_plan_document(self.scenario, self.hand, self.result, Path(out_dir))
        if self.quality is not None:
            doc["stats"]["quality"] = {**self.quality.as_dict(), "time_s": self.quality_time_s}
        return doc

    def save(self, path: str | Path) -> Path:
        """Write the plan file atomically; return its path.

        Raises:
            PlanFileError: the folder does not exist or is not writable.
        """
        path = Path(path)
        write_plan(path, self.to_document(path.resolve().parent))
        return path


def _scenario(scenario: Scenario | str | Path | None) -> Scenario:
    if scenario is None:
        return default_scenario()
    if isinstance(scenario, Scenario):
        # made or changed in Python: lists and tuples welcome, checked as a file's fields
        return checked_scenario(scenario)
    return load_scenario(scenario)


def plan(
    scenario: Scenario | str | Path | None = None,
    *,
    planner: str | None = None,
    params: Mapping[str, Any] | None = None,
    seed: int | None = None,
    time_limit: float | None = None,
    reduction: str = "auto",
    roadmap: Roadmap | None = None,
    progress: Progress | None = None,
    hand: Hand | None = None,
    quality: QualityLevel | str = QualityLevel.FULL,
) -> Plan:
    """Plan a scenario and check the plan with the independent verifier.

    Args:
        scenario: a :class:`~dexplan.model.scenario.scenario.Scenario`, a scenario TOML path,
            or None for the paper's experiment.
        planner: OMPL planner name (default: the scenario's).
        params: OMPL planner parameters, e.g. ``{"range": 0.05}`` (default:
            the scenario's ``[planner] params``).
        seed: random seed (default: the scenario's).
        time_limit: seconds for the whole query (default: the scenario's).
        reduction: ``auto``, ``gaits`` or ``edges`` (see
            :func:`dexplan.planning.planner.plan`).
        roadmap: a saved roadmap to answer the query on (multi-query).
        progress: called with a :class:`~dexplan.planning.progress.ProgressEvent`
            at each stage.
        hand: the scenario's hand, if already built (saves loading it again).
        quality: the quality figures of a solved plan
            (:class:`~dexplan.execution.quality.QualityLevel`): ``full`` (every
            figure; the execution time and grip forces take seconds), ``fast``
            (no execution figures: milliseconds) or ``none``.

    Returns:
        A :class:`Plan`; "no plan" is a status, not an exception.

    Raises:
        DexplanError: bad input (scenario, planner name or parameter, ...).
    """
    level = _quality_level(quality)
    scen = _scenario(scenario)
    if params is not None:
        spec = dataclasses.replace(scen.planner, params=dict(params))
        scen = dataclasses.replace(scen, planner=spec)
    hand = hand or build_hand(scen)
    checker = _Checker(scen, hand)
    result = _plan(
        scen,
        planner=planner,
        seed=seed,
        time_limit=time_limit,
        roadmap=roadmap,
        progress=progress,
        reduction=reduction,
        verify=checker,
        hand=hand,
    )
    return checker.plan(result, level)


class _Checker:
    """The plan-file verifier as the planner's ``verify``, and the quality of what it passed."""

    def __init__(self, scenario: Scenario, hand: Hand) -> None:
        self.scenario, self.hand = scenario, hand
        self.checked: list[tuple[dict[str, Any], VerifyReport]] = []  # the last plan verified

    def __call__(self, result: PlanResult) -> list[str]:
        scen = self.scenario
        doc = build_plan_document(scen, self.hand, result, scen.base_dir)
        # the plan's package:// meshes resolve where the planner's hand found
        # them (the scenario's package_dirs too), as `verify --package-dir`
        # would; given as folders, not as ROS_PACKAGE_PATH entries, each of
        # which is crawled two levels deep for packages (site-packages is one)
        report = verify_plan(doc, scen.base_dir, self.hand.package_dirs)
        self.checked[:] = [(doc, report)]
        return [str(v) for v in report.violations]

    def plan(self, result: PlanResult, level: QualityLevel) -> Plan:
        """The :class:`Plan` of ``result``, with the quality figures ``level`` asks for."""
        scen, hand = self.scenario, self.hand
        if level == QualityLevel.NONE or not result.solved or not self.checked:
            return Plan(result, scen, hand)
        t0 = time.perf_counter()
        doc, report = self.checked[-1]  # the solved plan's document and the verifier's report
        figures = plan_quality(
            doc, scen.base_dir, hand=hand, report=report, execution=level == QualityLevel.FULL
        )
        return Plan(result, scen, hand, figures, time.perf_counter() - t0)


def plan_path(
    scenario: Scenario | str | Path | None,
    path: object,
    *,
    planner: str = "user",
    seed: int | None = None,
    time_limit: float | None = None,
    reduction: str = "auto",
    progress: Progress | None = None,
    hand: Hand | None = None,
    quality: QualityLevel | str = QualityLevel.FULL,
) -> Plan:
    """A verified plan from your own GSn path: module 2, the reduction, the check.

    What :func:`plan` does after module 1, on a path your planner found (see
    :func:`dexplan.planning.path_plan.plan_path` for what ``path`` must be:
    ``(K, 7 + nq)`` grasps in scenario units from the start pose).

    Raises:
        DexplanError: bad input (scenario, a malformed or invalid path, ...).
    """
    level = _quality_level(quality)
    scen = _scenario(scenario)
    hand = hand or build_hand(scen)
    checker = _Checker(scen, hand)
    result = _plan_path(
        scen,
        path,
        planner=planner,
        seed=seed,
        time_limit=time_limit,
        reduction=reduction,
        progress=progress,
        verify=checker,
        hand=hand,
    )
    return checker.plan(result, level)


def _quality_level(quality: QualityLevel | str) -> QualityLevel:
    """The :class:`QualityLevel` of a ``quality`` argument.

    Raises:
        InvalidInputError: not one of the levels.
    """
    try:
        return QualityLevel(quality)
    except ValueError:
        levels = ", ".join(QualityLevel)
        raise InvalidInputError(f"quality must be one of {levels}, got {quality!r}") from None


class RoadmapPlanner:
    """Multi-query planning: one roadmap, many queries, each with its own statistics.

    Build a roadmap once (the learning phase), or load a saved one, then ask
    queries; each answer is a :class:`Plan` (verified like :func:`plan`) whose
    ``result.stats.time_s`` is that query's own time. A query the roadmap
    cannot answer grows it (module-2 links); :meth:`save` keeps that::

        rp = dexplan.RoadmapPlanner.build("scenarios/paper_sphere.toml", time_limit=20)
        rp.save("roadmap.npz")
        for p in rp.query_many(goals):
            print(p.status, p.result.stats.time_s)

    Attributes:
        scenario: the scenario (its start is every query's start).
        roadmap: the roadmap queries are answered on.
        hand: the hand model.
        build_stats: the learning phase's figures when built here, else None.
    """

    def __init__(
        self, scenario: Scenario | str | Path | None, roadmap: Roadmap, *, hand: Hand | None = None
    ) -> None:
        self.scenario = _scenario(scenario)
        self.hand = hand or build_hand(self.scenario)
        self.roadmap = roadmap
        self.build_stats: BuildStats | None = None

    @classmethod
    def build(
        cls,
        scenario: Scenario | str | Path | None = None,
        *,
        time_limit: float | None = None,
        nodes: int | None = None,
        planner: str = "PRM",
        seed: int = 1,
        progress: Progress | None = None,
    ) -> RoadmapPlanner:
        """Run the learning phase (:func:`~dexplan.planning.roadmap.learning.build_roadmap`).

        Give exactly one of ``time_limit`` (s) and ``nodes`` (deterministic for a seed).

        Raises:
            DexplanError: bad settings or scenario.
        """
        scen = _scenario(scenario)
        settings = BuildSettings(planner=planner, seed=seed, time_limit=time_limit, nodes=nodes)
        hand = build_hand(scen)
        roadmap, stats = build_roadmap(scen, settings, hand=hand, progress=progress)
        out = cls(scen, roadmap, hand=hand)
        out.build_stats = stats
        return out

    @classmethod
    def load(cls, scenario: Scenario | str | Path | None, path: str | Path) -> RoadmapPlanner:
        """Load a saved roadmap, refused unless built for the scenario's models.

        Raises:
            RoadmapFileError: unreadable or malformed file, or other models.
        """
        scen = _scenario(scenario)
        hand = build_hand(scen)
        ctx = learning_context(scen, scen.planner.seed, hand)
        roadmap = Roadmap.load(path, scenario_key(ctx), ambient_dim=ctx.gsn.ambient_dim)
        return cls(scen, roadmap, hand=hand)

    def save(self, path: str | Path) -> Path:
        """Write the roadmap (with what queries added) atomically; return its path."""
        self.roadmap.save(path)
        return Path(path)

    def query(
        self,
        goal: GoalSpec | np.ndarray | Iterable[float],
        *,
        seed: int | None = None,
        time_limit: float | None = None,
        progress: Progress | None = None,
    ) -> Plan:
        """Answer one query: the scenario's start to ``goal`` (a GoalSpec or an object pose).

        A bare pose ``(7,)`` (XYZW) takes the scenario goal's tolerances.
        """
        if not isinstance(goal, GoalSpec):
            # a list, tuple or array: plan() checks it as a scenario file's goal pose
            # (and makes it the FloatArray the field's type promises)
            pose = cast(FloatArray, goal)
            goal = dataclasses.replace(self.scenario.goal, object_pose_xyzquat=pose)
        scen = dataclasses.replace(self.scenario, goal=goal)
        return plan(
            scen,
            seed=seed,
            time_limit=time_limit,
            roadmap=self.roadmap,
            progress=progress,
            hand=self.hand,
        )

    def query_many(
        self,
        goals: Iterable[GoalSpec | np.ndarray],
        *,
        seed: int | None = None,
        time_limit: float | None = None,
    ) -> Iterator[Plan]:
        """Answer queries one after the other (a generator: one plan at a time)."""
        for goal in goals:
            yield self.query(goal, seed=seed, time_limit=time_limit)


def verify(plan_file: str | Path | Mapping[str, Any]) -> VerifyReport:
    """Re-check a plan file (or a plan document) from its content alone.

    Raises:
        PlanFileError: the file is missing, not JSON, or not a well-formed
            ``dexplan-plan/2`` document.
    """
    if isinstance(plan_file, Mapping):
        return verify_plan(plan_file, ".")
    path = Path(plan_file)
    return verify_plan(read_plan(path), path.resolve().parent)
