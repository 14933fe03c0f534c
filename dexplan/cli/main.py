"""The ``dexplan`` command line: its parser, the dispatch to a command, exit codes.

Exit codes: 0 success (plan found, plan verified), 1 no plan within the time
limit or a plan that fails verification, 2 bad input (malformed scenario or
plan file, unknown planner, missing file, non-finite number).

Progress and errors go to stderr, results to stdout. Library code never prints;
the command line owns all output. Each command is a module of
:mod:`dexplan.cli.commands`, given its options (:mod:`dexplan.cli.options`),
never the argparse namespace.
"""

from __future__ import annotations

from dexplan.cli import interrupt

# SIGINT is handled first thing, before the imports below and long before a
# command module loads NumPy, trimesh or OMPL, so that Ctrl-C is never lost,
# even during imports (before :func:`run` starts it is only noted).
interrupt.install()

import argparse  # noqa: E402
import importlib  # noqa: E402
import os  # noqa: E402
import sys  # noqa: E402
import warnings  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from typing import TYPE_CHECKING, NoReturn, TypeAlias  # noqa: E402

from dexplan.cli.console import ExitCode, dist_version, err  # noqa: E402
from dexplan.cli.options import (  # noqa: E402
    BenchOptions,
    ExportOptions,
    GoalKind,
    InfoOptions,
    PlannersOptions,
    PlanOptions,
    Reduction,
    ReplayLoops,
    ReplayOptions,
    RoadmapBuildOptions,
    RoadmapInfoOptions,
    ScenariosOptions,
    ShowOptions,
    StartMethod,
    VerifyOptions,
)
from dexplan.core.errors import DexplanError, one_line  # noqa: E402

__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_FAILED",
    "EXIT_INTERNAL",
    "EXIT_INTERRUPTED",
    "EXIT_OK",
    "Command",
    "build_parser",
    "main",
    "run",
]

EXIT_OK = ExitCode.OK
EXIT_FAILED = ExitCode.FAILED
EXIT_BAD_INPUT = ExitCode.BAD_INPUT
EXIT_INTERNAL = ExitCode.INTERNAL
EXIT_INTERRUPTED = ExitCode.INTERRUPTED

