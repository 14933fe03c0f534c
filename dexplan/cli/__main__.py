"""``python -m dexplan.cli``: the ``dexplan`` command."""

from dexplan.cli.main import main

main()
