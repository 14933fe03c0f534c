"""``dexplan verify``: check a plan file against every rule, from the file alone."""

from __future__ import annotations

import sys
from pathlib import Path

from dexplan.cli.console import ExitCode
from dexplan.cli.options import VerifyOptions
from dexplan.model.hand.packages import package_search_path
from dexplan.planfile import read_plan, verify_plan

__all__ = ["run"]


def run(opts: VerifyOptions) -> int:
    """Verify a plan file; print the first violations and the verdict."""
    # every hand built inside (plan, recording, replay) searches them too
    with package_search_path(opts.package_dirs):
        return _run(opts)


def _run(opts: VerifyOptions) -> int:
    """The command itself, inside the ``--package-dir`` search path."""
    doc = read_plan(opts.plan)
    report = verify_plan(doc, Path(opts.plan).resolve().parent)
    shown = opts.max_violations
    for v in report.violations[:shown]:
        sys.stdout.write(f"VIOLATION {v}\n")
    if len(report.violations) > shown:
        sys.stdout.write(f"... and {len(report.violations) - shown} more\n")
    verdict = "OK" if report.ok else "FAILED"
    sys.stdout.write(
        f"{verdict}: {report.segments} segments, {report.waypoints} waypoints, "
        f"{len(report.violations)} violations\n"
    )
    return ExitCode.OK if report.ok else ExitCode.FAILED
