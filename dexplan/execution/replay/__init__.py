"""Physics replay of a plan in MuJoCo (extra ``sim``), open or closed loop."""

__all__ = [
    "control",
    "mjcf",
    "simulation",
]
