"""Executing a plan: timing, grip forces, trajectories, their files, replay, plan quality."""

__all__ = [
    "bag",
    "check",
    "export",
    "forces",
    "quality",
    "replay",
    "segment_timing",
    "timing",
    "trajectory",
]
