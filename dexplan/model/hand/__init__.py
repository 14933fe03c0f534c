"""Hands: Pinocchio models, builtin hands, URDF loading, inverse kinematics, reach."""

__all__ = [
    "builtin",
    "hand",
    "ik",
    "reach",
    "urdf",
]
