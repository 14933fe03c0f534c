"""The physical models: the hand, the object, contacts and force closure, collisions, scenarios."""

__all__ = [
    "collision",
    "grasp",
    "hand",
    "objects",
    "scenario",
]
