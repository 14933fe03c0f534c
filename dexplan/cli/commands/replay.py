"""``dexplan replay``: a plan in MuJoCo physics, and how far the object strays from it."""

from __future__ import annotations

import sys
from pathlib import Path

from dexplan.cli import interrupt
from dexplan.cli.console import ExitCode, err
from dexplan.cli.options import ReplayLoops, ReplayOptions
from dexplan.core.files import check_output_path
from dexplan.execution.replay.result import Loop
from dexplan.execution.replay.simulation import replay_loops, require_mujoco
from dexplan.model.hand.packages import package_search_path
from dexplan.planfile import read_plan
from dexplan.viz import require_rerun
from dexplan.viz.replay_recording import record_replay

__all__ = ["run"]


def run(opts: ReplayOptions) -> int:
    """Replay the plan in the loops asked; exit 1 if the first one (closed if asked) loses track."""
    # every hand built inside (plan, recording, replay) searches them too
    with package_search_path(opts.package_dirs):
        return _run(opts)


def _run(opts: ReplayOptions) -> int:
    """The command itself, inside the ``--package-dir`` search path."""
    require_mujoco()
    if opts.rrd is not None:
        require_rerun()
        check_output_path(opts.rrd, "--rrd")
    doc = read_plan(opts.plan)
    base = Path(opts.plan).resolve().parent
    loops = (Loop.CLOSED, Loop.OPEN) if opts.loops == ReplayLoops.BOTH else (Loop(opts.loops),)
    report = replay_loops(doc, loops, gravity=opts.gravity, base_dir=base, rate=opts.rate)
    interrupt.check()
    if opts.rrd is not None:  # the first loop's replay: closed loop unless only open was asked
        record_replay(doc, report.results[0], opts.rrd, base_dir=base)
        err(f"recording written to {opts.rrd}")
    sys.stdout.write(report.summary() + "\n")
    return ExitCode.OK if report.tracked else ExitCode.FAILED
