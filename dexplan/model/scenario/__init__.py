"""Scenario files: the hand, object, obstacles, start, goal and planner; goal lists."""

__all__ = [
    "goals",
    "scenario",
]
