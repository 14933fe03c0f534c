"""The builtin scenarios: their names and summaries, and a scenario argument resolved.

Every command that takes a scenario accepts a TOML path or the name of a
builtin scenario (``paper_sphere``, ``suite/box_roll90``): :func:`resolve_scenario_path`.
:func:`builtin_scenarios` lists them (``dexplan scenarios``).
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from dexplan.core.errors import ScenarioError, shorten

__all__ = [
    "BuiltinScenario",
    "builtin_scenario_folder",
    "builtin_scenarios",
    "resolve_scenario_path",
]

_SUMMARY_CHARS = 150
"""Longest summary :func:`builtin_scenarios` gives (characters)."""


@dataclass(frozen=True)
class BuiltinScenario:
    """A scenario shipped with dexplan.

    Attributes:
        name: what commands accept (``paper_sphere``, ``suite/box_roll90``).
        path: its TOML file.
        summary: the first sentence of the file's leading comment.
    """

    name: str
    path: Path
    summary: str


def _root() -> Path:
    """The folder of the builtin scenarios (``dexplan/data/scenarios``)."""
    return Path(str(resources.files("dexplan").joinpath("data/scenarios")))


def _summary(path: Path) -> str:
    """The first sentence of a scenario file's leading comment block ("" without one)."""
    lines = []
    for line in path.read_text(encoding="utf-8").splitlines():
        if not line.startswith("#"):
            break
        lines.append(line.lstrip("#").strip())
    text = " ".join(lines)
    # a sentence ends at a full stop followed by a space and a capital (not "e.g. x")
    m = re.search(r"\.(?=\s+[A-Z]|$)", text)
    sentence = text[: m.end()] if m else text
    return sentence if len(sentence) <= _SUMMARY_CHARS else sentence[: _SUMMARY_CHARS - 3] + "..."


def builtin_scenarios() -> list[BuiltinScenario]:
    """The builtin scenarios: the top-level ones by name, then the suite's (``suite/NAME``)."""
    root = _root()
    files = sorted(root.glob("*.toml")) + sorted(root.glob("*/*.toml"))
    return [
        BuiltinScenario(p.relative_to(root).with_suffix("").as_posix(), p, _summary(p))
        for p in files
    ]


def builtin_scenario_folder(name: str) -> Path | None:
    """The builtin folder of scenarios called ``name`` (``suite``), or None."""
    if not name or "/" in name or name not in {p.name for p in _root().iterdir()}:
        return None
    folder = _root() / name
    return folder if folder.is_dir() else None


def resolve_scenario_path(arg: str | Path) -> Path:
    """A scenario argument as a file: a TOML path, or a builtin scenario's name.

    A file that exists wins over a builtin scenario of the same name.

    Raises:
        ScenarioError: neither a file nor a builtin scenario (with the closest
            builtin names, and where to list them).
    """
    path = Path(arg)
    try:
        if path.is_file():
            return path
    except (OSError, ValueError):  # a name too long, a NUL: load_scenario says so
        return path
    text = str(arg)
    names = {s.name: s.path for s in builtin_scenarios()}
    key = text.removesuffix(".toml")
    if key in names:
        return names[key]
    close = difflib.get_close_matches(key, list(names), n=3, cutoff=0.6)
    hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
    raise ScenarioError(
        f"scenario file not found: {shorten(text)}, and no builtin scenario has that name"
        f"{hint} (dexplan scenarios lists them)"
    )