EPILOG = """exit codes:
  0  success
  1  no plan found within the time limit, or the plan fails verification
  2  bad input (malformed scenario, plan or roadmap, unknown planner, missing
     file, unwritable output): one line on stderr naming the field
  3  internal error (a bug: please report it with the output of --debug)
  130 interrupted (Ctrl-C): nothing is written
"""


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line (exit 2), like every bad input."""

    def error(self, message: str) -> NoReturn:
        """Write ``dexplan CMD: error: ... (see dexplan CMD --help)`` and exit 2."""
        self.exit(2, f"{self.prog}: error: {one_line(message, 300)} (see {self.prog} --help)\n")


if TYPE_CHECKING:  # argparse's subparsers action is generic in its type stubs only
    Subparsers: TypeAlias = argparse._SubParsersAction[_Parser]
    """What ``add_subparsers`` returns: subcommand parsers are added to it."""


@dataclass(frozen=True)
class Command:
    """What a parsed command line runs.

    Attributes:
        module: the command's module in :mod:`dexplan.cli.commands`; its
            ``run`` takes the options and returns the exit code.
        read_options: the options of a parsed command line.
    """

    module: str
    read_options: Callable[[argparse.Namespace], object]


def _version(dist: str) -> str:
    """The version of the distribution ``dist`` (``--version``)."""
    return dist_version(dist)


def _command(sub: Subparsers, name: str, help_text: str) -> _Parser:
    """A subcommand parser whose help ends with the exit codes."""
    return sub.add_parser(
        name,
        help=help_text,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )


def _add_info(sub: Subparsers) -> None:
    """The ``info`` subcommand."""
    p_info = sub.add_parser(
        "info",
        help="show a hand (joints in planning order, limits, fingertips, reach), "
        "the object and dependency versions",
    )
    p_info.add_argument(
        "--hand",
        default="paper",
        metavar="HAND_OR_SCENARIO",
        help="a builtin hand (paper, three_finger, allegro, allegro_left), a scenario "
        "(TOML file or builtin name: its hand and object) or a URDF file (default: paper)",
    )
    p_info.set_defaults(dispatch=Command("info", InfoOptions.from_args))


def _add_param_option(parser: argparse.ArgumentParser, which: str) -> None:
    """The repeatable ``--param NAME=VALUE`` option of ``plan`` and ``bench``."""
    parser.add_argument(
        "--param",
        action="append",
        metavar="NAME=VALUE",
        help=f"an OMPL planner parameter, repeatable, {which} (names and ranges: "
        "dexplan planners NAME)",
    )


def _add_planners(sub: Subparsers) -> None:
    """The ``planners`` subcommand."""
    p_pl = _command(
        sub,
        "planners",
        "list the OMPL planners: family, what they search, parameters with defaults and ranges",
    )
    p_pl.add_argument("names", nargs="*", metavar="NAME", help="planners to show (default: all)")
    p_pl.set_defaults(dispatch=Command("planners", PlannersOptions.from_args))


def _add_scenarios(sub: Subparsers) -> None:
    """The ``scenarios`` subcommand."""
    p_sc = sub.add_parser(
        "scenarios",
        help="list the builtin scenarios: every command that takes a scenario accepts their names",
    )
    p_sc.set_defaults(dispatch=Command("scenarios", ScenariosOptions.from_args))


def _add_plan(sub: Subparsers) -> None:
    """The ``plan`` subcommand."""
    p_plan = _command(
        sub, "plan", "plan a scenario (default: the paper's sphere) and write plan.json"
    )
    p_plan.add_argument(
        "scenario",
        nargs="?",
        help="scenario TOML file or builtin scenario name (default: paper_sphere)",
    )
    p_plan.add_argument("--planner", help="OMPL planner name (default: the scenario's)")
    _add_param_option(p_plan, "over the scenario's [planner] params")
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
        choices=[r.value for r in Reduction],
        default=Reduction.AUTO.value,
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
    _add_query_options(p_plan)
    p_plan.set_defaults(dispatch=Command("plan", PlanOptions.from_args))


def _add_query_options(p_plan: argparse.ArgumentParser) -> None:
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
        choices=[k.value for k in GoalKind],
        default=GoalKind.ORIENTATION.value,
        help="what --random-goals draws (orientation)",
    )


def _add_roadmap_build(rsub: Subparsers) -> None:
    """The ``roadmap build`` subcommand."""
    p_b = _command(rsub, "build", "the learning phase: a goal-independent GSn roadmap")
    p_b.add_argument(
        "scenario",
        nargs="?",
        help="scenario TOML file or builtin scenario name (default: paper_sphere)",
    )
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
    p_b.set_defaults(dispatch=Command("roadmap", RoadmapBuildOptions.from_args))


def _add_roadmap(sub: Subparsers) -> None:
    """The ``roadmap`` subcommand (``build``, ``info``)."""
    p_rm = _command(sub, "roadmap", "multi-query roadmaps: build one (learning phase), inspect one")
    rsub = p_rm.add_subparsers(dest="roadmap_command", required=True)
    _add_roadmap_build(rsub)
    p_i = _command(rsub, "info", "sizes, components, links and build statistics of a roadmap")
    p_i.add_argument("roadmap", help="roadmap .npz")
    p_i.set_defaults(dispatch=Command("roadmap", RoadmapInfoOptions.from_args))


def _add_package_dir(parser: _Parser) -> None:
    """``--package-dir DIR`` (repeatable): folders ``package://`` mesh URIs resolve in."""
    parser.add_argument(
        "--package-dir",
        action="append",
        default=[],
        metavar="DIR",
        dest="package_dirs",
        help="folder package:// mesh URIs of the plan's hand resolve in, searched before "
        "ROS_PACKAGE_PATH and example-robot-data (repeatable)",
    )


def _add_verify(sub: Subparsers) -> None:
    """The ``verify`` subcommand."""
    p_ver = _command(sub, "verify", "check a plan file against every rule, from the file alone")
    p_ver.add_argument("plan", help="plan JSON file")
    p_ver.add_argument("--max-violations", type=int, default=50, help="violations to print")
    _add_package_dir(p_ver)
    p_ver.set_defaults(dispatch=Command("verify", VerifyOptions.from_args))


def _add_bench(sub: Subparsers) -> None:
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
    _add_param_option(p_bench, "for every planner of the sweep, the baseline included")
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
        choices=[m.value for m in StartMethod],
        default=StartMethod.FORKSERVER.value,
        help="worker processes of the local pool (forkserver)",
    )
    p_bench.add_argument(
        "--run-timeout",
        type=float,
        help="hard wall-clock seconds per run before it is killed (default: max(3 T, T + 120))",
    )
    p_bench.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")
    p_bench.set_defaults(dispatch=Command("bench", BenchOptions.from_args))


def _add_show(sub: Subparsers) -> None:
    """The ``show`` subcommand."""
    p_show = _command(
        sub, "show", "open a plan (.json), roadmap (.npz) or recording (.rrd) in the Rerun viewer"
    )
    p_show.add_argument("source", help="plan .json, roadmap .npz or recording .rrd")
    p_show.add_argument("--save", help="write the recording to this .rrd instead of opening it")
    p_show.add_argument("--roadmap", help="a roadmap .npz to show with a plan")
    p_show.add_argument("--plan", help="a plan .json giving hand and object for a roadmap")
    _add_package_dir(p_show)
    p_show.set_defaults(dispatch=Command("show", ShowOptions.from_args))


