"""Hands: Pinocchio models, builtin hands, URDF loading, inverse kinematics, reach."""

__all__ = [
    "hand",
    "ik",
    "reach",
    "urdf",
]
