"""The lazy ``rerun`` import, recording streams, timelines, colours and entity paths.

Every module of :mod:`dexplan.viz` reaches rerun through :func:`rerun_module`,
inside functions, so importing the package never imports rerun.
"""

from __future__ import annotations

import uuid
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from enum import StrEnum
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from dexplan.core.errors import DependencyError
from dexplan.core.files import atomic_output
from dexplan.core.typing import FloatArray

if TYPE_CHECKING:  # rerun's types for annotations; at run time rerun loads on first use
    import rerun
    import rerun.blueprint

#: Oldest rerun-sdk whose API and ``.rrd`` format this package is written for.
MIN_RERUN_VERSION: tuple[int, int] = (0, 41)
#: Rerun application id of every dexplan recording (the viewer keys layouts on it).
APPLICATION_ID = "dexplan"
#: Seconds per waypoint on the ``time`` timeline.
STEP_SECONDS = 0.05

INSTALL_HINT = "pip install 'dexplan[viz]'"

# Colours (RGBA).
GREY = (170, 174, 184, 255)
PALM = (120, 124, 134, 255)
OBJECT = (90, 150, 230, 200)
GOAL = (60, 200, 90, 255)
OBSTACLE = (150, 120, 90, 255)
LINK_COLOR = (230, 40, 200, 255)
FINGERS = (
    (230, 80, 60, 255),
    (250, 170, 30, 255),
    (60, 180, 90, 255),
    (150, 90, 220, 255),
    (40, 170, 200, 255),
    (220, 110, 170, 255),
)
COMPONENTS = (
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (127, 127, 127),
    (188, 189, 34),
    (23, 190, 207),
)


class Timeline(StrEnum):
    """The timelines of dexplan's recordings (a member equals its name)."""

    PLAN_STEP = "plan_step"
    """One step per waypoint of a plan (sequence)."""
    TIME = "time"
    """Seconds: :data:`STEP_SECONDS` per plan step, or a replay's time (duration)."""
    ROADMAP_NODE = "roadmap_node"
    """One step per roadmap vertex (sequence)."""
    REJECTED_SAMPLE = "rejected_sample"
    """One step per state a validity checker rejected (sequence)."""


PLAN_STEP = Timeline.PLAN_STEP
TIME = Timeline.TIME
ROADMAP_NODE = Timeline.ROADMAP_NODE
REJECTED_SAMPLE = Timeline.REJECTED_SAMPLE


def require_rerun() -> None:
    """Check that a usable rerun-sdk is installed.

    Raises:
        DependencyError: rerun-sdk is missing or older than
            :data:`MIN_RERUN_VERSION`; the message says what to install.

    """
    rerun_module()


def rerun_module() -> ModuleType:
    """Import and return the ``rerun`` module.

    Returns:
        The ``rerun`` module.

    Raises:
        DependencyError: rerun-sdk is missing or older than :data:`MIN_RERUN_VERSION`.
    """
    try:
        import rerun as rr
    except ImportError as exc:
        raise DependencyError(
            f"Rerun recordings need rerun-sdk, which is not installed: {INSTALL_HINT}"
        ) from exc
    version = str(getattr(rr, "__version__", "0"))
    parts = [int(p) for p in version.split(".")[:2] if p.isdigit()]
    if tuple(parts) < MIN_RERUN_VERSION:
        need = ".".join(str(v) for v in MIN_RERUN_VERSION)
        raise DependencyError(
            f"Rerun recordings need rerun-sdk >= {need}, found {version}: "
            f"pip install -U 'rerun-sdk>={need}'"
        )
    return rr


@contextmanager
def recording(
    path: str | Path, name: str, blueprint: rerun.blueprint.Blueprint
) -> Iterator[rerun.RecordingStream]:
    """Yield a recording stream whose data lands in ``path`` once the block succeeds.

    The stream saves to a temporary file beside ``path`` (with ``blueprint``
    as its active and default layout); on success the file is renamed onto
    ``path``, so a reader never sees half a recording, and on error it is
    removed.

    Args:
        path: the ``.rrd`` file.
        name: the recording's name, shown by the viewer.
        blueprint: the layout (a ``rerun.blueprint.Blueprint``).

    Yields:
        The ``rerun.RecordingStream``.
    """
    rr = rerun_module()
    path = Path(path)
    with atomic_output(path, "recording") as tmp:
        rec = rr.RecordingStream(APPLICATION_ID, recording_id=uuid.uuid4())
        try:
            rec.save(str(tmp))
            rec.set_log_time_enabled(False)
            rec.set_log_tick_enabled(False)
            rec.send_recording_name(name)
            rec.send_blueprint(blueprint, make_active=True, make_default=True)
            yield rec
        finally:
            rec.flush()
            rec.disconnect()


def rgba(c: Sequence[int]) -> list[int]:
    """A colour as a list of ints (what rerun's colour fields take)."""
    return [int(v) for v in c]


def finger_color(i: int) -> tuple[int, int, int, int]:
    """The colour of finger ``i`` (the palette repeats past six fingers)."""
    return FINGERS[i % len(FINGERS)]


def entity(*parts: str) -> str:
    """Entity path from raw names (each part escaped)."""
    rr = rerun_module()
    return "/".join(rr.escape_entity_path_part(p) for p in parts)


def transform(pose: FloatArray) -> rerun.Transform3D:
    """A ``rr.Transform3D`` of a pose ``pose_xyzquat: (7,)`` = ``[x, y, z, qx, qy, qz, qw]``."""
    rr = rerun_module()
    return rr.Transform3D(translation=pose[:3], quaternion=pose[3:])


def plan_index(steps: npt.ArrayLike) -> list[rerun.TimeColumn]:
    """The ``plan_step`` and ``time`` columns of the given steps ``(S,)``."""
    rr = rerun_module()
    step_numbers = np.asarray(steps, dtype=np.int64)
    return [
        rr.TimeColumn(PLAN_STEP, sequence=step_numbers),
        rr.TimeColumn(TIME, duration=step_numbers * STEP_SECONDS),
    ]


def set_step(rec: rerun.RecordingStream, step: int) -> None:
    """Set the stream's ``plan_step`` and ``time`` to one step."""
    rec.set_time(PLAN_STEP, sequence=step)
    rec.set_time(TIME, duration=step * STEP_SECONDS)
