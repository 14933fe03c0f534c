"""The ``dexplan`` command line.

Exit codes: 0 success (plan found, plan verified), 1 no plan within the time
limit or a plan that fails verification, 2 bad input (malformed scenario or
plan file, unknown planner, missing file, non-finite number).

Progress and errors go to stderr, results to stdout. Library code never prints;
this module owns all output.
"""

from __future__ import annotations

import signal
import threading
from typing import Any, NoReturn

# SIGINT: some libraries catch BaseException around their own imports
# (trimesh does), which swallows the KeyboardInterrupt raised there. The flag
# survives: it is checked at every progress message and before any output.
# Installed first thing, so that Ctrl-C is never lost, even during imports
# (before :func:`run` starts it is only noted: no traceback from an import).
_interrupted = False
_running = False


def _on_sigint(signum: int, frame: Any) -> None:
    global _interrupted
    _interrupted = True
    # never raise inside an import: libraries swallow it there (trimesh) or
    # abort when it surfaces in a native module's initialisation; the flag
    # is acted on at the next progress event or output instead
    if _running and not _importing(frame):
        raise KeyboardInterrupt


def _importing(frame: Any) -> bool:
    """True when the interrupted code runs inside an ``import``."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            return True
        frame = frame.f_back
    return False


if threading.current_thread() is threading.main_thread():
    signal.signal(signal.SIGINT, _on_sigint)

import argparse  # noqa: E402
import os  # noqa: E402
import sys  # noqa: E402
import warnings  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402

from dexplan.core.errors import DexplanError, InvalidInputError, one_line  # noqa: E402

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_BAD_INPUT = 2
EXIT_INTERNAL = 3
EXIT_INTERRUPTED = 130

EPILOG = """exit codes:
  0  success
  1  no plan found within the time limit, or the plan fails verification
  2  bad input (malformed scenario, plan or roadmap, unknown planner, missing
     file, unwritable output): one line on stderr naming the field
  3  internal error (a bug: please report it with the output of --debug)
  130 interrupted (Ctrl-C): nothing is written
"""


def _version(dist: str) -> str:
    from importlib import metadata

    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "not installed"


def cmd_info(args: argparse.Namespace) -> int:
    """Print the builtin hand, the default object and dependency versions."""
    from dexplan.model.hand.hand import Hand
    from dexplan.model.objects import Sphere

    hand = Hand.builtin(args.hand)
    out = sys.stdout
    out.write(f"dexplan {_version('dexplan')}\n")
    out.write(
        f"hand: {hand.name}: {hand.n_fingers} fingers, {hand.nq} joints, "
        f"fingertip radius {hand.fingertip_radius} m\n"
    )
    for i, idx in enumerate(hand.finger_q_index):
        joints = ", ".join(
            f"{hand.joint_names[j]} [{hand.lower[j]:+.2f}, {hand.upper[j]:+.2f}]" for j in idx
        )
        out.write(f"  finger {i} ({hand.fingertip_frames[i]}): {joints}\n")
    obj = Sphere(0.04)
    out.write(f"object: {obj.to_dict()}\n")
    for dist in ("ompl", "pin", "coal", "osqp", "numpy", "scipy", "trimesh", "rerun-sdk"):
        out.write(f"{dist}: {_version(dist)}\n")
    return EXIT_OK


def _err(msg: str) -> None:
    sys.stderr.write(f"dexplan: {msg}\n")
    sys.stderr.flush()


def _check_interrupted() -> None:
    if _interrupted:
        raise KeyboardInterrupt


def _progress(quiet: bool) -> Callable[[Any], None]:
    """The planner's progress callback: a stderr line per event, and the interrupt check."""

    def say(event: Any) -> None:  # a dexplan.planning.progress.ProgressEvent
        _check_interrupted()
        if not quiet:
            _err(event.message)

    return say


def _load_scenario(arg: str | None):
    from dexplan.model.scenario.scenario import default_scenario, load_scenario

    return default_scenario() if arg is None else load_scenario(arg)


