"""The front door's names: callable after first use, and documented in docs/api.md."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_plan_stays_the_function_after_the_api_is_loaded() -> None:
    # dexplan/plan.py (the plan-file module) is imported by dexplan.api and
    # binds the attribute dexplan.plan to itself; the front door rebinds it
    code = textwrap.dedent(
        """
        import types
        import dexplan
        dexplan.load_scenario  # loads dexplan.api, hence dexplan/plan.py
        for name in ("plan", "verify", "load_scenario", "Plan"):
            value = getattr(dexplan, name)
            assert callable(value) and not isinstance(value, types.ModuleType), name
        from dexplan.plan import read_plan  # the plan-file module is still importable
        assert callable(read_plan)
        """
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT, timeout=120)
