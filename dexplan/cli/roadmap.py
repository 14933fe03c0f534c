"""The multi-query commands: ``dexplan roadmap build|info`` and many-goal ``plan``.

Kept apart from :mod:`dexplan.cli.main` (which registers them) so that neither
module passes 1,000 lines; the same rules hold: progress and errors on
stderr, results on stdout, bad input one line and exit 2.
"""

from __future__ import annotations

import argparse
import csv
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from dexplan.core.errors import InvalidInputError

SUMMARY_FIELDS = (
    "query",
    "status",
    "solved",
    "time_s",
    "cpu_s",
    "gsn_time_s",
    "reduction_time_s",
    "verify_time_s",
    "regrasps",
    "transfers",
    "gsn_status",
    "plan",
)
"""Columns of ``summary.csv`` (one row per query)."""


def _err(msg: str) -> None:
    sys.stderr.write(f"dexplan: {msg}\n")
    sys.stderr.flush()


# --------------------------------------------------------------------- build
class BuildView:
    """Progress of a build on stderr: a tqdm bar (nodes, or seconds with --time), else lines."""

    def __init__(self, args: argparse.Namespace, check_interrupted: Callable[[], None]) -> None:
        self.check = check_interrupted
        self.quiet = args.quiet
        self.by_time = args.time is not None
        self.bar: Any = None
        if not self.quiet:
            try:
                from tqdm import tqdm
            except ImportError:  # plain progress lines instead of a bar
                return
            total = args.time if self.by_time else args.nodes
            unit = "s" if self.by_time else "node"
            self.bar = tqdm(total=total, unit=unit, file=sys.stderr, dynamic_ncols=True)

    def __call__(self, event: Any) -> None:
        """Show one :class:`~dexplan.planning.progress.ProgressEvent`."""
        self.check()
        if self.quiet:
            return
        if self.bar is None:
            _err(event.message)
            return
        c = event.counts
        done = event.elapsed_s if self.by_time else c.get("nodes", self.bar.n)
        self.bar.update(max(0.0, min(done, self.bar.total) - self.bar.n))
        self.bar.set_postfix_str(event.message.split(": ", 1)[-1], refresh=True)

    def close(self) -> None:
        """Close the bar, if one was opened."""
        if self.bar is not None:
            self.bar.close()


def cmd_roadmap_build(args: argparse.Namespace, check_interrupted: Callable[[], None]) -> int:
    """The learning phase: build a goal-independent roadmap and write it."""
    from dexplan.core.files import check_output_path
    from dexplan.model.scenario.scenario import SEED_LIMIT, default_scenario, load_scenario
    from dexplan.planning.context import build_hand
    from dexplan.planning.roadmap.learning import BuildSettings, build_roadmap

    scenario = default_scenario() if args.scenario is None else load_scenario(args.scenario)
    if not 0 <= args.seed < SEED_LIMIT:
        raise InvalidInputError(f"--seed must be in [0, {SEED_LIMIT - 1}], got {args.seed}")
    settings = BuildSettings(
        planner=args.planner,
        seed=args.seed,
        time_limit=args.time,
        nodes=args.nodes,
        max_link_attempts=args.link_attempts,
        jobs=args.jobs,
        ray_address=args.ray,
    )
    check_output_path(args.output, "-o")
    hand = build_hand(scenario)
    if not args.quiet:
        budget = f"{args.time:g} s" if args.time is not None else f"{args.nodes} nodes"
        _err(f"building a roadmap of {scenario.name!r} with {args.planner} ({budget})")
    view = BuildView(args, check_interrupted)
    try:
        roadmap, st = build_roadmap(scenario, settings, hand=hand, progress=view)
    finally:
        view.close()
    roadmap.save(args.output)
    sys.stdout.write(
        f"roadmap: {args.output}\nplanner: {st.planner}  seed: {st.seed}\n"
        f"nodes: {st.nodes}  edges: {st.edges}  links: {st.links}  "
        f"link_attempts: {st.link_attempts}\n"
        f"components: {st.components}  (GSn edges alone: {st.gsn_components})\n"
        f"time_s: {st.time_s:.3f}  (module 1 {st.module1_time_s:.3f}, "
        f"module 2 {st.module2_time_s:.3f})\n"
        + (f"workers: {st.workers}  tasks: {st.tasks}\n" if st.tasks else "")
    )
    return 0


