"""A scenario's identity: the fields that decide what it plans, and their hash.

Benchmark runs are keyed by it and roadmaps are tied to it.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from dexplan.core.files import file_sha256
from dexplan.model.scenario.spec import Scenario

__all__ = ["COSMETIC_FIELDS", "scenario_description", "scenario_hash"]

#: Fields of a scenario that name or place it without changing its problem.
COSMETIC_FIELDS = ("name", "base_dir")


def _json_value(value: Any) -> Any:
    """JSON-ready view of scenario fields (arrays as lists, paths as strings)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _json_value(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, Mapping):
        return {str(k): _json_value(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_value(v) for v in value]
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    return value


def _digest_or_mark(path: Path) -> str:
    try:
        return file_sha256(path)
    except OSError:
        return f"unreadable:{path}"


def scenario_description(scenario: Scenario, *, models_only: bool = False) -> dict[str, Any]:
    """The fields that decide what a scenario plans, as plain JSON values.

    The one scenario identity: benchmark runs are keyed by it, and roadmaps
    (``models_only``) are tied to it. Cosmetic fields are left out (the
    scenario's name and folder, obstacle names), and so are the planner
    name, seed and time limit (a sweep sets them); files the scenario refers
    to (URDF, meshes) enter by their SHA-256. The contact model and torsion
    enter when the model is not the default ``point``, ``hand.root_link``
    when it is given.

    Args:
        scenario: the scenario.
        models_only: only the models a GSn roadmap depends on (hand, object,
            obstacles, friction, contact model and margin), not the query
            (start, goal, workspace, planner parameters).
    """
    doc = _json_value(scenario)
    for key in COSMETIC_FIELDS:
        doc.pop(key, None)
    for ob in doc["obstacles"]:
        ob.pop("name", None)
    if doc.get("contact_model", "point") == "point":
        doc.pop("contact_model", None)
        doc.pop("torsion", None)
    if doc["hand"].get("root_link") is None:  # absent: the hashes of before it existed
        doc["hand"].pop("root_link", None)
    doc["planner"] = {k: v for k, v in doc["planner"].items() if k in ("params", "space")}
    if scenario.hand.urdf is not None:
        doc["hand"]["urdf"] = _digest_or_mark(Path(scenario.base_dir) / scenario.hand.urdf)
    if scenario.hand.mjcf is not None:  # by content: a wheel's file sits anywhere
        doc["hand"]["mjcf"] = _digest_or_mark(Path(scenario.base_dir) / scenario.hand.mjcf)
    for shape in [doc["object"], *doc["obstacles"]]:
        if isinstance(shape, dict) and "path" in shape:
            shape["path_sha256"] = _digest_or_mark(Path(scenario.base_dir) / str(shape["path"]))
    if models_only:
        for key in ("start", "goal", "planner", "workspace_half_extent"):
            doc.pop(key, None)
    return doc


def scenario_hash(scenario: Scenario, *, models_only: bool = False) -> str:
    """Short content hash (16 hex digits) of :func:`scenario_description`."""
    text = json.dumps(scenario_description(scenario, models_only=models_only), sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]
