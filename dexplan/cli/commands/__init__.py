"""The ``dexplan`` commands, one module each.

Each module has a ``run`` function taking the command's options
(:mod:`dexplan.cli.options`) and returning its exit code; it imports what the
command needs at module level, and :mod:`dexplan.cli.main` imports only the
module of the command asked for.
"""

__all__ = [
    "bench",
    "export",
    "goals",
    "info",
    "plan",
    "planners",
    "replay",
    "roadmap",
    "scenarios",
    "show",
    "verify",
]
