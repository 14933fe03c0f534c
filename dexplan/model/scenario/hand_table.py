"""The ``[hand]`` table of a scenario: a builtin hand, a URDF file or an MJCF file.

Exactly one of ``builtin``, ``urdf`` and ``mjcf`` names the hand (``builtin =
"paper"`` when none is given); each kind accepts its own fields
(:data:`~dexplan.model.scenario.spec.HAND_BUILTIN_FIELDS`, ``HAND_URDF_FIELDS``,
``HAND_MJCF_FIELDS``) and rejects the others' with a line saying which kind uses
them. File fields resolve relative to the scenario file; ``mjcf`` may also be a
``package://`` URI of an installed description wheel.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from dexplan.core.errors import shorten
from dexplan.model.scenario.fields import (
    check_only,
    check_text_file,
    existing_file,
    fail,
    number,
    string,
)
from dexplan.model.scenario.spec import (
    HAND_BUILTIN_FIELDS,
    HAND_COMMON_FIELDS,
    HAND_MJCF_FIELDS,
    HAND_URDF_FIELDS,
    MAX_COLLISION_EXCLUDE,
    MAX_EFFORT_LIMIT,
    MAX_FINGERS,
    MAX_FINGERTIP_RADIUS,
    MAX_JOINT_VALUE,
    MAX_NAME,
    MAX_PACKAGE_DIRS,
    MAX_PATH,
    MAX_URDF_BYTES,
    HandSpec,
)

__all__ = ["hand_spec"]

#: The fields that name the hand, one per kind.
_KINDS = ("builtin", "urdf", "mjcf")
#: The extra that installs the wheel a ``package://`` MJCF names, by package.
_EXTRA = {"gymnasium_robotics": "hands"}


def hand_spec(h: Mapping[str, Any], base_dir: Path) -> HandSpec:
    """``[hand]``: the hand's kind from ``builtin``/``urdf``/``mjcf``, then its fields."""
    given = [k for k in _KINDS if k in h]
    if len(given) > 1:
        a, b = given[:2]
        fail(
            f"hand.{a} (= {shorten(h[a], 40)}) and hand.{b} (= {shorten(h[b], 40)}) "
            "exclude each other: give one"
        )
    kind = given[0] if given else "builtin"
    if kind == "builtin":
        return _builtin_hand(h)
    own = HAND_URDF_FIELDS if kind == "urdf" else HAND_MJCF_FIELDS
    for key, val in h.items():
        if key not in own and key in HAND_URDF_FIELDS | HAND_MJCF_FIELDS:
            other = "mjcf" if kind == "urdf" else "urdf"
            fail(f"hand.{key} (= {shorten(val, 40)}) is only used with hand.{other}")
    check_only(h, "hand", own)
    return _urdf_hand(h, base_dir) if kind == "urdf" else _mjcf_hand(h, base_dir)


def _builtin_hand(h: Mapping[str, Any]) -> HandSpec:
    """``[hand] builtin``: one of the builtin hands' names (``"paper"`` by default)."""
    for key, val in h.items():
        if key in (HAND_URDF_FIELDS | HAND_MJCF_FIELDS) - HAND_COMMON_FIELDS:
            fail(
                f"hand.{key} (= {shorten(val, 40)}) is only used with hand.urdf or hand.mjcf; "
                "a builtin hand defines its own"
            )
    check_only(h, "hand", HAND_BUILTIN_FIELDS)
    # imported on use: dexplan.model.hand loads Pinocchio (about 0.5 s measured),
    # which validating a scenario does not otherwise need
    from dexplan.model.hand.builtin import BUILTIN_HANDS

    builtin = h.get("builtin", "paper")
    if not isinstance(builtin, str) or builtin not in BUILTIN_HANDS:
        fail(f"hand.builtin must be one of {', '.join(BUILTIN_HANDS)}, got {shorten(builtin)}")
    return HandSpec(builtin=builtin, effort_limits=_effort_limits(h))


def _effort_limits(h: Mapping[str, Any]) -> float | dict[str, float] | None:
    """``[hand] effort_limits``: one limit (N m) for every joint, or a table by joint name.

    The joint names are checked when the hand is built (they are the URDF's).
    """
    if "effort_limits" not in h:
        return None
    v = h["effort_limits"]
    if isinstance(v, Mapping):
        if not v or len(v) > MAX_FINGERS * 16:
            fail(f"hand.effort_limits must name 1 to {MAX_FINGERS * 16} joints, got {shorten(v)}")
        return {
            str(k): number(v, k, "hand.effort_limits", lo=0.0, lo_open=True, hi=MAX_EFFORT_LIMIT)
            for k in v
        }
    return number(h, "effort_limits", "hand", lo=0.0, lo_open=True, hi=MAX_EFFORT_LIMIT)