def cmd_roadmap_info(args: argparse.Namespace) -> int:
    """Sizes, components, links, scenario hash and build statistics of a roadmap file."""
    import numpy as np

    from dexplan.planning.roadmap.roadmap import Roadmap

    rm = Roadmap.load(args.roadmap)
    n_comp, labels = rm.components()
    gsn_comp = rm.components(with_links=False)[0]
    sizes = np.sort(np.bincount(labels, minlength=n_comp))[::-1] if rm.n_vertices else []
    shown = ", ".join(str(int(s)) for s in sizes[:10]) + (" ..." if len(sizes) > 10 else "")
    out = sys.stdout
    out.write(
        f"roadmap: {args.roadmap}\nformat: dexplan-roadmap/1\nplanner: {rm.planner}\n"
        f"scenario_key: {rm.scenario_key}\n"
        f"nodes: {rm.n_vertices}  joints: {rm.vertices.shape[1] - 7}\n"
        f"edges: {len(rm.edges)}  links: {len(rm.links)}\n"
        f"components: {n_comp}  (GSn edges alone: {gsn_comp})\n"
        f"component sizes: {shown or '-'}\n"
    )
    for key in sorted(rm.build):
        out.write(f"build.{key}: {rm.build[key]}\n")
    return 0


def add_roadmap(sub: Any, command: Callable[..., argparse.ArgumentParser]) -> None:
    """The ``roadmap build|info`` subcommands (``command`` makes a parser with the epilog)."""
    p_rm = command(sub, "roadmap", "multi-query roadmaps: build one (learning phase), inspect one")
    rsub = p_rm.add_subparsers(dest="roadmap_command", required=True)
    p_b = command(rsub, "build", "the learning phase: a goal-independent GSn roadmap")
    p_b.add_argument("scenario", nargs="?", help="scenario TOML (default: paper_sphere)")
    budget = p_b.add_mutually_exclusive_group(required=True)
    budget.add_argument("--time", type=float, help="seconds for the whole build")
    budget.add_argument(
        "--nodes", type=int, help="module-1 roadmap size (deterministic for a seed)"
    )
    p_b.add_argument("--planner", default="PRM", help="PRM or PRMstar (default: PRM)")
    p_b.add_argument("--seed", type=int, default=1, help="random seed (1)")
    p_b.add_argument(
        "--link-attempts",
        type=int,
        help="most module-2 link attempts (default: until merged, or 20 per component "
        "with --nodes)",
    )
    p_b.add_argument(
        "--jobs",
        type=int,
        help="build in tasks over K local processes (the same roadmap for a seed and "
        "--nodes whatever K; 1: tasks in this process)",
    )
    p_b.add_argument(
        "--ray",
        metavar="ADDRESS",
        help="build in tasks over a Ray cluster (auto, ray://HOST:10001, or local; "
        "needs dexplan[ray]); --jobs caps the workers",
    )
    p_b.add_argument("-o", "--output", required=True, help="roadmap file (.npz)")
    p_b.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")
    p_b.set_defaults(roadmap_func="build")
    p_i = command(rsub, "info", "sizes, components, links and build statistics of a roadmap")
    p_i.add_argument("roadmap", help="roadmap .npz")
    p_i.set_defaults(roadmap_func="info")


# --------------------------------------------------------------------- queries
def add_query_options(p_plan: argparse.ArgumentParser) -> None:
    """The many-goal options of ``plan``."""
    goals = p_plan.add_mutually_exclusive_group()
    goals.add_argument(
        "--goals", metavar="FILE", help="a TOML list of [[goals]] (pose, tolerances): many queries"
    )
    goals.add_argument(
        "--random-goals",
        type=int,
        metavar="K",
        help="K random goals (uniform orientations at the start position; with "
        "--goal-kind pose, positions in the [workspace] box too), drawn with --seed",
    )
    p_plan.add_argument(
        "--goal-kind",
        choices=("orientation", "pose"),
        default="orientation",
        help="what --random-goals draws (orientation)",
    )


def many_goals(args: argparse.Namespace) -> bool:
    """Whether ``plan`` answers several queries."""
    return args.goals is not None or args.random_goals is not None


def query_goals(args: argparse.Namespace, scenario: Any, hand: Any) -> list[Any]:
    """The goals of ``--goals`` or ``--random-goals`` (checked).

    Random goal poses where the object alone meets an obstacle are drawn again.
    """
    from dexplan.model.scenario.goals import load_goals, random_goals
    from dexplan.planning.context import build_context

    if args.goals is not None:
        return load_goals(args.goals, scenario.goal)
    seed = scenario.planner.seed if args.seed is None else args.seed
    world = build_context(scenario, hand=hand).world
    return random_goals(
        scenario, args.random_goals, seed, args.goal_kind, lambda p: not world.object_collides(p)
    )


