"""``dexplan roadmap build|info``: the learning phase, and what a roadmap file holds."""

from __future__ import annotations

import sys
from typing import Any

import numpy as np

from dexplan.cli import interrupt
from dexplan.cli.console import ExitCode, err
from dexplan.cli.options import RoadmapBuildOptions, RoadmapInfoOptions
from dexplan.core.errors import InvalidInputError
from dexplan.core.files import check_output_path
from dexplan.core.ray_cluster import parse_ray_address
from dexplan.model.scenario import (
    SEED_LIMIT,
    default_scenario,
    load_scenario,
    resolve_scenario_path,
)
from dexplan.planning.context import build_hand
from dexplan.planning.progress import ProgressEvent
from dexplan.planning.roadmap.graph import Roadmap
from dexplan.planning.roadmap.learning import BuildSettings, BuildStats, build_roadmap

try:
    from tqdm import tqdm
except ImportError:  # plain progress lines instead of a bar
    tqdm = None

__all__ = ["BuildView", "build", "info", "run"]


class BuildView:
    """Progress of a build on stderr: a tqdm bar (nodes, or seconds with --time), else lines."""

    def __init__(self, opts: RoadmapBuildOptions) -> None:
        self.quiet = opts.quiet
        self.by_time = opts.time is not None
        self.bar: Any = None
        if not self.quiet and tqdm is not None:
            total = opts.time if self.by_time else opts.nodes
            unit = "s" if self.by_time else "node"
            self.bar = tqdm(total=total, unit=unit, file=sys.stderr, dynamic_ncols=True)

    def __call__(self, event: ProgressEvent) -> None:
        """Show one progress event (and act on Ctrl-C)."""
        interrupt.check()
        if self.quiet:
            return
        if self.bar is None:
            err(event.message)
            return
        c = event.counts
        done = event.elapsed_s if self.by_time else c.get("nodes", self.bar.n)
        self.bar.update(max(0.0, min(done, self.bar.total) - self.bar.n))
        self.bar.set_postfix_str(event.message.split(": ", 1)[-1], refresh=True)

    def close(self) -> None:
        """Close the bar, if one was opened."""
        if self.bar is not None:
            self.bar.close()


def _build_report(output: str, st: BuildStats) -> str:
    """The stdout report of a finished build."""
    return (
        f"roadmap: {output}\nplanner: {st.planner}  seed: {st.seed}\n"
        f"nodes: {st.nodes}  edges: {st.edges}  links: {st.links}  "
        f"link_attempts: {st.link_attempts}\n"
        f"components: {st.components}  (GSn edges alone: {st.gsn_components})\n"
        f"time_s: {st.time_s:.3f}  (module 1 {st.module1_time_s:.3f}, "
        f"module 2 {st.module2_time_s:.3f})\n"
        + (f"workers: {st.workers}  tasks: {st.tasks}\n" if st.tasks else "")
    )


def build(opts: RoadmapBuildOptions) -> int:
    """The learning phase: build a goal-independent roadmap and write it."""
    scenario = (
        default_scenario()
        if opts.scenario is None
        else load_scenario(resolve_scenario_path(opts.scenario))
    )
    if not 0 <= opts.seed < SEED_LIMIT:
        raise InvalidInputError(f"--seed must be in [0, {SEED_LIMIT - 1}], got {opts.seed}")
    settings = BuildSettings(
        planner=opts.planner,
        seed=opts.seed,
        time_limit=opts.time,
        nodes=opts.nodes,
        max_link_attempts=opts.link_attempts,
        jobs=opts.jobs,
        ray_address=opts.ray,
    )
    check_output_path(interrupt.output(opts.output), "-o")
    if opts.ray is not None:  # the address's form, before the models are built
        parse_ray_address(opts.ray)
    hand = build_hand(scenario)
    if not opts.quiet:
        budget = f"{opts.time:g} s" if opts.time is not None else f"{opts.nodes} nodes"
        err(f"building a roadmap of {scenario.name!r} with {opts.planner} ({budget})")
    view = BuildView(opts)
    try:
        roadmap, st = build_roadmap(scenario, settings, hand=hand, progress=view)
    finally:
        view.close()
    roadmap.save(opts.output)
    sys.stdout.write(_build_report(opts.output, st))
    return ExitCode.OK


def info(opts: RoadmapInfoOptions) -> int:
    """Sizes, components, links, scenario hash and build statistics of a roadmap file."""
    rm = Roadmap.load(opts.roadmap)
    n_comp, labels = rm.components()
    gsn_comp = rm.components(with_links=False)[0]
    sizes: list[int] = []
    if rm.n_vertices:
        sizes = [int(s) for s in np.sort(np.bincount(labels, minlength=n_comp))[::-1]]
    shown = ", ".join(str(s) for s in sizes[:10]) + (" ..." if len(sizes) > 10 else "")
    out = sys.stdout
    out.write(
        f"roadmap: {opts.roadmap}\nformat: dexplan-roadmap/1\nplanner: {rm.planner}\n"
        f"scenario_key: {rm.scenario_key}\n"
        f"nodes: {rm.n_vertices}  joints: {rm.vertices.shape[1] - 7}\n"
        f"edges: {len(rm.edges)}  links: {len(rm.links)}\n"
        f"components: {n_comp}  (GSn edges alone: {gsn_comp})\n"
        f"component sizes: {shown or '-'}\n"
    )
    for key in sorted(rm.build):
        out.write(f"build.{key}: {rm.build[key]}\n")
    return ExitCode.OK


def run(opts: RoadmapBuildOptions | RoadmapInfoOptions) -> int:
    """``roadmap build`` or ``roadmap info``, by the options given."""
    if isinstance(opts, RoadmapBuildOptions):
        return build(opts)
    return info(opts)