def _file_hand_fields(h: Mapping[str, Any], kind: str) -> dict[str, Any]:
    """The fields a URDF and an MJCF hand share: fingertips, radius, exclusions, efforts."""
    if "fingertip_frames" not in h:
        where = "URDF frames" if kind == "urdf" else "MJCF sites or bodies"
        fail(f"missing field hand.fingertip_frames (the {where} at the fingertip centres)")
    frames = h["fingertip_frames"]
    if not (
        isinstance(frames, list)
        and 1 <= len(frames) <= MAX_FINGERS
        and all(isinstance(f, str) and f and len(f) <= MAX_NAME for f in frames)
    ):
        fail(
            f"hand.fingertip_frames must be a list of 1 to {MAX_FINGERS} frame names, "
            f"got {shorten(frames)}"
        )
    excl = h.get("collision_exclude", [])
    if not (
        isinstance(excl, list)
        and len(excl) <= MAX_COLLISION_EXCLUDE
        and all(
            isinstance(p, list)
            and len(p) == 2
            and all(isinstance(x, str) and x and len(x) <= MAX_NAME for x in p)
            for p in excl
        )
    ):
        fail(
            f"hand.collision_exclude must be a list of at most {MAX_COLLISION_EXCLUDE} "
            f"[link, link] pairs, got {shorten(excl)}"
        )
    return {
        "builtin": None,
        "fingertip_frames": tuple(frames),
        # absent: read from the model's fingertip spheres when the hand is built
        "fingertip_radius": number(
            h, "fingertip_radius", "hand", lo=0.0, lo_open=True, hi=MAX_FINGERTIP_RADIUS
        )
        if "fingertip_radius" in h
        else None,
        "collision_exclude": tuple((a, b) for a, b in excl),
        "effort_limits": _effort_limits(h),
    }


def _urdf_hand(h: Mapping[str, Any], base_dir: Path) -> HandSpec:
    """``[hand] urdf``: the URDF file, its fingertip frames and radius, excluded pairs."""
    fields = _file_hand_fields(h, "urdf")
    urdf = existing_file(h, "urdf", "hand", base_dir)
    check_text_file(urdf, "hand.urdf", MAX_URDF_BYTES)
    # a whole robot's URDF: the hand is the subtree below this link (checked when built)
    root_link = string(h, "root_link", "hand") if "root_link" in h else None
    return HandSpec(
        urdf=urdf, package_dirs=_package_dirs(h, base_dir), root_link=root_link, **fields
    )


def _mjcf_hand(h: Mapping[str, Any], base_dir: Path) -> HandSpec:
    """``[hand] mjcf``: the MJCF file, its fingertip sites or bodies, locked joints."""
    fields = _file_hand_fields(h, "mjcf")
    raw = h["mjcf"]
    if isinstance(raw, str) and raw.startswith("package://"):
        mjcf = _package_file(raw)
    else:
        mjcf = existing_file(h, "mjcf", "hand", base_dir)
    check_text_file(mjcf, "hand.mjcf", MAX_URDF_BYTES)
    return HandSpec(mjcf=mjcf, locked_joints=_locked_joints(h), **fields)


def _package_file(uri: str) -> Path:
    """The installed file a ``package://<package>/<path>`` URI names."""
    # imported on use, as BUILTIN_HANDS above (dexplan.model.hand loads Pinocchio)
    from dexplan.model.hand.packages import resolve_mesh, search_dirs

    if len(uri) > MAX_PATH:
        fail(f"hand.mjcf must be at most {MAX_PATH} characters, got {shorten(uri)}")
    path = resolve_mesh(uri, search_dirs())
    if path is None:
        package = uri[len("package://") :].split("/", 1)[0]
        extra = _EXTRA.get(package)
        hint = f"; install it with: pip install 'dexplan[{extra}]'" if extra else ""
        fail(f"hand.mjcf: {uri!r} not found (package {package!r} not installed?){hint}")
    return path


def _locked_joints(h: Mapping[str, Any]) -> dict[str, float]:
    """``[hand] locked_joints``: a table of joint values (rad, m) by MJCF joint name."""
    v = h.get("locked_joints", {})
    if not isinstance(v, Mapping) or len(v) > MAX_FINGERS * 16:
        fail(
            f"hand.locked_joints must be a table of at most {MAX_FINGERS * 16} joint values "
            f"by joint name, got {shorten(v)}"
        )
    out = {}
    for k in v:
        out[str(k)] = number(v, k, "hand.locked_joints", lo=-MAX_JOINT_VALUE, hi=MAX_JOINT_VALUE)
        assert math.isfinite(out[str(k)])
    return out


def _package_dirs(h: Mapping[str, Any], base_dir: Path) -> tuple[Path, ...]:
    """``[hand] package_dirs``: existing folders, relative to the scenario file."""
    dirs = h.get("package_dirs", [])
    if not (
        isinstance(dirs, list)
        and len(dirs) <= MAX_PACKAGE_DIRS
        and all(isinstance(d, str) and d and len(d) <= MAX_PATH for d in dirs)
    ):
        fail(
            f"hand.package_dirs must be a list of at most {MAX_PACKAGE_DIRS} folder names, "
            f"got {shorten(dirs)}"
        )
    out = []
    for d in dirs:
        path = (base_dir / Path(d).expanduser()).resolve()
        if not path.is_dir():
            fail(f"hand.package_dirs: {d!r} is not a folder (looked at {str(path)!r})")
        out.append(path)
    return tuple(out)
