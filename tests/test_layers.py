"""The package's layers are its folders, and they point down (scripts/import_graph.py)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _graph():
    spec = importlib.util.spec_from_file_location(
        "import_graph", ROOT / "scripts" / "import_graph.py"
    )
    mod = importlib.util.module_from_spec(spec)
    sys.modules["import_graph"] = mod
    spec.loader.exec_module(mod)
    return mod


def test_every_folder_of_the_package_is_a_layer():
    g = _graph()
    tops = {
        p.name if p.is_dir() else p.stem
        for p in (ROOT / "dexplan").iterdir()
        if (p.is_dir() and (p / "__init__.py").is_file())
        or (p.suffix == ".py" and p.stem != "__init__")
    }
    assert {t for t in tops if g.layer_of(t) is None} == set()


def test_no_import_points_upwards():
    g = _graph()
    assert g.violations(g.edges()) == []


def test_the_checker_sees_an_upward_import():
    g = _graph()
    assert g.violations(
        [("dexplan.planning.planner", "dexplan.planfile.document")]
    )  # planning -> plan file
    assert g.violations([("dexplan.planfile.document", "dexplan.planning.path")])  # and back
    assert g.violations([("dexplan.model.hand.hand", "dexplan.planning.gsn.sampler")])
    assert g.violations([("dexplan.core.pose", "dexplan.model.objects")])
    assert g.violations([("dexplan.execution.export", "dexplan.cli.main")])
    assert not g.violations([("dexplan.api", "dexplan.planfile.document")])
    assert not g.violations([("dexplan.cli.main", "dexplan.bench")])


def test_the_checker_sees_a_cycle():
    g = _graph()
    assert g.cycles(
        [("dexplan.a", "dexplan.b"), ("dexplan.b", "dexplan.c"), ("dexplan.c", "dexplan.a")]
    )
    assert not g.cycles([("dexplan.a", "dexplan.b"), ("dexplan.a", "dexplan.c")])


def test_no_cycle_no_private_import_no_import_inside_a_function():
    g = _graph()
    imports = g.all_imports()
    assert g.cycles(g.edges(imports)) == []
    assert [(i.src, i.dst, i.names) for i in g.private_imports(imports)] == []
    assert [(i.src, i.line, i.dst) for i in g.function_imports(imports)] == []


def test_every_package_declares_its_public_names():
    missing = [
        str(p.relative_to(ROOT))
        for p in sorted((ROOT / "dexplan").rglob("__init__.py"))
        if "__all__" not in p.read_text()
    ]
    assert missing == []
