"""The package's import graph: layers from its folders, cycles, and imports that break the rules.

The layers are the package's top-level folders (and the front door, ``api``),
lowest first; a module may import its own folder and the layers below it:

0. ``core``: errors, array types, files, poses, path segments
1. ``model``: hands, objects, grasps and force closure, collisions, scenarios
2. ``planfile`` | ``planning``: the plan file, and the planner (with ``ompl``)
3. ``execution`` | ``viz`` | ``api`` | ``ompl``: timing, forces, export, replay; Rerun; the
   front door; the public OMPL surface (re-exports, never imports ``ompl`` itself)
4. ``bench``: benchmark sweeps
5. ``cli``: the command line

The plan file and planning know nothing of each other (callers build, write
and verify plans): an arrow between them either way is a violation, as is any
arrow to a higher layer. ``ompl`` is imported only in ``dexplan/planning/ompl/``,
``rerun`` only in ``dexplan/viz/``, ``mujoco`` and ``coacd`` only in
``dexplan/execution/replay/``.

    python scripts/import_graph.py          # edges between layers, cycles, violations
    python scripts/import_graph.py --dot    # Graphviz of folder-level edges
"""

from __future__ import annotations

import argparse
import ast
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "dexplan"

#: The layers, lowest first: each a group of top-level folders (or modules).
LAYERS: tuple[tuple[str, ...], ...] = (
    ("core",),
    ("model",),
    ("planfile", "planning"),
    ("execution", "viz", "api", "ompl"),
    ("bench",),
    ("cli",),
)
#: Pairs of one layer that must not import each other.
APART: frozenset[frozenset[str]] = frozenset({frozenset({"planfile", "planning"})})
#: Third-party packages confined to one place: package -> module prefix allowed.
CONFINED: dict[str, str] = {
    "ompl": "dexplan.planning.ompl",
    "rerun": "dexplan.viz",
    "mujoco": "dexplan.execution.replay",
    "coacd": "dexplan.execution.replay",
}
#: Imports allowed inside a function: optional extras, loaded only on use.
OPTIONAL: tuple[str, ...] = ("rerun", "mujoco", "coacd", "ray", "matplotlib", "example_robot_data")
#: Other imports allowed inside a function, each for a reason its comment in the code gives.
ON_USE: frozenset[tuple[str, str]] = frozenset(
    {
        ("dexplan", "dexplan.api"),  # the front door's start-up cost (measured)
        # dexplan.model.hand loads Pinocchio (measured), which validating a scenario does not need
        ("dexplan.model.scenario.hand_table", "dexplan.model.hand.builtin"),
        ("dexplan.model.scenario.hand_table", "dexplan.model.hand.packages"),
        ("dexplan.model.grasp.least_distance", "scipy.optimize._slsqplib"),  # guarded private API
        ("dexplan.model.grasp.ratio_lp", "scipy.optimize._highspy"),  # guarded private API
    }
)


def layer_of(top_name: str) -> int | None:
    """The layer index of a top-level folder or module (None: in no layer)."""
    for i, group in enumerate(LAYERS):
        if top_name in group:
            return i
    return None