def _add_export(sub: Subparsers) -> None:
    """The ``export`` subcommand."""
    p_exp = _command(
        sub,
        "export",
        "time-parameterise a plan, add grip forces, write a trajectory (.json, .csv) "
        "or a ROS 2 bag (.mcap)",
    )
    p_exp.add_argument("plan", help="plan JSON file")
    p_exp.add_argument(
        "-o",
        "--output",
        required=True,
        help="trajectory file: .json, .csv, or .mcap (ROS 2 bag, needs the ros extra)",
    )
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
    _add_package_dir(p_exp)
    p_exp.set_defaults(dispatch=Command("export", ExportOptions.from_args))


def _add_replay(sub: Subparsers) -> None:
    """The ``replay`` subcommand."""
    p_rep = _command(
        sub,
        "replay",
        "replay a plan in MuJoCo physics (needs the sim extra), closed and open loop; "
        "exit 1 if it loses track",
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
    loop = p_rep.add_mutually_exclusive_group()
    loop.add_argument(
        "--loop",
        choices=[v.value for v in ReplayLoops],
        default=ReplayLoops.BOTH.value,
        help="closed: object-pose feedback; open: the planned joints; both (default): "
        "closed then open, exit status from closed (docs/trajectory_format.md)",
    )
    loop.add_argument("--open-loop", action="store_true", help="the same as --loop open")
    p_rep.add_argument(
        "--rrd", help="write a Rerun recording, plan and replay (needs the viz extra)"
    )
    _add_package_dir(p_rep)
    p_rep.set_defaults(dispatch=Command("replay", ReplayOptions.from_args))


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
    _add_scenarios(sub)
    _add_plan(sub)
    _add_roadmap(sub)
    _add_verify(sub)
    _add_bench(sub)
    _add_planners(sub)
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
    interrupt.install()
    interrupt.running(True)
    interrupt.forget_outputs()
    try:
        return _run(argv)
    finally:
        interrupt.running(False)
        interrupt.forget_outputs()


def _dispatch(args: argparse.Namespace) -> int:
    """Read the command's options, import its module and run it."""
    command: Command = args.dispatch
    options = command.read_options(args)
    # The one import inside a function, a measured start-up cost: importing
    # every command module (OMPL, Pinocchio, trimesh, ...) takes about 2 s of
    # CPU, `dexplan --help` with the parser alone 0.13 s.
    module = importlib.import_module(f"dexplan.cli.commands.{command.module}")
    return int(module.run(options))


def _run(argv: Sequence[str] | None) -> int:
    args: argparse.Namespace | None = None
    try:
        interrupt.check()  # Ctrl-C during the imports above
        try:
            args = build_parser().parse_args(argv)
        except SystemExit as exc:  # argparse: --help, --version or a usage error
            return int(exc.code or 0) if isinstance(exc.code, int) else EXIT_BAD_INPUT
        with warnings.catch_warnings():
            # numerical warnings of NumPy/SciPy inside the library are not for
            # users: results are checked (and verified) on their own
            warnings.simplefilter("ignore", RuntimeWarning)
            code = _dispatch(args)
        interrupt.check()
        return code
    except BrokenPipeError:  # `dexplan info | head`: the reader left, nothing to say
        return EXIT_OK
    except KeyboardInterrupt:
        interrupt.discard_outputs()
        err("interrupted")
        return EXIT_INTERRUPTED
    except Exception as exc:
        return _exit_code_of(exc, debug=args is not None and args.debug)


def _exit_code_of(exc: Exception, *, debug: bool) -> int:
    """Say what went wrong in one line; the exit code it maps to.

    Raises:
        Exception: ``exc`` again, for an internal error with ``--debug``.
    """
    if interrupt.is_interrupted():
        # a library that swallowed Ctrl-C (trimesh leaves an ExceptionWrapper
        # where a module should be) then fails: the interrupt is the cause
        interrupt.discard_outputs()
        err("interrupted")
        return EXIT_INTERRUPTED
    if isinstance(exc, DexplanError | OSError):  # bad input; unreadable or unwritable files
        err(f"error: {exc}")
        return EXIT_BAD_INPUT
    if debug:  # a bug: say so plainly, traceback only on request
        raise exc
    detail = str(exc)[:300]
    err(f"internal error: {type(exc).__name__}: {detail} (rerun with --debug)")
    return EXIT_INTERNAL


def main(argv: Sequence[str] | None = None) -> NoReturn:
    """Entry point of the ``dexplan`` console script."""
    code = run(argv)
    sys.stdout.flush()
    sys.stderr.flush()
    # nanobind (ompl) reports "leaked instances" at interpreter exit; users
    # should not see it, and everything is flushed already.
    os._exit(code)


if __name__ == "__main__":
    main()
