"""Local planners (paper, section IV): transfers, regrasps, landings, the reduction."""

__all__ = [
    "contact_paths",
    "edge_reduction",
    "geodesic_motion",
    "reduction",
    "smoothing",
    "transitions",
]
