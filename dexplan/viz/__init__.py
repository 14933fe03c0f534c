"""Rerun recordings of plans and roadmaps (optional extra ``viz``).

This package is the only part of dexplan that imports ``rerun``, and it does
so lazily, inside functions: the planner, the plan files and the CLI work
without rerun-sdk, and asking for a recording without it raises
:class:`~dexplan.core.errors.DependencyError` naming the extra to install.

Three entry points write ``.rrd`` files that the Rerun viewer opens directly:

- :func:`record_plan`: a ``dexplan-plan/2`` document (and optionally the
  roadmap it came from), animated on the ``plan_step`` and ``time`` timelines;
- :func:`record_roadmap`: a GSn roadmap alone, with or without the hand,
  object and obstacles of a plan document or scenario;
- :func:`write_recording`: either of the above from a file name (plan
  ``.json`` or roadmap ``.npz``), as ``dexplan show --save`` needs.

:func:`show` records to a temporary file and opens the native viewer;
:func:`record_rejections` records the states a validity checker rejected and
:func:`~dexplan.viz.replay_recording.record_replay` a physics replay.

The modules, by what they draw:

- :mod:`~dexplan.viz.session`: the lazy rerun import, recording files,
  timelines, colours and entity paths;
- :mod:`~dexplan.viz.shapes`: archetypes of dexplan shapes and coal geometries;
- :mod:`~dexplan.viz.scene`: hand, object, goal and obstacles, static and per
  configuration;
- :mod:`~dexplan.viz.contacts`: contact points, friction cones, force closure;
- :mod:`~dexplan.viz.plan_recording`, :mod:`~dexplan.viz.roadmap_recording`,
  :mod:`~dexplan.viz.rejections`, :mod:`~dexplan.viz.replay_recording`: the
  recordings;
- :mod:`~dexplan.viz.blueprints`: the viewer layouts;
- :mod:`~dexplan.viz.viewer`: recordings from files and the native viewer.

Entity paths, timelines and colours are documented in ``docs/viz.md``. The
world frame is the palm frame, right-handed, z up; all lengths are metres.
"""

from __future__ import annotations

from dexplan.viz.plan_recording import record_plan
from dexplan.viz.rejections import record_rejections
from dexplan.viz.roadmap_recording import RoadmapSummary, record_roadmap, summarize_roadmap
from dexplan.viz.session import (
    APPLICATION_ID,
    INSTALL_HINT,
    MIN_RERUN_VERSION,
    PLAN_STEP,
    REJECTED_SAMPLE,
    ROADMAP_NODE,
    STEP_SECONDS,
    TIME,
    Timeline,
    require_rerun,
)
from dexplan.viz.viewer import show, write_recording

__all__ = [
    "APPLICATION_ID",
    "INSTALL_HINT",
    "MIN_RERUN_VERSION",
    "PLAN_STEP",
    "REJECTED_SAMPLE",
    "ROADMAP_NODE",
    "STEP_SECONDS",
    "TIME",
    "RoadmapSummary",
    "Timeline",
    "record_plan",
    "record_rejections",
    "record_roadmap",
    "require_rerun",
    "show",
    "summarize_roadmap",
    "write_recording",
]