def _check_plan_options(args: argparse.Namespace, scenario: Any) -> Any:
    """Every option of ``plan`` checked before any work; returns the hand.

    Every output path is checked (none is written unless all can be), and the
    hand is built, so that a bad URDF is one line before any progress.
    """
    from dexplan.core.files import check_output_path
    from dexplan.model.scenario.scenario import MAX_TIME_LIMIT, SEED_LIMIT
    from dexplan.planning.context import build_hand
    from dexplan.planning.ompl import check_planner

    if args.time_limit is not None and not (0 < args.time_limit <= MAX_TIME_LIMIT):
        raise InvalidInputError(
            f"--time-limit must be in (0, {MAX_TIME_LIMIT:g}] s, got {args.time_limit}"
        )
    if args.seed is not None and not 0 <= args.seed < SEED_LIMIT:
        raise InvalidInputError(f"--seed must be in [0, {SEED_LIMIT - 1}], got {args.seed}")
    if args.planner is not None and not args.planner.strip():
        raise InvalidInputError("--planner: empty planner name")
    check_planner(args.planner or scenario.planner.name, scenario.planner.params)
    if args.rrd is not None or args.debug_rrd is not None:
        from dexplan.viz import require_rerun

        require_rerun()
    from dexplan.cli.roadmap import many_goals

    single = None if many_goals(args) else args.output or "plan.json"
    if not single and args.rrd is not None:
        raise InvalidInputError("--rrd records one plan: not with --goals or --random-goals")
    outputs = (("-o", single), ("--rrd", args.rrd), ("--save-roadmap", args.save_roadmap))
    for option, value in (*outputs, ("--debug-rrd", args.debug_rrd)):
        if value is not None:
            check_output_path(value, option)
    hand = build_hand(scenario)
    q0 = scenario.start.q
    if q0 is not None and q0.shape != (hand.nq,):
        raise InvalidInputError(
            f"start.q must have {hand.nq} entries (the hand's joints), got {q0.shape[0]}"
        )
    return hand


def _load_roadmap(path: str, scenario: Any, hand: Any) -> Any:
    """The roadmap of ``--load-roadmap``, refused unless made for these models."""
    from dexplan.planning.context import build_context
    from dexplan.planning.roadmap.roadmap import Roadmap, scenario_key

    ctx = build_context(scenario, hand=hand)
    return Roadmap.load(path, scenario_key(ctx), ambient_dim=ctx.gsn.ambient_dim)


def _report_no_plan(planned: Any, out: Any) -> int:
    """Say why there is no plan; keep a plan that failed verification for inspection."""
    from dexplan.planfile.document import write_plan

    result = planned.result
    _err(f"no plan: {result.status}: {one_line(result.message, 500)}")
    if result.rejections is not None:
        _err(result.rejections.describe())
    if result.status == "invalid_plan" and result.segments:
        bad = out.with_name(f"{out.stem}.invalid.json")  # never under the requested name
        doc = planned.to_document(bad.resolve().parent)
        doc["stats"]["violations"] = list(result.violations)
        write_plan(bad, doc)
        _err(f"the plan that failed verification is in {bad}")
    sys.stdout.write(f"status: {result.status}\ntime_s: {result.stats.time_s:.3f}\n")
    return EXIT_FAILED


def _summary(out: Any, st: Any) -> str:
    """The stdout summary of a solved plan (a :class:`PlanStats`)."""
    return (
        f"status: solved\nplan: {out}\nplanner: {st.planner}  seed: {st.seed}\n"
        f"time_s: {st.time_s:.3f}  (GSn {st.gsn_time_s or 0:.3f}, "
        f"reduction {st.reduction_time_s or 0:.3f}, verify {st.verify_time_s or 0:.3f})\n"
        f"roadmap_nodes: {st.roadmap_nodes}  graph_nodes: {st.graph_nodes}  "
        f"components: {st.components}\n"
        f"transfers: {st.transfers}  regrasps: {st.regrasps}  "
        f"waypoints: {st.waypoints}  reduction: {st.reduction_method}\n"
    )


