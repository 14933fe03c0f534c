"""``dexplan plan``: plan a scenario, write the plan (and roadmap, recordings).

With ``--goals`` or ``--random-goals`` it answers many queries instead
(:mod:`dexplan.cli.commands.goals`). Every option is checked, and the hand
built, before any planning work, so that bad input is one line and exit 2.
"""

from __future__ import annotations

import dataclasses
import functools
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from dexplan.api import Plan, plan
from dexplan.cli import interrupt
from dexplan.cli.commands.goals import output_dir, query_goals, run_queries
from dexplan.cli.console import ExitCode, err, plan_progress
from dexplan.cli.options import PlanOptions
from dexplan.core.errors import InvalidInputError, one_line
from dexplan.core.files import check_output_path
from dexplan.execution.quality import PlanQuality, format_quality
from dexplan.model.hand.hand import Hand
from dexplan.model.scenario import (
    MAX_TIME_LIMIT,
    SEED_LIMIT,
    Scenario,
    default_scenario,
    load_scenario,
    resolve_scenario_path,
)
from dexplan.planfile import write_plan
from dexplan.planning.context import PlanningContext, build_context, build_hand
from dexplan.planning.ompl import check_planner
from dexplan.planning.roadmap.graph import Roadmap, scenario_key
from dexplan.planning.stats import PlanStats
from dexplan.viz import record_plan, record_rejections, require_rerun

__all__ = ["check_options", "run", "with_params"]


def _check_numbers(opts: PlanOptions) -> None:
    """``--time-limit``, ``--seed`` and ``--planner`` in range (or not given)."""
    if opts.time_limit is not None and not (0 < opts.time_limit <= MAX_TIME_LIMIT):
        raise InvalidInputError(
            f"--time-limit must be in (0, {MAX_TIME_LIMIT:g}] s, got {opts.time_limit}"
        )
    if opts.seed is not None and not 0 <= opts.seed < SEED_LIMIT:
        raise InvalidInputError(f"--seed must be in [0, {SEED_LIMIT - 1}], got {opts.seed}")
    if opts.planner is not None and not opts.planner.strip():
        raise InvalidInputError("--planner: empty planner name")


def check_options(opts: PlanOptions, scenario: Scenario) -> Hand:
    """Every option of ``plan`` checked before any work; returns the hand.

    Every output path is checked (none is written unless all can be), and the
    hand is built, so that a bad URDF is one line before any progress.

    Raises:
        DexplanError: an option out of range, an unwritable output, a bad hand.
    """
    _check_numbers(opts)
    check_planner(opts.planner or scenario.planner.name, scenario.planner.params)
    if opts.rrd is not None or opts.debug_rrd is not None:
        require_rerun()
    single = None if opts.many_goals else opts.output or "plan.json"
    if not single and opts.rrd is not None:
        raise InvalidInputError("--rrd records one plan: not with --goals or --random-goals")
    outputs = (("-o", single), ("--rrd", opts.rrd), ("--save-roadmap", opts.save_roadmap))
    for option, value in (*outputs, ("--debug-rrd", opts.debug_rrd)):
        if value is not None:
            check_output_path(interrupt.output(value), option)
    hand = build_hand(scenario)
    q0 = scenario.start.q
    if q0 is not None and q0.shape != (hand.nq,):
        raise InvalidInputError(
            f"start.q must have {hand.nq} entries (the hand's joints), got {q0.shape[0]}"
        )
    return hand


def _load_roadmap(opts: PlanOptions, context: Callable[[], PlanningContext]) -> Roadmap | None:
    """The roadmap of ``--load-roadmap`` (None without), refused unless made for these models."""
    if opts.load_roadmap is None:
        return None
    ctx = context()
    return Roadmap.load(opts.load_roadmap, scenario_key(ctx), ambient_dim=ctx.gsn.ambient_dim)


def with_params(scenario: Scenario, params: Sequence[tuple[str, Any]]) -> Scenario:
    """``scenario`` with ``--param`` values over its ``[planner] params`` (checked later)."""
    if not params:
        return scenario
    spec = dataclasses.replace(scenario.planner, params={**scenario.planner.params, **dict(params)})
    return dataclasses.replace(scenario, planner=spec)


