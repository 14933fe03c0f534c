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
def paper_plan(tmp_path_factory: pytest.TempPathFactory) -> Callable[[int, Path], Path]:
    """``copy(seed, folder)``: the builtin scenario's plan of ``seed``, as ``folder/plan.json``.

    ``dexplan plan --seed N -q`` runs once per seed for the whole session (the
    export, forces, timing and replay tests read the same plans); every caller gets
    its own copy, so that files it writes beside the plan stay its own.
    """
    from dexplan.cli import main as cli

    made: dict[int, Path] = {}

    def copy(seed: int, folder: Path) -> Path:
        if seed not in made:
            path = tmp_path_factory.mktemp(f"paper_plan_seed{seed}") / "plan.json"
            # a generous limit: the plans take a few seconds; a slow machine must not fail them
            args = ["plan", "--seed", str(seed), "--time-limit", "300", "-q", "-o", str(path)]
            assert cli.run(args) == 0
            made[seed] = path
        out = Path(folder) / "plan.json"
        shutil.copyfile(made[seed], out)
        return out

    return copy
