"""Shared fixtures: the builtin hand and the builtin scenario's plans, made once a session.

Hypothesis profiles: ``default`` (CI: a few hundred examples per input format
in all, well within two minutes) and ``thorough`` (thousands; select it with
``HYPOTHESIS_PROFILE=thorough`` or run the slow tests, ``-m slow``).
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

from dexplan.model.hand.hand import Hand

settings.register_profile(
    "default",
    max_examples=60,
    deadline=None,  # no test may depend on how fast the machine is
    derandomize=True,  # CI runs the same examples every time
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
settings.register_profile(
    "thorough",
    max_examples=1500,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))


@pytest.fixture(scope="session")
def paper_hand() -> Hand:
    return Hand.builtin("paper")


@pytest.fixture(scope="session")
def paper_plan(tmp_path_factory: pytest.TempPathFactory) -> Callable[..., Path]:
    """``copy(seed, folder, motion=None)``: the builtin plan of ``seed``, as ``folder/plan.json``.

    ``dexplan plan --seed N -q`` runs once per seed and contact motion for the
    whole session (the export, forces, timing and replay tests read the same
    plans); every caller gets its own copy, so that files it writes beside the
    plan stay its own. ``motion="fixed"`` plans the builtin scenario with
    ``[contact] motion = "fixed"`` (the paper's fixed contacts; the builtin
    rolls): tests of what only fixed contacts do ask for it.
    """
    from dexplan.cli import main as cli
    from dexplan.model.scenario import builtin_scenario_path

    made: dict[tuple[int, str | None], Path] = {}

    def copy(seed: int, folder: Path, motion: str | None = None) -> Path:
        if (seed, motion) not in made:
            where = tmp_path_factory.mktemp(f"paper_plan_seed{seed}_{motion or 'builtin'}")
            path = where / "plan.json"
            scenario = []
            if motion is not None:
                text = builtin_scenario_path("paper_sphere").read_text()
                assert 'motion = "rolling"' in text
                toml = where / "paper_sphere.toml"
                toml.write_text(text.replace('motion = "rolling"', f'motion = "{motion}"'))
                scenario = [str(toml)]
            # a generous limit: the plans take a few seconds; a slow machine must not fail them
            args = ["plan", *scenario, "--seed", str(seed), "--time-limit", "300", "-q", "-o"]
            assert cli.run([*args, str(path)]) == 0
            made[(seed, motion)] = path
        out = Path(folder) / "plan.json"
        shutil.copyfile(made[(seed, motion)], out)
        return out

    return copy