def cmd_plan(args: argparse.Namespace) -> int:
    """Plan a scenario; write the plan (and optionally roadmap and recordings)."""
    from pathlib import Path

    from dexplan.api import plan
    from dexplan.cli import roadmap as cli_roadmap
    from dexplan.planfile.document import write_plan

    scenario = _load_scenario(args.scenario)
    hand = _check_plan_options(args, scenario)
    if cli_roadmap.many_goals(args):
        cli_roadmap.query_goals(args, scenario, hand)  # a bad goals file fails before any work
        cli_roadmap.output_dir(args)
    roadmap = (
        None if args.load_roadmap is None else _load_roadmap(args.load_roadmap, scenario, hand)
    )
    if cli_roadmap.many_goals(args):
        return cli_roadmap.run_queries(args, scenario, hand, roadmap, _check_interrupted)
    out = Path(args.output or "plan.json")
    if not args.quiet:
        _err(f"planning {scenario.name!r} with {args.planner or scenario.planner.name}")
    planned = plan(
        scenario,
        planner=args.planner,
        seed=args.seed,
        time_limit=args.time_limit,
        roadmap=roadmap,
        progress=_progress(args.quiet),
        reduction=args.reduction,
        hand=hand,
    )
    result = planned.result
    _check_interrupted()
    if args.debug_rrd is not None and result.rejections is not None:
        from dexplan.viz import record_rejections

        n = record_rejections(result.rejections.samples, args.debug_rrd, scenario=scenario)
        _err(f"{n} rejected samples recorded in {args.debug_rrd}")  # asked for: even with -q
    if args.save_roadmap is not None and result.roadmap is not None:
        result.roadmap.save(args.save_roadmap)
        if not args.quiet:
            _err(f"roadmap written to {args.save_roadmap}")
    if not result.solved:
        return _report_no_plan(planned, out)
    doc = planned.to_document(out.resolve().parent)
    write_plan(out, doc)
    if args.rrd is not None:
        from dexplan.viz import record_plan

        record_plan(doc, args.rrd, roadmap=result.roadmap, base_dir=out.resolve().parent)
        if not args.quiet:
            _err(f"recording written to {args.rrd}")
    sys.stdout.write(_summary(out, result.stats))
    return EXIT_OK


def cmd_verify(args: argparse.Namespace) -> int:
    """Verify a plan file from the file alone."""
    from pathlib import Path

    from dexplan.planfile import read_plan, verify_plan

    doc = read_plan(args.plan)
    report = verify_plan(doc, Path(args.plan).resolve().parent)
    for v in report.violations[: args.max_violations]:
        sys.stdout.write(f"VIOLATION {v}\n")
    if len(report.violations) > args.max_violations:
        sys.stdout.write(f"... and {len(report.violations) - args.max_violations} more\n")
    verdict = "OK" if report.ok else "FAILED"
    sys.stdout.write(
        f"{verdict}: {report.segments} segments, {report.waypoints} waypoints, "
        f"{len(report.violations)} violations\n"
    )
    return EXIT_OK if report.ok else EXIT_FAILED


class _BenchProgressView:
    """Renders a sweep's progress on stderr: a tqdm bar, or a line per run."""

    def __init__(self, quiet: bool) -> None:
        self.quiet = quiet
        self.bar: Any = None
        self.tqdm: Any = None
        if not quiet:
            try:
                from tqdm import tqdm

                self.tqdm = tqdm
            except ImportError:  # plain progress lines instead of a bar
                self.tqdm = None

    def __call__(self, p: Any) -> None:  # a dexplan.bench.BenchProgress
        if self.quiet:
            return
        if p.record is None:
            if p.skipped:
                _err(f"resuming: {p.skipped} runs already in the database, {p.total} to do")
            if self.tqdm is not None:
                self.bar = self.tqdm(total=p.total, file=sys.stderr, unit="run", dynamic_ncols=True)
            return
        r, t = p.record, p.record.get("time")
        what = f"{r['scenario']} {r['planner']} seed {r['seed']}: {r['status_name']}"
        what += f" {t:.2f}s" if t is not None else ""
        if self.bar is not None:
            self.bar.set_postfix_str(what, refresh=False)
            self.bar.update(1)
        else:
            _err(f"[{p.done}/{p.total}] {what}")

    def close(self) -> None:
        """Close the bar, if one was opened."""
        if self.bar is not None:
            self.bar.close()


