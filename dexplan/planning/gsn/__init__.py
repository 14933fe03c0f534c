"""The grasp subspace GSn (paper, section III): constraint, chart, sampler, validity."""

__all__ = [
    "chart",
    "combinations",
    "finger_reach",
    "sampler",
    "space",
    "validity",
]
