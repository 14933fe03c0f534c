"""Shared fixtures: the builtin hand, the paper scenario and its planning context."""

from __future__ import annotations

import pytest

from dexplan.hand import Hand


@pytest.fixture(scope="session")
def paper_hand() -> Hand:
    return Hand.builtin("paper")