def cmd_bench(args: argparse.Namespace) -> int:
    """Benchmark planners on scenarios: SQLite (Planner Arena), CSV, plots, summary."""
    from dexplan.bench import format_summary, run_benchmark

    view = _BenchProgressView(args.quiet)
    baseline = None if args.baseline.lower() == "none" else args.baseline
    try:
        result = run_benchmark(
            args.scenarios,
            args.planners,
            args.seeds,
            args.time_limit,
            out_dir=args.output,
            first_seed=args.first_seed,
            jobs=args.jobs,
            ray_address=args.ray,
            baseline=baseline,
            plots=not args.no_plots,
            save_plans=args.save_plans,
            start_method=args.start_method,
            run_timeout=args.run_timeout,
            progress=view,
        )
    finally:
        view.close()
    sys.stdout.write(format_summary(result.summary, baseline) + "\n")
    sys.stdout.write(
        f"runs: {result.new_runs} new, {result.skipped} resumed ({result.backend} backend)\n"
        f"database: {result.database}  (Planner Arena: upload it at plannerarena.org, or "
        f"pip install plannerarena && DATABASE={result.database} plannerarena)\n"
        f"csv: {result.csv}  summary: {result.summary_csv}\n"
    )
    for path in result.plots:
        sys.stdout.write(f"plot: {path}\n")
    failed = result.failed
    if failed:
        first = failed[0]
        _err(
            f"{len(failed)} of {len(result.records)} runs failed ({first['status_name']}: "
            f"{first['scenario']} {first['planner']} seed {first['seed']}: "
            f"{str(first.get('message') or '')[:200]}); see {result.csv}"
        )
        return EXIT_FAILED
    return EXIT_OK


def cmd_show(args: argparse.Namespace) -> int:
    """Open (or with --save, write) a Rerun recording of a plan or roadmap."""
    from dexplan import viz

    viz.require_rerun()
    if args.save is not None:
        out = viz.write_recording(args.source, args.save, roadmap=args.roadmap, plan=args.plan)
        sys.stdout.write(f"recording written to {out}\n")
        return EXIT_OK
    out = viz.show(args.source, roadmap=args.roadmap, plan=args.plan)
    sys.stdout.write(f"opened {out} in the Rerun viewer\n")
    return EXIT_OK


def _plan_sha256(path: str) -> str:
    from dexplan.core.files import file_sha256

    return file_sha256(path)


def cmd_export(args: argparse.Namespace) -> int:
    """Time-parameterise a plan, add grip forces, write dexplan-trajectory/1 (JSON or CSV)."""
    from pathlib import Path

    from dexplan.core.files import check_output_path
    from dexplan.execution.check import check_trajectory
    from dexplan.execution.export import trajectory_document, write_trajectory
    from dexplan.execution.forces import force_settings_from_plan
    from dexplan.execution.timing import TimingLimits
    from dexplan.execution.trajectory import build_trajectory
    from dexplan.planfile import hand_from_plan, read_plan

    out = check_output_path(args.output, "-o")
    if out.suffix.lower() not in (".json", ".csv"):
        raise InvalidInputError(
            f"-o: the trajectory file must end in .json or .csv, got {str(out)!r}"
        )
    doc = read_plan(args.plan)
    base = Path(args.plan).resolve().parent
    limits = TimingLimits(
        **{
            k: v
            for k, v in (
                ("max_acceleration", args.max_acceleration),
                ("object_speed", args.max_object_speed),
                ("object_angular_speed", args.max_object_angular_speed),
            )
            if v is not None
        }
    )
    settings = force_settings_from_plan(doc, mass=args.mass, gravity=args.gravity)
    hand = hand_from_plan(doc["hand"])
    traj = build_trajectory(
        doc, rate=args.rate, limits=limits, settings=settings, base_dir=base, hand=hand
    )
    _check_interrupted()
    tdoc = trajectory_document(traj, doc, _plan_sha256(args.plan))
    problems = check_trajectory(tdoc)
    write_trajectory(out, tdoc)
    import numpy as np

    fmax = float(np.nanmax(np.linalg.norm(traj.forces, axis=2), initial=0.0))
    verdict = "OK" if not problems else f"FAILED ({len(problems)}: {problems[0]})"
    sys.stdout.write(
        f"trajectory: {out}\npoints: {traj.t.size}  segments: {len(traj.segments)}  "
        f"duration_s: {traj.duration:.3f}\nmax_grip_force_N: {fmax:.3f}  "
        f"max_joint_torque_Nm: {float(np.abs(traj.joint_torques).max(initial=0.0)):.4f}\n"
        f"limits check: {one_line(verdict, 300)}\n"
    )
    return EXIT_OK if not problems else EXIT_FAILED


