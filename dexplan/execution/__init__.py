"""Executing a plan: time parameterisation, grip forces, trajectory export, replay."""

__all__ = [
    "export",
    "forces",
    "replay",
    "timing",
]
