"""``dexplan replay``: a plan in MuJoCo physics, and how far the object strays from it."""

from __future__ import annotations

import sys
from pathlib import Path

from dexplan.cli import interrupt
from dexplan.cli.console import ExitCode, err
from dexplan.cli.options import ReplayOptions
from dexplan.core.files import check_output_path
from dexplan.execution.replay.simulation import replay_plan, require_mujoco
from dexplan.planfile import read_plan
from dexplan.viz import require_rerun
from dexplan.viz.replay_recording import record_replay

__all__ = ["run"]


def run(opts: ReplayOptions) -> int:
    """Replay the plan; exit 1 if the object loses track of it."""
    require_mujoco()
    if opts.rrd is not None:
        require_rerun()
        check_output_path(opts.rrd, "--rrd")
    doc = read_plan(opts.plan)
    base = Path(opts.plan).resolve().parent
    result = replay_plan(
        doc, gravity=opts.gravity, base_dir=base, rate=opts.rate, feedback=not opts.open_loop
    )
    interrupt.check()
    if opts.rrd is not None:
        record_replay(doc, result, opts.rrd, base_dir=base)
        err(f"recording written to {opts.rrd}")
    sys.stdout.write(result.summary() + "\n")
    return ExitCode.OK if result.tracked else ExitCode.FAILED
