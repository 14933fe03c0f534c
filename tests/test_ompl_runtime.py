"""Tests of dexplan.planning.ompl.runtime: OMPL's log level."""

from __future__ import annotations

import pytest

from dexplan.core.errors import InvalidInputError
from dexplan.planning.ompl import get_log_level, set_log_level


def test_log_level_roundtrip():
    assert get_log_level() == "none"
    set_log_level("debug")
    try:
        assert get_log_level() == "debug"
    finally:
        set_log_level("none")
    with pytest.raises(InvalidInputError):
        set_log_level("loud")
