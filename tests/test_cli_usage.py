"""Usage errors (a bad flag value, a missing argument, an unknown command) are one line, exit 2."""

from __future__ import annotations

import pytest

from dexplan.cli import main as cli


@pytest.mark.parametrize(
    ("argv", "names"),
    [
        (["plan", "--seed", "abc"], ["dexplan plan", "--seed", "'abc'"]),
        (["nosuch"], ["dexplan", "'nosuch'"]),
        (["roadmap", "build"], ["dexplan roadmap build", "-o/--output"]),
        (["bench"], ["dexplan bench", "SCENARIO"]),
        (["export", "p.json", "--rate", "fast"], ["dexplan export", "--rate", "'fast'"]),
    ],
)
def test_usage_error_is_one_line_naming_the_argument(capfd, argv, names) -> None:
    code = cli.run(argv)
    out, err = capfd.readouterr()
    assert code == 2
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "error:" in lines[0] and "--help" in lines[0]
    for name in names:
        assert name in lines[0]