def output_dir(args: argparse.Namespace) -> Path:
    """The folder of a many-goal ``plan`` (``-o``, default ``queries``), created."""
    out = Path(args.output or "queries")
    if out.suffix.lower() == ".json":
        raise InvalidInputError(
            f"-o: with several queries -o is a folder for query_NNN.json and summary.csv, "
            f"got {str(out)!r}"
        )
    if out.exists() and not out.is_dir():
        raise InvalidInputError(f"-o: {str(out)!r} exists and is not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InvalidInputError(f"-o: cannot create the folder {str(out)!r}: {exc}") from exc
    return out


def run_queries(
    args: argparse.Namespace,
    scenario: Any,
    hand: Any,
    roadmap: Any,
    check_interrupted: Callable[[], None],
) -> int:
    """Answer every goal in this process; write the plans, summary.csv and the table."""
    import dataclasses

    from dexplan.api import plan

    goals = query_goals(args, scenario, hand)
    out = output_dir(args)
    mode = "the roadmap" if roadmap is not None else "single-query planning"
    if not args.quiet:
        _err(f"answering {len(goals)} queries of {scenario.name!r} with {mode}")
    rows = []
    for k, goal in enumerate(goals, start=1):
        scen = dataclasses.replace(scenario, goal=goal)
        cpu0 = time.process_time()
        planned = plan(
            scen,
            planner=args.planner,
            seed=args.seed,
            time_limit=args.time_limit,
            roadmap=roadmap,
            progress=_quiet(check_interrupted),
            reduction=args.reduction,
            hand=hand,
        )
        cpu = time.process_time() - cpu0
        check_interrupted()
        rows.append({**_write_query(out, k, planned), "cpu_s": cpu})
        if not args.quiet:
            r = rows[-1]
            _err(f"query {k}/{len(goals)}: {r['status']} in {r['time_s']:.3f} s")
    if args.save_roadmap is not None and roadmap is not None:
        roadmap.save(args.save_roadmap)
        if not args.quiet:
            _err(f"roadmap written to {args.save_roadmap}")
    _write_summary(out / "summary.csv", rows)
    sys.stdout.write(format_table(rows) + f"plans: {out}  summary: {out / 'summary.csv'}\n")
    return 0 if all(r["solved"] for r in rows) else 1


def _quiet(check_interrupted: Callable[[], None]) -> Callable[[Any], None]:
    def say(_event: Any) -> None:
        check_interrupted()

    return say


def _write_query(out: Path, k: int, planned: Any) -> dict[str, Any]:
    """Write one query's plan file (solved or failed verification); its summary row."""
    from dexplan.planfile.document import write_plan

    result = planned.result
    st = result.stats
    name = ""
    if result.segments:
        path = out / (f"query_{k:03d}.json" if result.solved else f"query_{k:03d}.invalid.json")
        doc = planned.to_document(out.resolve())
        if not result.solved:
            doc["stats"]["violations"] = list(result.violations)
        write_plan(path, doc)
        name = path.name
    return {
        "query": k,
        "status": str(result.status),
        "solved": int(result.solved),
        "time_s": st.time_s,
        "gsn_time_s": st.gsn_time_s,
        "reduction_time_s": st.reduction_time_s,
        "verify_time_s": st.verify_time_s,
        "regrasps": st.regrasps,
        "transfers": st.transfers,
        "gsn_status": st.gsn_status,
        "plan": name,
    }


def _write_summary(path: Path, rows: list[dict[str, Any]]) -> None:
    from dexplan.core.files import atomic_output

    with atomic_output(path, "summary") as tmp, open(tmp, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=SUMMARY_FIELDS)
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if r[k] is None else r[k]) for k in SUMMARY_FIELDS})


def format_table(rows: list[dict[str, Any]]) -> str:
    """The stdout table: one line per query, then solved count and time quantiles."""
    head = f"{'query':>5}  {'status':<16} {'time_s':>8} {'cpu_s':>8} {'regrasps':>8}  roadmap"
    lines = [head]
    for r in rows:
        reg = "-" if r["regrasps"] is None else str(r["regrasps"])
        lines.append(
            f"{r['query']:>5}  {r['status']:<16} {r['time_s']:>8.3f} {r['cpu_s']:>8.3f} "
            f"{reg:>8}  {r['gsn_status'] or '-'}"
        )
    times = [r["time_s"] for r in rows]
    cpu = [r["cpu_s"] for r in rows]
    solved = sum(r["solved"] for r in rows)
    lines.append(
        f"solved: {solved}/{len(rows)}  time_s median {statistics.median(times):.3f}  "
        f"mean {statistics.fmean(times):.3f}  max {max(times):.3f}  "
        f"cpu_s median {statistics.median(cpu):.3f}"
    )
    return "\n".join(lines) + "\n"
