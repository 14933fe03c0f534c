"""``dexplan info``: a hand's joints, limits, fingertips and reach, and dependency versions.

``--hand`` takes a builtin hand (``paper``, ``allegro``, ...), a scenario (a
TOML file or a builtin scenario's name: its hand) or a URDF file (its joints
and the frames that could be fingertips: a URDF alone does not say which are).
"""

from __future__ import annotations

import difflib
import io
import sys
from pathlib import Path
from typing import TextIO

import numpy as np
import pinocchio as pin

from dexplan.cli.console import ExitCode, dist_version
from dexplan.cli.options import InfoOptions
from dexplan.core.errors import DexplanError, ModelError, ScenarioError, one_line, shorten
from dexplan.core.files import read_input_file
from dexplan.model.hand.builtin import BUILTIN_HANDS
from dexplan.model.hand.hand import Hand
from dexplan.model.hand.urdf import build_models, parse_urdf, urdf_text
from dexplan.model.objects import Sphere
from dexplan.model.scenario import (
    Scenario,
    builtin_scenarios,
    load_scenario,
    resolve_scenario_path,
)
from dexplan.planning.context import build_context
from dexplan.planning.pose_check import check_pose, reach_extent

__all__ = ["run"]

DEPENDENCIES = ("ompl", "pin", "coal", "osqp", "numpy", "scipy", "trimesh", "rerun-sdk")
"""The distributions whose versions ``info`` lists."""


def run(opts: InfoOptions) -> int:
    """Print the hand (builtin, a scenario's, or a URDF's joints), the object, versions."""
    # everything is loaded before the first line: bad input prints nothing on stdout
    buf = io.StringIO()
    arg = opts.hand
    if arg.lower().endswith(".urdf"):
        _write_urdf(buf, Path(arg))
    else:
        hand, scenario = _hand_and_scenario(arg)
        _write_hand(buf, hand)
        if scenario is None:
            buf.write(f"object: {Sphere(0.04).to_dict()}\n")
        else:
            buf.write(f"object: {dict(scenario.object)}\n")
            _write_poses(buf, scenario, hand)
    out = sys.stdout
    out.write(f"dexplan {dist_version('dexplan')}\n{buf.getvalue()}")
    for dist in DEPENDENCIES:
        out.write(f"{dist}: {dist_version(dist)}\n")
    return ExitCode.OK


def _hand_and_scenario(arg: str) -> tuple[Hand, Scenario | None]:
    """The hand ``--hand`` names (builtin, or a scenario's) and the scenario, if one."""
    if arg in {str(h) for h in BUILTIN_HANDS}:
        return Hand.builtin(arg), None
    try:
        path = resolve_scenario_path(arg)
    except ScenarioError as exc:
        hands = [str(h) for h in BUILTIN_HANDS]
        names = hands + [s.name for s in builtin_scenarios()]
        close = difflib.get_close_matches(arg, names, n=2, cutoff=0.6)
        hint = f"did you mean {' or '.join(map(repr, close))}? " if close else ""
        raise ScenarioError(
            f"--hand: {shorten(arg)} is not a builtin hand ({', '.join(hands)}), a scenario "
            f"file or name, or a .urdf file ({hint}dexplan scenarios lists the scenarios)"
        ) from exc
    scenario = load_scenario(path)
    return Hand.from_spec(scenario.hand), scenario


def _limit(v: float) -> str:
    return "-" if not np.isfinite(v) or v <= 0.0 else f"{v:g}"


def _write_joints(out: TextIO, model: pin.Model, finger_of: dict[int, int]) -> None:
    """The joints in planning order (the plan's ``joint_names``), limits and effort."""
    out.write("joints (planning order): index, name, finger, lower, upper (rad), "
              "velocity (rad/s), effort (N m)\n")  # fmt: skip
    # joints with a value of their own: a mimic joint (a coupling) follows another's
    own = [jid for jid in range(1, model.njoints) if model.joints[jid].nq > 0]
    for j, jid in enumerate(own):
        name, idx_v = model.names[jid], model.joints[jid].idx_v
        finger = finger_of.get(j)
        out.write(
            f"  {j:3d}  {name:<20s} {'-' if finger is None else finger:>2}  "
            f"{model.lowerPositionLimit[j]:+.3f}  {model.upperPositionLimit[j]:+.3f}  "
            f"{_limit(model.velocityLimit[idx_v]):>6s}  {_limit(model.effortLimit[idx_v]):>6s}\n"
        )


def _write_hand(out: TextIO, hand: Hand) -> None:
    """The hand's joints, fingertip frames, radius and each fingertip's reach."""
    out.write(
        f"hand: {hand.name}: {hand.n_fingers} fingers, {hand.nq} joints, "
        f"fingertip radius {hand.fingertip_radius:g} m\n"
    )
    finger_of = {int(j): i for i, idx in enumerate(hand.finger_q_index) for j in idx}
    _write_joints(out, hand.model, finger_of)
    out.write("fingertips: frame; reach of the fingertip centre (world frame, m)\n")
    for i, tip in enumerate(hand.fingertip_frames):
        r = reach_extent(hand, i)
        box = "  ".join(
            f"{a} [{lo:+.3f}, {hi:+.3f}]" for a, lo, hi in zip("xyz", r.lower, r.upper, strict=True)
        )
        out.write(
            f"  finger {i}: {tip}: {box}; {r.nearest:.3f}-{r.farthest:.3f} m from its "
            f"first joint at ({', '.join(f'{v:+.3f}' for v in r.base_world)})\n"
        )


def _write_urdf(out: TextIO, path: Path) -> None:
    """A URDF's joints in planning order, and the frames at the ends of its chains."""
    text = urdf_text(read_input_file(path, "URDF", ModelError), f"URDF file {str(path)!r}")
    model, _ = build_models(parse_urdf(text, path.stem), path.stem, [str(path.parent)])
    out.write(f"hand: {path} (URDF: no fingertip frames or radius; a scenario gives them)\n")
    _write_joints(out, model, {})
    parents = set(model.parents[1:])
    ends = [
        f.name
        for f in model.frames
        if f.parentJoint > 0
        and f.parentJoint not in parents
        and f.type in (pin.FrameType.BODY, pin.FrameType.OP_FRAME)
    ]
    out.write(
        f"frames at the ends of its chains (fingertip frame candidates): {', '.join(ends)}\n"
        "for fingertips, radius and reach: dexplan info --hand SCENARIO.toml with "
        "[hand] urdf, fingertip_frames, fingertip_radius\n"
    )


def _write_poses(out: TextIO, scenario: Scenario, hand: Hand) -> None:
    """How far past the object's surface each fingertip reaches at the start and goal poses."""
    try:
        ctx = build_context(scenario, hand=hand)
    except DexplanError as exc:  # e.g. a hand that can never let a finger go
        out.write(f"start and goal poses: not checked ({one_line(exc, 200)})\n")
        return
    for which, pose in (
        ("start", scenario.start.object_pose_xyzquat),
        ("goal", scenario.goal.object_pose_xyzquat),
    ):
        check = check_pose(ctx, pose, which)
        margins = ", ".join(f"{f.tip_frame} {f.margin * 1e3:+.0f}" for f in check.reach)
        if check.blocked:
            verdict = f"no grasp can exist: {check.describe()}"
        elif check.edge_hint():
            verdict = "some fingertips are at the edge of their reach: grasps may be rare"
        else:
            verdict = "every fingertip reaches the object"
        out.write(f"{which} pose: fingertip reach past the surface (mm): {margins}; {verdict}\n")
