"""``dexplan show``: open (or save) a Rerun recording of a plan, roadmap or recording."""

from __future__ import annotations

import sys

from dexplan import viz
from dexplan.cli.console import ExitCode
from dexplan.cli.options import ShowOptions
from dexplan.model.hand.packages import package_search_path

__all__ = ["run"]


def run(opts: ShowOptions) -> int:
    """Open the source in the Rerun viewer, or with ``--save`` write the recording."""
    # every hand built inside (plan, recording, replay) searches them too
    with package_search_path(opts.package_dirs):
        return _run(opts)


def _run(opts: ShowOptions) -> int:
    """The command itself, inside the ``--package-dir`` search path."""
    viz.require_rerun()
    if opts.save is not None:
        out = viz.write_recording(opts.source, opts.save, roadmap=opts.roadmap, plan=opts.plan)
        sys.stdout.write(f"recording written to {out}\n")
        return ExitCode.OK
    out = viz.show(opts.source, roadmap=opts.roadmap, plan=opts.plan)
    sys.stdout.write(f"opened {out} in the Rerun viewer\n")
    return ExitCode.OK
