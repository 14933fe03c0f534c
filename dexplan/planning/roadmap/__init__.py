"""Roadmaps (paper, section V): module 1, module 2, the roadmap file, multi-query."""

__all__ = [
    "file",
    "learning",
    "queries",
    "roadmap",
    "tasks",
]
