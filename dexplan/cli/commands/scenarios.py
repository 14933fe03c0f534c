"""``dexplan scenarios``: the builtin scenarios, by the names every command accepts."""

from __future__ import annotations

import sys

from dexplan.cli.console import ExitCode
from dexplan.cli.options import ScenariosOptions
from dexplan.model.scenario import builtin_scenarios

__all__ = ["run"]


def run(opts: ScenariosOptions) -> int:
    """List the builtin scenarios: name, then the first sentence of the file's comment."""
    del opts  # no options
    found = builtin_scenarios()
    width = max(len(s.name) for s in found)
    out = sys.stdout
    for s in found:
        out.write(f"{s.name:<{width}}  {s.summary}\n")
    out.write(
        "\nevery command that takes a scenario accepts these names "
        f"(dexplan plan allegro_sphere); the files, to copy and edit: {found[0].path.parent}\n"
    )
    return ExitCode.OK
