"""The package's import graph by layer, and any arrow that points upwards.

Layers, lowest first (a module may import its own layer and the ones below):

0. foundations: exceptions, typing, files, pose, segments, native_output
1. models: hand, urdf, ik, objects, collision, grasp, grip, scenario
2. the plan file: plan_file, plan_schema, plan_verify
3. planning: dexplan.planning.* (ompl only inside dexplan.planning.ompl)
4. callers: api, timing, forces, replay, viz, bench, cli

The plan file and planning know nothing of each other (DESIGN.md: "planning
never imports it; callers verify"): an arrow between them either way is a
violation, as is any arrow to a higher layer.

    python scripts/import_graph.py          # edges between layers, then violations
    python scripts/import_graph.py --dot    # Graphviz of module-level edges
"""

from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "dexplan"

LAYERS: dict[str, int] = {
    "exceptions": 0, "typing": 0, "files": 0, "pose": 0, "segments": 0, "native_output": 0,
    "hand": 1, "urdf": 1, "ik": 1, "objects": 1, "collision": 1, "grasp": 1, "scenario": 1,
    "goals": 1, "grip": 1, "reach": 1,
    "plan_file": 2, "plan_schema": 2, "plan_verify": 2,
    "planning": 3,
    "api": 4, "timing": 4, "forces": 4, "replay": 4, "viz": 4, "bench": 4, "cli": 4,
    "export": 4, "trajectory": 4, "cli_roadmap": 4, "replay_control": 4,
}  # fmt: skip
NAMES = ["foundations", "models", "plan file", "planning", "callers"]


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


def imports(path: Path) -> set[str]:
    """Every dexplan module imported anywhere in the file (function-level too)."""
    tree = ast.parse(path.read_text())
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name.startswith("dexplan"))
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            if node.module == "dexplan":  # submodules only, not names like __version__
                out.update(
                    f"dexplan.{a.name}"
                    for a in node.names
                    if (PKG / a.name).is_dir() or (PKG / f"{a.name}.py").is_file()
                )
            elif node.module.startswith("dexplan."):
                out.add(node.module)
    return out


def edges() -> list[tuple[str, str]]:
    out = []
    for path in sorted(PKG.rglob("*.py")):
        src = module_of(path)
        for dst in sorted(imports(path)):
            if dst != src:
                out.append((src, dst))
    return out


def violations(all_edges: list[tuple[str, str]]) -> list[str]:
    bad = []
    for src, dst in all_edges:
        a, b = top(src), top(dst)
        if a == "" or b == "" or a == b:
            continue
        la, lb = LAYERS.get(a), LAYERS.get(b)
        if la is None or lb is None:
            bad.append(f"{src} -> {dst}: module not in a layer (add it to LAYERS)")
        elif lb > la and {la, lb} != {2, 3}:
            bad.append(f"{src} ({NAMES[la]}) -> {dst} ({NAMES[lb]}): points upwards")
        elif {la, lb} == {2, 3}:
            bad.append(f"{src} -> {dst}: the plan file and planning must not import each other")
    for path in sorted(PKG.rglob("*.py")):
        mod = module_of(path)
        text = path.read_text()
        if ("import ompl" in text or "from ompl" in text) and not mod.startswith(
            "dexplan.planning.ompl"
        ):
            bad.append(f"{mod} imports ompl outside dexplan.planning.ompl")
    return bad


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dot", action="store_true", help="print a Graphviz graph instead")
    args = ap.parse_args()
    all_edges = edges()
    if args.dot:
        print("digraph dexplan {\n  rankdir=BT;")
        for src, dst in sorted({(top(a), top(b)) for a, b in all_edges if top(a) != top(b)}):
            if src and dst:
                print(f'  "{src}" -> "{dst}";')
        print("}")
        return 0
    by_layer: dict[tuple[int, int], int] = {}
    for src, dst in all_edges:
        la, lb = LAYERS.get(top(src)), LAYERS.get(top(dst))
        if la is not None and lb is not None:
            by_layer[(la, lb)] = by_layer.get((la, lb), 0) + 1
    print("| from \\ to | " + " | ".join(NAMES) + " |")
    print("|---" * (len(NAMES) + 1) + "|")
    for la, name in enumerate(NAMES):
        row = [str(by_layer.get((la, lb), "")) for lb in range(len(NAMES))]
        print(f"| {name} | " + " | ".join(row) + " |")
    bad = violations(all_edges)
    for line in bad:
        print("UPWARD", line)
    print(f"{len(all_edges)} import edges, {len(bad)} violations")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
