"""Foundations every layer uses: errors, array types, atomic files, poses, path segments."""

__all__ = [
    "errors",
    "files",
    "native_output",
    "pose",
    "segments",
    "typing",
]
