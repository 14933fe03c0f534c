"""Recordings of the states a validity checker rejected (``dexplan plan --debug-rrd``)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from dexplan.model.scenario import Scenario
from dexplan.planning.gsn.validity import RejectedSample
from dexplan.viz.blueprints import rejections_blueprint
from dexplan.viz.scene import log_scene_static, scene_from_scenario, send_configurations
from dexplan.viz.session import REJECTED_SAMPLE, recording, rerun_module


def record_rejections(
    samples: Sequence[RejectedSample], path: str | Path, *, scenario: Scenario
) -> int:
    """Write a Rerun recording of states the validity checker rejected (``--debug-rrd``).

    Each sample (a :class:`~dexplan.planning.gsn.validity.RejectedSample`) is one
    step of the ``rejected_sample`` timeline: the hand and the object at that
    state, with its reason and detail (the colliding pair, the force-closure
    quality) as a text entry, so the user sees why the sampler's states fail.

    Args:
        samples: the rejected states, e.g. ``PlanResult.rejections.samples``.
        path: output ``.rrd`` file.
        scenario: the :class:`~dexplan.model.scenario.scenario.Scenario` they belong to.

    Returns:
        The number of samples recorded.

    Raises:
        DependencyError: rerun-sdk missing.
        InvalidInputError: the output folder does not exist.
    """
    rr = rerun_module()
    models = scene_from_scenario(scenario)
    assert models.hand is not None
    X = np.array([s.x for s in samples], dtype=float).reshape(-1, 7 + models.hand.nq)
    with recording(path, "dexplan rejected samples", rejections_blueprint()) as rec:
        layout = log_scene_static(rec, models)
        if len(X):
            steps = np.arange(len(X), dtype=np.int64)
            idx = [rr.TimeColumn(REJECTED_SAMPLE, sequence=steps)]
            send_configurations(rec, models, layout, idx, X[:, :7], X[:, 7:])
            for k, smp in enumerate(samples):
                rec.set_time(REJECTED_SAMPLE, sequence=k)
                text = smp.reason + (f": {smp.detail}" if smp.detail else "")
                rec.log("rejected", rr.TextLog(text, level=rr.TextLogLevel.WARN))
    return len(X)