def cmd_replay(args: argparse.Namespace) -> int:
    """Replay a plan in MuJoCo physics; report how far the object strays from the plan."""
    from pathlib import Path

    from dexplan.core.files import check_output_path
    from dexplan.execution.replay.simulation import replay_plan, require_mujoco
    from dexplan.planfile.document import read_plan

    require_mujoco()
    if args.rrd is not None:
        from dexplan.viz import require_rerun

        require_rerun()
        check_output_path(args.rrd, "--rrd")
    doc = read_plan(args.plan)
    result = replay_plan(
        doc,
        gravity=args.gravity,
        base_dir=Path(args.plan).resolve().parent,
        rate=args.rate,
        feedback=not args.open_loop,
    )
    _check_interrupted()
    if args.rrd is not None:
        from dexplan.viz.replay_recording import record_replay

        record_replay(doc, result, args.rrd, base_dir=Path(args.plan).resolve().parent)
        _err(f"recording written to {args.rrd}")
    sys.stdout.write(result.summary() + "\n")
    return EXIT_OK if result.tracked else EXIT_FAILED


def _command(sub: Any, name: str, help_text: str) -> argparse.ArgumentParser:
    """A subcommand parser whose help ends with the exit codes."""
    return sub.add_parser(
        name,
        help=help_text,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )


def _add_info(sub: Any) -> None:
    """The ``info`` subcommand."""
    p_info = sub.add_parser("info", help="show the builtin hand, object and dependency versions")
    p_info.add_argument("--hand", default="paper", help="builtin hand name (default: paper)")
    p_info.set_defaults(func=cmd_info)


def _add_plan(sub: Any) -> None:
    """The ``plan`` subcommand."""
    p_plan = _command(
        sub, "plan", "plan a scenario (default: the paper's sphere) and write plan.json"
    )
    p_plan.add_argument("scenario", nargs="?", help="scenario TOML (default: paper_sphere)")
    p_plan.add_argument("--planner", help="OMPL planner name (default: the scenario's)")
    p_plan.add_argument("--seed", type=int, help="random seed (default: the scenario's)")
    p_plan.add_argument("--time-limit", type=float, help="seconds (default: the scenario's)")
    p_plan.add_argument(
        "-o",
        "--output",
        help="plan file (plan.json); with --goals or --random-goals a folder (queries) "
        "for query_NNN.json and summary.csv",
    )
    p_plan.add_argument("--save-roadmap", help="write the GSn roadmap to this .npz file")
    p_plan.add_argument("--load-roadmap", help="answer the query on a saved roadmap")
    p_plan.add_argument(
        "--reduction",
        choices=("auto", "gaits", "edges"),  # planner.REDUCTIONS (not imported: slow)
        default="auto",
        help="GSn path to transfers/regrasps: finger gaits along the object trajectory, "
        "edge by edge with bisection, or auto (gaits, then edges) (default: auto)",
    )
    p_plan.add_argument("--rrd", help="write a Rerun recording (needs the viz extra)")
    p_plan.add_argument(
        "--debug-rrd",
        metavar="FILE",
        help="record the states the validity checker rejected, with the reason "
        "(the first 32 of each), in a Rerun recording (needs the viz extra)",
    )
    p_plan.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")
    from dexplan.cli.roadmap import add_query_options

    add_query_options(p_plan)
    p_plan.set_defaults(func=cmd_plan)


def cmd_roadmap(args: argparse.Namespace) -> int:
    """``roadmap build`` or ``roadmap info``."""
    from dexplan.cli import roadmap as cli_roadmap

    if args.roadmap_func == "build":
        return cli_roadmap.cmd_roadmap_build(args, _check_interrupted)
    return cli_roadmap.cmd_roadmap_info(args)


def _add_roadmap(sub: Any) -> None:
    """The ``roadmap`` subcommand (``build``, ``info``)."""
    from dexplan.cli.roadmap import add_roadmap

    add_roadmap(sub, _command)
    sub.choices["roadmap"].set_defaults(func=cmd_roadmap)


