"""Module sizes and the longest functions of the dexplan package at two revisions.

    python scripts/code_size.py                          # HEAD vs the working tree
    python scripts/code_size.py --before A --after B     # any two git revisions
    python scripts/code_size.py --top 20                 # longer tables

Prints Markdown: a summary, the largest modules and the longest functions, each
side by side. The files are read with ``git show REV:path`` (the working tree for
``.``), so the figures do not depend on what is checked out.

What is counted: a module's lines are its physical lines (``wc -l``); a
function's length is its code lines, from the ``def`` line to its last line
without its docstring (nested functions count in their parent too, and again
on their own). Functions and methods are named ``module:Class.method``.
"""

from __future__ import annotations

import argparse
import ast
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The default "before": the last commit.
BEFORE = "HEAD"
#: No function should be longer than this (code lines, docstring left out).
LONG_FUNCTION = 60
#: No module should be longer than this (lines).
LONG_MODULE = 600


@dataclass(frozen=True)
class Sizes:
    """The package at one revision: ``modules`` (path, lines), ``functions`` (name, lines)."""

    rev: str
    modules: list[tuple[str, int]]
    functions: list[tuple[str, int]]


def _git(*args: str) -> str:
    out = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, check=False)
    if out.returncode != 0:
        sys.exit(f"code_size: git {' '.join(args)}: {out.stderr.strip()}")
    return out.stdout


def _sources(rev: str) -> dict[str, str]:
    """Every ``dexplan/**/*.py`` at ``rev`` (``.``: the working tree), path -> text."""
    if rev == ".":
        return {
            str(p.relative_to(ROOT)): p.read_text()
            for p in sorted((ROOT / "dexplan").rglob("*.py"))
        }
    paths = [
        p for p in _git("ls-tree", "-r", "--name-only", rev, "dexplan").split() if p.endswith(".py")
    ]
    return {p: _git("show", f"{rev}:{p}") for p in paths}


def _docstring_lines(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    first = node.body[0] if node.body else None
    if (
        isinstance(first, ast.Expr)
        and isinstance(first.value, ast.Constant)
        and isinstance(first.value.value, str)
    ):
        return (first.end_lineno or first.lineno) - first.lineno + 1
    return 0


def _functions(module: str, text: str) -> list[tuple[str, int]]:
    """``(module:qualified.name, code lines)`` of every function in ``text``."""
    out: list[tuple[str, int]] = []

    def walk(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                length = (child.end_lineno or child.lineno) - child.lineno + 1
                out.append((f"{module}:{prefix}{child.name}", length - _docstring_lines(child)))
                walk(child, f"{prefix}{child.name}.")
            elif isinstance(child, ast.ClassDef):
                walk(child, f"{prefix}{child.name}.")
            else:
                walk(child, prefix)

    walk(ast.parse(text), "")
    return out


def measure(rev: str) -> Sizes:
    """Module and function sizes of the package at ``rev``, longest first."""
    modules: list[tuple[str, int]] = []
    functions: list[tuple[str, int]] = []
    for path, text in _sources(rev).items():
        name = path.removesuffix(".py").replace("/", ".")
        modules.append((path, len(text.splitlines())))
        functions += _functions(name, text)
    modules.sort(key=lambda m: (-m[1], m[0]))
    functions.sort(key=lambda f: (-f[1], f[0]))
    return Sizes(rev, modules, functions)


def _summary(a: Sizes, b: Sizes) -> list[str]:
    def row(label: str, fa: object, fb: object) -> str:
        return f"| {label} | {fa} | {fb} |"

    def over(s: Sizes, limit: int, items: str) -> int:
        return sum(n > limit for _, n in getattr(s, items))

    return [
        f"| | before ({a.rev}) | after ({b.rev}) |",
        "| --- | --- | --- |",
        row("modules", len(a.modules), len(b.modules)),
        row("lines", f"{sum(n for _, n in a.modules):,}", f"{sum(n for _, n in b.modules):,}"),
        row(
            "largest module",
            f"`{a.modules[0][0]}` {a.modules[0][1]:,}",
            f"`{b.modules[0][0]}` {b.modules[0][1]:,}",
        ),
        row(
            f"modules over {LONG_MODULE:,} lines",
            over(a, LONG_MODULE, "modules"),
            over(b, LONG_MODULE, "modules"),
        ),
        row("functions", len(a.functions), len(b.functions)),
        row(
            f"functions over {LONG_FUNCTION} code lines",
            over(a, LONG_FUNCTION, "functions"),
            over(b, LONG_FUNCTION, "functions"),
        ),
        row(
            "longest function",
            f"`{a.functions[0][0]}` {a.functions[0][1]}",
            f"`{b.functions[0][0]}` {b.functions[0][1]}",
        ),
    ]


def _side_by_side(
    title: str, a: list[tuple[str, int]], b: list[tuple[str, int]], top: int
) -> list[str]:
    lines = [
        f"| # | {title} before | lines | {title} after | lines |",
        "| --- | --- | --- | --- | --- |",
    ]
    for i in range(min(top, max(len(a), len(b)))):
        ca = f"`{a[i][0]}` | {a[i][1]:,}" if i < len(a) else " | "
        cb = f"`{b[i][0]}` | {b[i][1]:,}" if i < len(b) else " | "
        lines.append(f"| {i + 1} | {ca} | {cb} |")
    return lines


def report(before: str, after: str, top: int) -> str:
    """The Markdown report comparing ``before`` and ``after``."""
    a, b = measure(before), measure(after)
    parts = [
        "### Summary",
        "",
        *_summary(a, b),
        "",
        "### Largest modules",
        "",
        *_side_by_side("module", a.modules, b.modules, top),
        "",
        f"### Longest functions (code lines, docstrings left out; limit {LONG_FUNCTION})",
        "",
        *_side_by_side("function", a.functions, b.functions, top),
    ]
    return "\n".join(parts) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", default=BEFORE, help=f"git revision (default {BEFORE})")
    ap.add_argument(
        "--after", default=".", help="git revision, or . for the working tree (default)"
    )
    ap.add_argument("--top", type=int, default=12, help="rows per table (default 12)")
    args = ap.parse_args(argv)
    if args.top < 1:
        print(f"code_size: --top must be at least 1, got {args.top}", file=sys.stderr)
        return 2
    sys.stdout.write(report(args.before, args.after, args.top))
    return 0


if __name__ == "__main__":
    sys.exit(main())
