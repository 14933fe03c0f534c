"""The ``dexplan`` command line."""

__all__ = [
    "main",
    "roadmap",
]