def _add_verify(sub: Any) -> None:
    """The ``verify`` subcommand."""
    p_ver = _command(sub, "verify", "check a plan file against every rule, from the file alone")
    p_ver.add_argument("plan", help="plan JSON file")
    p_ver.add_argument("--max-violations", type=int, default=50, help="violations to print")
    p_ver.set_defaults(func=cmd_verify)


def _add_bench(sub: Any) -> None:
    """The ``bench`` subcommand."""
    p_bench = _command(
        sub, "bench", "benchmark planners: Planner Arena SQLite, CSV, plots, summary table"
    )
    p_bench.add_argument(
        "scenarios",
        nargs="+",
        metavar="SCENARIO",
        help="scenario TOML files, folders of them, or builtin names",
    )
    p_bench.add_argument(
        "--planners",
        default="PRM,RRTConnect,KPIECE1",
        help="comma-separated OMPL planner names; 'all': every registered planner; "
        "'default': each scenario's own (default: PRM,RRTConnect,KPIECE1)",
    )
    p_bench.add_argument("--seeds", type=int, default=10, help="seeds per planner (10)")
    p_bench.add_argument("--first-seed", type=int, default=1, help="first seed (1)")
    p_bench.add_argument(
        "--time-limit", type=float, help="seconds per run (default: each scenario's)"
    )
    p_bench.add_argument(
        "-j", "--jobs", type=int, help="parallel runs (default: CPU cores, or the Ray cluster's)"
    )
    p_bench.add_argument(
        "-o", "--output", default="bench_results", help="output folder (bench_results)"
    )
    p_bench.add_argument(
        "--ray",
        metavar="ADDRESS",
        help="run on this Ray cluster ('local' starts one in-process; needs the ray extra)",
    )
    p_bench.add_argument(
        "--baseline",
        default="PRM",
        help="planner the figures are compared with, added if missing ('none': no ratios)",
    )
    p_bench.add_argument("--no-plots", action="store_true", help="do not write PNG plots")
    p_bench.add_argument("--save-plans", action="store_true", help="write plans to OUTPUT/plans")
    p_bench.add_argument(
        "--start-method",
        choices=("forkserver", "spawn"),
        default="forkserver",
        help="worker processes of the local pool (forkserver)",
    )
    p_bench.add_argument(
        "--run-timeout",
        type=float,
        help="hard wall-clock seconds per run before it is killed (default: max(3 T, T + 120))",
    )
    p_bench.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")
    p_bench.set_defaults(func=cmd_bench)


def _add_show(sub: Any) -> None:
    """The ``show`` subcommand."""
    p_show = _command(
        sub, "show", "open a plan (.json), roadmap (.npz) or recording (.rrd) in the Rerun viewer"
    )
    p_show.add_argument("source", help="plan .json, roadmap .npz or recording .rrd")
    p_show.add_argument("--save", help="write the recording to this .rrd instead of opening it")
    p_show.add_argument("--roadmap", help="a roadmap .npz to show with a plan")
    p_show.add_argument("--plan", help="a plan .json giving hand and object for a roadmap")
    p_show.set_defaults(func=cmd_show)


def _add_export(sub: Any) -> None:
    """The ``export`` subcommand."""
    p_exp = _command(
        sub,
        "export",
        "time-parameterise a plan, add grip forces, write a trajectory (.json or .csv)",
    )
    p_exp.add_argument("plan", help="plan JSON file")
    p_exp.add_argument("-o", "--output", required=True, help="trajectory file: .json or .csv")
    p_exp.add_argument("--rate", type=float, default=100.0, help="samples per second (100)")
    p_exp.add_argument("--mass", type=float, help="object mass, kg (default: the plan's or 0.1)")
    p_exp.add_argument(
        "--gravity",
        type=float,
        nargs=3,
        metavar=("X", "Y", "Z"),
        help="gravity, m/s^2, world frame (default: the plan's or 0 0 -9.81)",
    )
    p_exp.add_argument("--max-object-speed", type=float, help="m/s (0.02)")
    p_exp.add_argument("--max-object-angular-speed", type=float, help="rad/s (0.5)")
    p_exp.add_argument("--max-acceleration", type=float, help="joint acceleration, rad/s^2 (5)")
    p_exp.set_defaults(func=cmd_export)


