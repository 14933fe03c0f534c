"""The ``dexplan`` command line.

:mod:`~dexplan.cli.main` parses the command line and runs one command of
:mod:`~dexplan.cli.commands` with its options (:mod:`~dexplan.cli.options`);
:mod:`~dexplan.cli.console` is what they write (exit codes, stderr lines,
progress) and :mod:`~dexplan.cli.interrupt` is how Ctrl-C stops them.
"""

__all__ = [
    "commands",
    "console",
    "interrupt",
    "main",
    "options",
]
