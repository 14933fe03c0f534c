"""Links and file paths in README.md and docs/ name files that exist in the repository."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
#: the user-facing pages (CHANGELOG.md is history: it may name files since removed)
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]

#: ``[text](target)`` and ``![alt](target)``; the target stops at whitespace or ``)``
LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
#: backticked repository paths that look like files
PATH = re.compile(
    r"`((?:dexplan/[\w./-]*\.py)|(?:scenarios/[\w./-]*\.toml)|(?:examples/[\w./-]+)"
    r"|(?:scripts/[\w./-]*\.py)|(?:docs/[\w./-]*\.md))`"
)


#: backticked dotted names of the package (``dexplan.model.hand.urdf.mount_urdf``)
DOTTED = re.compile(r"`(dexplan(?:\.[A-Za-z_][A-Za-z0-9_]*)+)`")


def _without_code_blocks(text: str) -> str:
    """The page with fenced code blocks blanked (their lines kept, for line numbers)."""
    out, fenced = [], False
    for line in text.splitlines():
        if line.lstrip().startswith("```"):
            fenced = not fenced
            out.append("")
        else:
            out.append("" if fenced else line)
    return "\n".join(out)


def _broken(page: Path, root: Path = ROOT) -> list[str]:
    """Where ``page`` links to a missing file or names a missing repository path."""
    text = _without_code_blocks(page.read_text())
    bad = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        for target in LINK.findall(line):
            if re.match(r"^[a-z][a-z0-9+.-]*:", target) or target.startswith("#"):
                continue  # http(s), mailto, ... and anchors within the page
            path = target.split("#", 1)[0]
            if not path:
                continue
            resolved = (page.parent / path).resolve()
            if not resolved.exists() or not resolved.is_relative_to(root.resolve()):
                bad.append(f"{page.relative_to(root)}:{lineno}: link to {target}")
        for path in PATH.findall(line):
            if "*" in path or "<" in path:
                continue
            if not (root / path).exists():
                bad.append(f"{page.relative_to(root)}:{lineno}: no file {path}")
    return bad


@pytest.mark.parametrize("page", PAGES, ids=[str(p.relative_to(ROOT)) for p in PAGES])
def test_links_and_paths_exist(page: Path) -> None:
    bad = _broken(page)
    assert not bad, "\n".join(bad)


def test_the_checker_sees_a_broken_link(tmp_path: Path) -> None:
    page = tmp_path / "page.md"
    page.write_text(
        "[ok](page.md#top) [web](https://example.org) [here](#x)\n"
        "[gone](missing.md) `dexplan/no_such_module.py` [out](../elsewhere.md)\n"
        "```\n[in code](also_missing.md)\n```\n"
    )
    bad = _broken(page, root=tmp_path)
    assert len(bad) == 3, bad
    assert "missing.md" in bad[0] and "elsewhere.md" in bad[1] and "no_such_module" in bad[2]


def _resolves(name: str) -> bool:
    """Whether ``name`` is a module of the package, or an attribute path below one."""
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        for attr in parts[i:]:
            if not hasattr(obj, attr):
                return False
            obj = getattr(obj, attr)
        return True
    return False


@pytest.mark.parametrize("page", PAGES, ids=[str(p.relative_to(ROOT)) for p in PAGES])
def test_dotted_names_resolve(page: Path) -> None:
    # after a module moves, the docs' `dexplan.x.y` names must follow it
    names = sorted(set(DOTTED.findall(_without_code_blocks(page.read_text()))))
    missing = [n for n in names if not _resolves(n)]
    assert not missing, f"{page.relative_to(ROOT)} names {missing}"
