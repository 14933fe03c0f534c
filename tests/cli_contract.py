"""The command line's contract for bad input, shared by the malformed-input tests.

Bad input gets exit code 2 and exactly one line on stderr, ``dexplan: error:
...``, naming the field; never a traceback, never foreign text from a C++
library, never an output file left behind.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from dexplan.cli import main as cli

MAX_LINE = 400  # characters: values are shortened, never echoed whole


def run_cli(capfd, *args: str) -> tuple[int, str, str]:
    """Run ``dexplan ARGS`` in this process; (exit code, stdout, stderr) at fd level."""
    capfd.readouterr()
    code = cli.run([str(a) for a in args])
    out, err = capfd.readouterr()
    return code, out, err


def assert_bad_input(
    code: int,
    err: str,
    *,
    names: Iterable[str] = (),
    outputs: Iterable[str | Path] = (),
) -> str:
    """Assert the bad-input contract; return the error line.

    Args:
        code: exit code. err: everything written to stderr (fd 2).
        names: strings the message must contain (the field path, a value).
        outputs: files that must not exist afterwards.
    """
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == cli.EXIT_BAD_INPUT, f"exit {code}, stderr: {err[:2000]}"
    assert "Traceback" not in err, err[:2000]
    assert len(lines) == 1, f"expected one line on stderr, got {len(lines)}: {err[:2000]}"
    line = lines[0]
    assert line.startswith("dexplan: error: "), line[:500]
    assert len(line) <= MAX_LINE, f"{len(line)} characters: {line[:500]}"
    for name in names:
        assert name in line, f"{name!r} not in {line!r}"
    for path in outputs:
        assert not Path(path).exists(), f"{path} was left behind"
    return line
