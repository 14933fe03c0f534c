"""Goal lists for multi-query runs: a goals file, or random goals in the workspace.

A goals file is TOML with one ``[[goals]]`` table per query::

    [[goals]]
    object_pose_xyzquat = [0.0, 0.0, 0.1, 0.0, 0.0, 1.0, 0.0]
    position_tol = 0.005   # optional: the scenario's [goal] tolerance
    angle_tol = 0.05       # optional: likewise

It is validated like a scenario: the first bad field is named with its value
in a one-line :class:`~dexplan.core.errors.ScenarioError`.
"""

from __future__ import annotations

import tomllib
from collections.abc import Callable
from enum import StrEnum
from pathlib import Path

import numpy as np

from dexplan.core.errors import InvalidInputError, ScenarioError, one_line, shorten
from dexplan.core.pose import random_quaternion
from dexplan.core.typing import FloatArray
from dexplan.model.scenario.fields import check_only, number, pose
from dexplan.model.scenario.spec import MAX_ANGLE_TOL, MAX_POSITION_TOL, GoalSpec, Scenario

MAX_GOALS = 100_000
"""Most goals one run answers."""

MAX_GOALS_BYTES = 16_000_000
"""Largest goals file."""

GOAL_FIELDS = frozenset({"object_pose_xyzquat", "position_tol", "angle_tol"})


class GoalKind(StrEnum):
    """What random goals vary (members equal their strings).

    ``ORIENTATION``: uniform orientations at the start position; ``POSE``: also
    a uniform position in the ``[workspace]`` box around it.
    """

    ORIENTATION = "orientation"
    POSE = "pose"


GOAL_KINDS: tuple[GoalKind, ...] = tuple(GoalKind)
"""Values of :func:`random_goals`' ``kind``."""


def parse_goals(doc: object, default: GoalSpec) -> list[GoalSpec]:
    """Validate a parsed goals document (``{"goals": [{...}, ...]}``).

    Raises:
        ScenarioError: the first bad table or field, with its value.
    """
    if not isinstance(doc, dict):
        raise ScenarioError(f"a goals file is a TOML table, got {shorten(doc)}")
    extra = sorted(set(doc) - {"goals"})
    if extra:
        raise ScenarioError(f"unknown field {extra[0]!r} in the goals file (expected [[goals]])")
    goals = doc.get("goals")
    if not isinstance(goals, list) or not goals:
        raise ScenarioError(f"goals must be a non-empty array of tables, got {shorten(goals)}")
    if len(goals) > MAX_GOALS:
        raise ScenarioError(f"goals has {len(goals)} entries, at most {MAX_GOALS}")
    out: list[GoalSpec] = []
    for i, g in enumerate(goals):
        where = f"goals[{i}]"
        if not isinstance(g, dict):
            raise ScenarioError(f"{where} must be a table, got {shorten(g)}")
        check_only(g, where, GOAL_FIELDS)
        out.append(
            GoalSpec(
                pose(g, "object_pose_xyzquat", where),
                number(
                    g,
                    "position_tol",
                    where,
                    default.position_tol,
                    lo=0.0,
                    lo_open=True,
                    hi=MAX_POSITION_TOL,
                ),
                number(
                    g, "angle_tol", where, default.angle_tol, lo=0.0, lo_open=True, hi=MAX_ANGLE_TOL
                ),
            )
        )
    return out


def load_goals(path: str | Path, default: GoalSpec) -> list[GoalSpec]:
    """Read and validate a goals TOML file (see the module docstring).

    Args:
        path: the file.
        default: the tolerances a goal without its own takes (the scenario's goal).

    Raises:
        ScenarioError: missing, oversized or unreadable file, bad TOML or a bad field.
    """
    path = Path(path)
    where = shorten(str(path))
    try:
        if not path.is_file():
            raise ScenarioError(f"goals file not found: {where}")
        if path.stat().st_size > MAX_GOALS_BYTES:
            raise ScenarioError(f"goals file {where} is larger than {MAX_GOALS_BYTES} bytes")
        text = path.read_bytes().decode("utf-8")
        doc = tomllib.loads(text)
    except ScenarioError:
        raise
    except UnicodeDecodeError as exc:
        raise ScenarioError(f"{where}: not valid TOML: not UTF-8 text") from exc
    except (tomllib.TOMLDecodeError, RecursionError, ValueError) as exc:
        raise ScenarioError(f"{where}: not valid TOML: {one_line(str(exc), 200)}") from exc
    except OSError as exc:
        raise ScenarioError(f"cannot read goals file {where}: {one_line(str(exc), 120)}") from exc
    try:
        return parse_goals(doc, default)
    except ScenarioError as exc:
        raise ScenarioError(f"{where}: {exc}") from exc


def random_goals(
    scenario: Scenario,
    count: int,
    seed: int,
    kind: GoalKind | str = GoalKind.ORIENTATION,
    accept: Callable[[FloatArray], bool] | None = None,
) -> list[GoalSpec]:
    """``count`` random goals (uniform orientations; with ``pose``, positions too).

    Positions are uniform in the scenario's ``[workspace]`` box around the
    start position; tolerances are the scenario goal's. The same seed gives
    the same goals.

    Args:
        scenario: the start pose, workspace and tolerances.
        count: how many goals.
        seed: random seed.
        kind: one of :data:`GOAL_KINDS`.
        accept: ``accept(pose (7,)) -> bool``; poses it refuses are drawn again
            (e.g. the object alone colliding with an obstacle: no goal at all).

    Raises:
        InvalidInputError: ``count`` outside ``[1, MAX_GOALS]``, an unknown kind,
            or ``accept`` refusing 1000 draws in a row.
    """
    if not 1 <= count <= MAX_GOALS:
        raise InvalidInputError(f"--random-goals must be in [1, {MAX_GOALS}], got {count}")
    if kind not in GOAL_KINDS:
        raise InvalidInputError(f"goal kind must be one of {', '.join(GOAL_KINDS)}, got {kind!r}")
    rng = np.random.default_rng([seed, 7])
    centre = scenario.start.object_pose_xyzquat[:3]
    half = np.asarray(scenario.workspace_half_extent, dtype=float)
    out: list[GoalSpec] = []
    while len(out) < count:
        for _ in range(1000):
            pos = centre + rng.uniform(-half, half) if kind == GoalKind.POSE else centre.copy()
            quat = random_quaternion(rng)
            if accept is None or accept(np.concatenate([pos, quat])):
                break
        else:
            raise InvalidInputError("no random goal pose is free of the obstacles (1000 draws)")
        out.append(
            GoalSpec(
                np.concatenate([pos, quat]),
                scenario.goal.position_tol,
                scenario.goal.angle_tol,
            )
        )
    return out
