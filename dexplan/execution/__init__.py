"""Executing a plan: time parameterisation, grip forces, trajectories, their files, replay."""

__all__ = [
    "check",
    "export",
    "forces",
    "replay",
    "segment_timing",
    "timing",
    "trajectory",
]
