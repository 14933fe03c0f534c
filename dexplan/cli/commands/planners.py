"""``dexplan planners``: every registered planner, what it searches, its parameters."""

from __future__ import annotations

import sys
import textwrap

from dexplan.cli.console import ExitCode
from dexplan.cli.options import PlannersOptions
from dexplan.planning.ompl import available_planners, check_planner, planner_traits
from dexplan.planning.ompl.param_declarations import planner_params
from dexplan.planning.roadmap.problems import CHART_RANGE, searched_space

__all__ = ["describe_planner", "run"]


def describe_planner(name: str) -> list[str]:
    """The lines ``dexplan planners`` prints for one planner.

    Raises:
        PlannerError: unknown planner (with a did-you-mean hint).
    """
    check_planner(name)
    traits = planner_traits(name)
    space, why = searched_space(name)
    lines = [
        f"{name}  ({traits.family})",
        *_wrapped(f"  searches: {space}", "    "),
        *_wrapped(f"    why: {why}", "      "),
    ]
    if traits.note:
        lines += _wrapped(f"  note: {traits.note}", "    ")
    params = planner_params(name)
    if not params:
        lines.append("  parameters: none declared")
        return lines
    lines.append("  parameters (--param NAME=VALUE; default; OMPL's suggested range):")
    width = max(len(p.name) for p in params)
    for p in params:
        text = f"    {p.name:<{width}}  {p.default:<8}  {p.range or '-'}"
        if not p.settable:
            text += "  (not settable: the binding has no setter)"
        elif p.name == "range" and not traits.multi_query:
            text += f"  (dexplan sets {CHART_RANGE} on the contact chart unless given)"
        lines.append(text.rstrip())
    return lines


def _wrapped(text: str, indent: str) -> list[str]:
    """``text`` in lines of at most 100 characters, later lines indented by ``indent``."""
    return textwrap.wrap(text, 100, subsequent_indent=indent, break_on_hyphens=False)


def run(opts: PlannersOptions) -> int:
    """Print the registered planners (or the named ones) with their parameters."""
    names = opts.names or tuple(available_planners())
    for name in names:
        check_planner(name)  # every name checked before anything is printed
    blocks = ["\n".join(describe_planner(name)) for name in names]
    sys.stdout.write("\n\n".join(blocks) + "\n")
    if not opts.names:
        sys.stdout.write(
            "\nranges are OMPL's own ParamSet suggestions (low:step:high; 0,1 for a flag); "
            "a default of 0 for range or max_nearest_neighbors means OMPL chooses at setup\n"
        )
    return ExitCode.OK