def _add_replay(sub: Any) -> None:
    """The ``replay`` subcommand."""
    p_rep = _command(
        sub,
        "replay",
        "replay a plan in MuJoCo physics (needs the sim extra); exit 1 if it loses track",
    )
    p_rep.add_argument("plan", help="plan JSON file")
    grav = p_rep.add_mutually_exclusive_group()
    grav.add_argument(
        "--gravity",
        dest="gravity",
        action="store_true",
        default=True,
        help="with gravity (default)",
    )
    grav.add_argument("--no-gravity", dest="gravity", action="store_false", help="without gravity")
    p_rep.add_argument("--rate", type=float, default=100.0, help="trajectory samples per second")
    p_rep.add_argument(
        "--open-loop",
        action="store_true",
        help="planned joints only, no object-pose feedback (docs/trajectory_format.md)",
    )
    p_rep.add_argument(
        "--rrd", help="write a Rerun recording, plan and replay (needs the viz extra)"
    )
    p_rep.set_defaults(func=cmd_replay)


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line (exit 2), like every bad input."""

    def error(self, message: str) -> NoReturn:
        """Write ``dexplan CMD: error: ... (see dexplan CMD --help)`` and exit 2."""
        self.exit(2, f"{self.prog}: error: {one_line(message, 300)} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``dexplan`` command (subcommands share its class)."""
    parser = _Parser(
        prog="dexplan",
        description="Dexterous in-hand manipulation planning in the n-finger grasp subspace.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=_version("dexplan"))
    parser.add_argument("--debug", action="store_true", help="show tracebacks of internal errors")
    sub = parser.add_subparsers(dest="command", required=True)
    _add_info(sub)
    _add_plan(sub)
    _add_roadmap(sub)
    _add_verify(sub)
    _add_bench(sub)
    _add_show(sub)
    _add_export(sub)
    _add_replay(sub)
    return parser


def run(argv: Sequence[str] | None = None) -> int:
    """Run one ``dexplan`` command in this process and return its exit code.

    Every error becomes one ``dexplan: error: ...`` line on stderr and exit
    code 2 (bad input) or 3 (a bug); nothing is raised. Tests call this;
    :func:`main` is the console script.
    """
    global _running
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, _on_sigint)
    _running = True
    try:
        return _run(argv)
    finally:
        _running = False


def _run(argv: Sequence[str] | None) -> int:
    args: argparse.Namespace | None = None
    try:
        _check_interrupted()  # Ctrl-C during the imports above
        try:
            args = build_parser().parse_args(argv)
        except SystemExit as exc:  # argparse: --help, --version or a usage error
            return int(exc.code or 0) if isinstance(exc.code, int) else EXIT_BAD_INPUT
        with warnings.catch_warnings():
            # numerical warnings of NumPy/SciPy inside the library are not for
            # users: results are checked (and verified) on their own
            warnings.simplefilter("ignore", RuntimeWarning)
            code = int(args.func(args))
        _check_interrupted()
        return code
    except BrokenPipeError:  # `dexplan info | head`: the reader left, nothing to say
        return EXIT_OK
    except KeyboardInterrupt:
        _err("interrupted")
        return EXIT_INTERRUPTED
    except Exception as exc:
        if _interrupted:
            # a library that swallowed Ctrl-C (trimesh leaves an ExceptionWrapper
            # where a module should be) then fails: the interrupt is the cause
            _err("interrupted")
            return EXIT_INTERRUPTED
        if isinstance(exc, DexplanError | OSError):  # bad input; unreadable or unwritable files
            _err(f"error: {exc}")
            return EXIT_BAD_INPUT
        if args is not None and args.debug:  # a bug: say so plainly, traceback only on request
            raise
        detail = str(exc)[:300]
        _err(f"internal error: {type(exc).__name__}: {detail} (rerun with --debug)")
        return EXIT_INTERNAL


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``dexplan`` console script."""
    code = run(argv)
    sys.stdout.flush()
    sys.stderr.flush()
    # nanobind (ompl) reports "leaked instances" at interpreter exit; users
    # should not see it, and everything is flushed already.
    os._exit(code)


if __name__ == "__main__":
    main()
