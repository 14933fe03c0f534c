"""``dexplan export``: a plan as a timed trajectory with grip forces (JSON, CSV, ROS 2 bag)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from dexplan.cli import interrupt
from dexplan.cli.console import ExitCode
from dexplan.cli.options import ExportOptions
from dexplan.core.errors import InvalidInputError, one_line
from dexplan.core.files import check_output_path, file_sha256
from dexplan.execution.bag import BAG_SUFFIX, require_rosbags, write_bag
from dexplan.execution.check import check_trajectory
from dexplan.execution.export import TrajectoryFormat, trajectory_document, write_trajectory
from dexplan.execution.forces import force_settings_from_plan
from dexplan.execution.segment_timing import TimingLimits
from dexplan.execution.trajectory import build_trajectory
from dexplan.model.hand.packages import package_search_path
from dexplan.planfile import hand_from_plan, read_plan

__all__ = ["run"]


def _limits(opts: ExportOptions) -> TimingLimits:
    """The timing limits: the defaults, overridden by the options given."""
    default = TimingLimits()
    acc, speed, turn = opts.max_acceleration, opts.max_object_speed, opts.max_object_angular_speed
    return TimingLimits(
        max_acceleration=default.max_acceleration if acc is None else acc,
        object_speed=default.object_speed if speed is None else speed,
        object_angular_speed=default.object_angular_speed if turn is None else turn,
    )


def run(opts: ExportOptions) -> int:
    """Time-parameterise a plan, add grip forces, write the trajectory (JSON, CSV or a bag)."""
    # every hand built inside (plan, recording, replay) searches them too
    with package_search_path(opts.package_dirs):
        return _run(opts)


def _run(opts: ExportOptions) -> int:
    """The command itself, inside the ``--package-dir`` search path."""
    out = check_output_path(interrupt.output(opts.output), "-o")
    is_bag = out.suffix.lower() == BAG_SUFFIX
    if TrajectoryFormat.of_path(out) is None and not is_bag:
        raise InvalidInputError(
            f"-o: the trajectory file must end in .json, .csv or .mcap (ROS 2 bag), "
            f"got {str(out)!r}"
        )
    if is_bag:
        require_rosbags()  # before the minutes of timing, not after
    doc = read_plan(opts.plan)
    base = Path(opts.plan).resolve().parent
    limits = _limits(opts)
    settings = force_settings_from_plan(doc, mass=opts.mass, gravity=opts.gravity)
    hand = hand_from_plan(doc["hand"])
    traj = build_trajectory(
        doc, rate=opts.rate, limits=limits, settings=settings, base_dir=base, hand=hand
    )
    interrupt.check()
    tdoc = trajectory_document(traj, doc, file_sha256(opts.plan))
    problems = check_trajectory(tdoc)
    interrupt.check()
    topics = ""
    if is_bag:
        counts = write_bag(out, tdoc)
        topics = "".join(f"  {t}: {n} messages\n" for t, n in counts.items())
    else:
        write_trajectory(out, tdoc)
    fmax = float(np.nanmax(np.linalg.norm(traj.forces, axis=2), initial=0.0))
    verdict = "OK" if not problems else f"FAILED ({len(problems)}: {problems[0]})"
    sys.stdout.write(
        f"trajectory: {out}\npoints: {traj.t.size}  segments: {len(traj.segments)}  "
        f"duration_s: {traj.duration:.3f}\nmax_grip_force_N: {fmax:.3f}  "
        f"max_joint_torque_Nm: {float(np.abs(traj.joint_torques).max(initial=0.0)):.4f}\n"
        f"limits check: {one_line(verdict, 300)}\n{topics}"
    )
    return ExitCode.OK if not problems else ExitCode.FAILED
