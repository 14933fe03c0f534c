"""Shared fixtures: the builtin hand, the paper scenario and its planning context.

Hypothesis profiles: ``default`` (CI: a few hundred examples per input format
in all, well within two minutes) and ``thorough`` (thousands; select it with
``HYPOTHESIS_PROFILE=thorough`` or run the slow tests, ``-m slow``).
"""

from __future__ import annotations

import os

import pytest
from hypothesis import HealthCheck, settings

from dexplan.hand import Hand

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