def run(opts: PlanOptions) -> int:
    """Plan a scenario (or many goals); write the plan and what else was asked for."""
    scenario = (
        default_scenario()
        if opts.scenario is None
        else load_scenario(resolve_scenario_path(opts.scenario))
    )
    scenario = with_params(scenario, opts.params)
    hand = check_options(opts, scenario)
    # built at most once, and only if needed: random goals and a loaded roadmap share it
    context = functools.cache(lambda: build_context(scenario, hand=hand))
    if not opts.many_goals:
        return _plan_one(opts, scenario, hand, _load_roadmap(opts, context))
    goals = query_goals(opts, scenario, context)  # a bad goals file fails before any work
    out = output_dir(opts)
    return run_queries(opts, scenario, hand, _load_roadmap(opts, context), goals, out)


def _plan_one(opts: PlanOptions, scenario: Scenario, hand: Hand, roadmap: Roadmap | None) -> int:
    """One query: plan, write the plan file and the recordings asked for."""
    out = Path(opts.output or "plan.json")
    if not opts.quiet:
        err(f"planning {scenario.name!r} with {opts.planner or scenario.planner.name}")
    planned = plan(
        scenario,
        planner=opts.planner,
        seed=opts.seed,
        time_limit=opts.time_limit,
        roadmap=roadmap,
        progress=plan_progress(opts.quiet),
        reduction=opts.reduction.value,
        hand=hand,
    )
    result = planned.result
    interrupt.check()
    if opts.debug_rrd is not None and result.rejections is not None:
        n = record_rejections(result.rejections.samples, opts.debug_rrd, scenario=scenario)
        err(f"{n} rejected samples recorded in {opts.debug_rrd}")  # asked for: even with -q
    if opts.save_roadmap is not None and result.roadmap is not None:
        result.roadmap.save(opts.save_roadmap)
        if not opts.quiet:
            err(f"roadmap written to {opts.save_roadmap}")
    if not result.solved:
        return _report_no_plan(planned, out)
    doc = planned.to_document(out.resolve().parent)
    write_plan(out, doc)
    if opts.rrd is not None:
        record_plan(doc, opts.rrd, roadmap=result.roadmap, base_dir=out.resolve().parent)
        if not opts.quiet:
            err(f"recording written to {opts.rrd}")
    sys.stdout.write(_summary(out, result.stats, planned.quality))
    return ExitCode.OK


def _report_no_plan(planned: Plan, out: Path) -> int:
    """Say why there is no plan; keep a plan that failed verification for inspection."""
    result = planned.result
    err(f"no plan: {result.status}: {one_line(result.message, 500)}")
    rej = result.rejections
    if rej is not None and (rej.attempts or rej.checked):  # none: the pose check said why
        err(rej.describe())
    if result.status == "invalid_plan" and result.segments:
        bad = out.with_name(f"{out.stem}.invalid.json")  # never under the requested name
        doc = planned.to_document(bad.resolve().parent)
        doc["stats"]["violations"] = list(result.violations)
        write_plan(bad, doc)
        err(f"the plan that failed verification is in {bad}")
    sys.stdout.write(f"status: {result.status}\ntime_s: {result.stats.time_s:.3f}\n")
    return ExitCode.FAILED


def _summary(out: Path, st: PlanStats, quality: PlanQuality | None) -> str:
    """The stdout summary of a solved plan (its quality in two lines, when computed)."""
    lines = "".join(f"{line}\n" for line in format_quality(quality)) if quality else ""
    return (
        f"status: solved\nplan: {out}\nplanner: {st.planner}  seed: {st.seed}\n"
        f"time_s: {st.time_s:.3f}  (GSn {st.gsn_time_s or 0:.3f}, "
        f"reduction {st.reduction_time_s or 0:.3f}, verify {st.verify_time_s or 0:.3f})\n"
        f"roadmap_nodes: {st.roadmap_nodes}  graph_nodes: {st.graph_nodes}  "
        f"components: {st.components}\n"
        f"transfers: {st.transfers}  regrasps: {st.regrasps}  "
        f"waypoints: {st.waypoints}  reduction: {st.reduction_method}\n"
        f"{lines}"
    )
