"""The front door's names: callable after first use, and named in docs/api.md."""

from __future__ import annotations

import re
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_plan_stays_the_function_after_the_api_is_loaded() -> None:
    # the plan-file module is dexplan.planfile.document: no submodule shadows the front
    # door's dexplan.plan, in whatever order things are imported
    code = textwrap.dedent(
        """
        import types
        import dexplan.api, dexplan.planfile.document, dexplan.planning.planner
        import dexplan
        dexplan.load_scenario
        for name in ("plan", "verify", "load_scenario", "Plan"):
            value = getattr(dexplan, name)
            assert callable(value) and not isinstance(value, types.ModuleType), name
        from dexplan.planfile.document import read_plan  # the plan-file module is still importable
        assert callable(read_plan)
        """
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT, timeout=120)


API_DOC = ROOT / "docs" / "api.md"


def _mentioned(name: str) -> bool:
    return re.search(rf"\b{re.escape(name)}\b", API_DOC.read_text()) is not None


def test_api_page_names_every_exported_name() -> None:
    import dexplan
    import dexplan.api

    missing = [n for n in {*dexplan.__all__, *dexplan.api.__all__} if not _mentioned(n)]
    assert not missing, f"docs/api.md does not mention {missing}"


def test_api_page_names_every_status_stage_field_and_exception() -> None:
    import dataclasses
    import inspect

    from dexplan.core import errors as exceptions
    from dexplan.planning.planner import PlanResult
    from dexplan.planning.progress import PlanStatus, ProgressEvent, Stage
    from dexplan.planning.stats import PlanStats

    names = [m.name for m in PlanStatus] + [m.value for m in PlanStatus]
    names += [m.name for m in Stage]
    for cls in (PlanResult, PlanStats, ProgressEvent):
        names += [f.name for f in dataclasses.fields(cls)]
    names += [
        n
        for n, c in inspect.getmembers(exceptions, inspect.isclass)
        if issubclass(c, Exception) and c.__module__ == exceptions.__name__
    ]
    missing = [n for n in names if not _mentioned(n)]
    assert not missing, f"docs/api.md does not mention {missing}"