def module_of(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def top(module: str) -> str:
    """``dexplan.planning.ompl.problem`` -> ``planning``."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def _is_module(dotted: str) -> bool:
    rel = Path(*dotted.split(".")[1:]) if "." in dotted else Path()
    return (PKG / rel).is_dir() or (PKG / rel).with_suffix(".py").is_file()


@dataclass(frozen=True)
class Import:
    """One ``import`` of a dexplan module: where, what, and whether in a function."""

    src: str
    dst: str
    names: tuple[str, ...]
    in_function: bool
    line: int


def _imports_of(path: Path) -> list[Import]:
    src = module_of(path)
    tree = ast.parse(path.read_text())
    out: list[Import] = []

    def visit(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            inside = in_function or isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef)
            if isinstance(child, ast.Import):
                for a in child.names:
                    out.append(Import(src, a.name, (), in_function, child.lineno))
            elif isinstance(child, ast.ImportFrom) and child.module and child.level == 0:
                names = tuple(a.name for a in child.names)
                if child.module.startswith("dexplan"):
                    subs = [n for n in names if _is_module(f"{child.module}.{n}")]
                    for n in subs:
                        out.append(
                            Import(src, f"{child.module}.{n}", (), in_function, child.lineno)
                        )
                    rest = tuple(n for n in names if n not in subs)
                    if rest or not subs:
                        out.append(Import(src, child.module, rest, in_function, child.lineno))
                else:
                    out.append(Import(src, child.module, names, in_function, child.lineno))
            visit(child, inside)

    visit(tree, False)
    return out


def all_imports() -> list[Import]:
    """Every import in every module of the package, function-level ones too."""
    out: list[Import] = []
    for path in sorted(PKG.rglob("*.py")):
        out += _imports_of(path)
    return out


def edges(imports: list[Import] | None = None) -> list[tuple[str, str]]:
    """``(importer, imported)`` pairs of dexplan modules, without self-imports."""
    seen: set[tuple[str, str]] = set()
    for imp in all_imports() if imports is None else imports:
        if imp.dst.startswith("dexplan") and imp.dst != imp.src:
            seen.add((imp.src, imp.dst))
    return sorted(seen)


def violations(all_edges: list[tuple[str, str]]) -> list[str]:
    """Arrows that point upwards, between the apart pairs, or out of any layer."""
    bad = []
    for src, dst in all_edges:
        a, b = top(src), top(dst)
        if a == "" or b == "" or a == b:
            continue
        la, lb = layer_of(a), layer_of(b)
        if la is None or lb is None:
            bad.append(f"{src} -> {dst}: folder not in a layer (add it to LAYERS)")
        elif frozenset({a, b}) in APART:
            bad.append(f"{src} -> {dst}: {a} and {b} must not import each other")
        elif lb > la:
            bad.append(f"{src} ({a}) -> {dst} ({b}): points upwards")
    for imp in all_imports():
        root = imp.dst.split(".")[0]
        allowed = CONFINED.get(root)
        if allowed is not None and not imp.src.startswith(allowed):
            bad.append(f"{imp.src} imports {root} outside {allowed}")
    return bad


def cycles(all_edges: list[tuple[str, str]]) -> list[list[str]]:
    """Strongly connected sets of two or more modules (Tarjan), each sorted.

    A package importing its own submodules (its ``__init__`` re-exporting them)
    is not a cycle unless a submodule imports the package back.
    """
    graph: dict[str, set[str]] = {}
    for a, b in all_edges:
        graph.setdefault(a, set()).add(b)
        graph.setdefault(b, set())
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = [0]

    def strong(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(10_000)
    for v in sorted(graph):
        if v not in index:
            strong(v)
    return sorted(out)


def function_imports(imports: list[Import] | None = None) -> list[Import]:
    """Imports inside functions, except of the optional extras and the ``ON_USE`` pairs."""
    return [
        imp
        for imp in (all_imports() if imports is None else imports)
        if imp.in_function
        and imp.dst.split(".")[0] not in OPTIONAL
        and (imp.src, imp.dst) not in ON_USE
    ]


def private_imports(imports: list[Import] | None = None) -> list[Import]:
    """Imports of ``_private`` names from another dexplan module."""
    return [
        imp
        for imp in (all_imports() if imports is None else imports)
        if imp.dst.startswith("dexplan")
        and imp.dst != imp.src
        and any(n.startswith("_") and not n.startswith("__") for n in imp.names)
    ]


def layer_table(all_edges: list[tuple[str, str]]) -> list[str]:
    """Markdown: import edges between the layers (rows import columns)."""
    names = [" \\| ".join(g) for g in LAYERS]
    by_layer: dict[tuple[int, int], int] = {}
    for src, dst in all_edges:
        la, lb = layer_of(top(src)), layer_of(top(dst))
        if la is not None and lb is not None:
            by_layer[(la, lb)] = by_layer.get((la, lb), 0) + 1
    lines = ["| from \\ to | " + " | ".join(names) + " |", "|---" * (len(names) + 1) + "|"]
    for la, name in enumerate(names):
        row = [str(by_layer.get((la, lb), "")) for lb in range(len(names))]
        lines.append(f"| {name} | " + " | ".join(row) + " |")
    return lines


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dot", action="store_true", help="print a Graphviz graph instead")
    args = ap.parse_args()
    imports = all_imports()
    all_edges = edges(imports)
    if args.dot:
        print("digraph dexplan {\n  rankdir=BT;")
        for src, dst in sorted({(top(a), top(b)) for a, b in all_edges if top(a) != top(b)}):
            if src and dst:
                print(f'  "{src}" -> "{dst}";')
        print("}")
        return 0
    print("\n".join(layer_table(all_edges)))
    bad = violations(all_edges)
    for line in bad:
        print("VIOLATION", line)
    found = cycles(all_edges)
    for comp in found:
        print("CYCLE", " <-> ".join(comp))
    inner = function_imports(imports)
    private = private_imports(imports)
    for imp in private:
        print(f"PRIVATE {imp.src}:{imp.line} imports {', '.join(imp.names)} from {imp.dst}")
    print(
        f"{len(all_edges)} import edges, {len(bad)} violations, {len(found)} cycles, "
        f"{len(inner)} imports inside functions (optional extras and ON_USE left out), "
        f"{len(private)} private imports across modules"
    )
    for imp in inner:
        print(f"IN FUNCTION {imp.src}:{imp.line} imports {imp.dst}")
    return 1 if bad or found or private or inner else 0


if __name__ == "__main__":
    sys.exit(main())
