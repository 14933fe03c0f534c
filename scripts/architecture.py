"""Regenerate the measured parts of docs/architecture.md from the code.

    python scripts/architecture.py           # rewrite the generated blocks in place
    python scripts/architecture.py --check   # exit 1 if the page is out of date

The page keeps its written text; what the code decides (the folders and their
modules, module and function sizes, the import graph) sits between
``<!-- generated:NAME -->`` and ``<!-- /generated:NAME -->`` markers and is
written here, so it cannot drift from the code. The test suite runs ``--check``.
"""

from __future__ import annotations

import argparse
import ast
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import code_size
import import_graph

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "dexplan"
PAGE = ROOT / "docs" / "architecture.md"
LONG_MODULE = 600
LONG_FUNCTION = code_size.LONG_FUNCTION
TOP = 10


def _summary_line(path: Path) -> str:
    doc = ast.get_docstring(ast.parse(path.read_text())) or ""
    return doc.strip().splitlines()[0] if doc.strip() else ""


def _lines(path: Path) -> int:
    return len(path.read_text().splitlines())


def _folder_rows(folder: Path) -> list[str]:
    rows = []
    for path in sorted(folder.iterdir()):
        if path.name == "__pycache__":
            continue
        rel = path.relative_to(ROOT).as_posix()
        if path.is_dir() and (path / "__init__.py").is_file():
            rows.append(f"| `{rel}/` | | {_summary_line(path / '__init__.py')} |")
            rows += _folder_rows(path)
        elif path.suffix == ".py" and path.name != "__init__.py":
            rows.append(f"| `{rel}` | {_lines(path)} | {_summary_line(path)} |")
    return rows


def layout() -> list[str]:
    """The layers, their folders and every module with its size and summary."""
    out = ["| layer | folder | modules | what it is |", "| --- | --- | --- | --- |"]
    for i, group in enumerate(import_graph.LAYERS):
        for name in group:
            folder = PKG / name
            if folder.is_dir():
                n = sum(1 for p in folder.rglob("*.py") if p.name != "__init__.py")
                out.append(f"| {i} | `{name}/` | {n} | {_summary_line(folder / '__init__.py')} |")
            else:
                out.append(
                    f"| {i} | `{name}.py` | 1 | {_summary_line(folder.with_suffix('.py'))} |"
                )
    out += ["", "| module | lines | what it is |", "| --- | --- | --- |"]
    for group in import_graph.LAYERS:
        for name in group:
            folder = PKG / name
            if folder.is_dir():
                out += _folder_rows(folder)
            else:
                path = folder.with_suffix(".py")
                rel = path.relative_to(ROOT).as_posix()
                out.append(f"| `{rel}` | {_lines(path)} | {_summary_line(path)} |")
    return out


def sizes() -> list[str]:
    """Module and function sizes: totals, the largest, and any over the limits."""
    s = code_size.measure(".")
    over_m = [m for m in s.modules if m[1] > LONG_MODULE]
    over_f = [f for f in s.functions if f[1] > LONG_FUNCTION]
    out = [
        "| | count |",
        "| --- | --- |",
        f"| modules | {len(s.modules)} |",
        f"| lines | {sum(n for _, n in s.modules):,} |",
        f"| modules over {LONG_MODULE} lines | {len(over_m)} |",
        f"| functions | {len(s.functions)} |",
        f"| functions over {LONG_FUNCTION} code lines | {len(over_f)} |",
        "",
        "| largest modules | lines | longest functions (code lines) | lines |",
        "| --- | --- | --- | --- |",
    ]
    for (m, ml), (f, fl) in zip(s.modules[:TOP], s.functions[:TOP], strict=True):
        out.append(f"| `{m}` | {ml} | `{f}` | {fl} |")
    return out


def imports() -> list[str]:
    """The import graph between layers, and what breaks the house rules."""
    imps = import_graph.all_imports()
    edges = import_graph.edges(imps)
    found = import_graph.cycles(edges)
    inner = import_graph.function_imports(imps)
    private = import_graph.private_imports(imps)
    out = [*import_graph.layer_table(edges), ""]
    out.append(
        f"{len(edges)} import edges; {len(import_graph.violations(edges))} upward; "
        f"{len(found)} cycles; {len(inner)} imports inside functions (optional extras "
        f"and the measured on-use imports left out); {len(private)} private names imported "
        "across modules."
    )
    for comp in found:
        out.append(f"- cycle: {' <-> '.join(f'`{m}`' for m in comp)}")
    return out


BLOCKS = {"layout": layout, "sizes": sizes, "imports": imports}


def render(text: str) -> str:
    """``text`` with every generated block rewritten."""
    for name, make in BLOCKS.items():
        pattern = re.compile(
            rf"(<!-- generated:{name} -->\n).*?(<!-- /generated:{name} -->)", re.DOTALL
        )
        if not pattern.search(text):
            raise SystemExit(f"architecture: {PAGE} has no generated:{name} block")
        body = "\n".join(make()) + "\n"
        text = pattern.sub(lambda m, b=body: m.group(1) + b + m.group(2), text)
    return text


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="exit 1 if the page is out of date")
    args = ap.parse_args(argv)
    old = PAGE.read_text()
    new = render(old)
    if args.check:
        if new != old:
            print(
                f"{PAGE.relative_to(ROOT)} is out of date: run python scripts/architecture.py",
                file=sys.stderr,
            )
            return 1
        return 0
    PAGE.write_text(new)
    return 0


if __name__ == "__main__":
    sys.exit(main())
