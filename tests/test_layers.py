"""The package's layers point down: models <- (plan file | planning) <- callers."""

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


def test_no_import_points_upwards():
    g = _graph()
    assert g.violations(g.edges()) == []


def test_the_checker_sees_an_upward_import():
    g = _graph()
    assert g.violations(
        [("dexplan.planning.planner", "dexplan.plan_file")]
    )  # planning -> plan file
    assert g.violations([("dexplan.plan_file", "dexplan.planning.path")])  # and back
    assert g.violations([("dexplan.hand", "dexplan.planning.sampler")])
    assert not g.violations([("dexplan.api", "dexplan.plan_file")])
