"""What a scenario is: its dataclasses, the fields each table accepts, and the limits.

Scenarios are TOML, in metres and radians, poses in the world (= palm) frame
with quaternions XYZW (``docs/scenario.md``). :mod:`.scenario` parses and
validates them into a :class:`Scenario`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path
from typing import Any

from dexplan.core.typing import FloatArray
from dexplan.model.grasp.cones import ContactModel
from dexplan.model.grasp.rolling import ContactMotion
from dexplan.model.objects.factory import ALL_SHAPE_FIELDS

DEFAULT_SCENARIO = "paper_sphere"


class Space(StrEnum):
    """``planner.space``: how OMPL's constrained state space meets the grasp manifold.

    Members equal their strings, as scenario files and roadmap keys hold them.
    """

    PROJECTED = "projected"
    ATLAS = "atlas"
    TANGENT_BUNDLE = "tangent_bundle"


#: Values of ``planner.space``.
SPACES: tuple[Space, ...] = tuple(Space)

# ---------------------------------------------------------------------- limits
# Documented in docs/scenario.md ("Limits"); a value outside is bad input.
MAX_SCENARIO_BYTES = 1_000_000  # a scenario file is a few hundred bytes
MAX_POSITION = 10.0  # m: |x|, |y|, |z| of start, goal and obstacle positions
MAX_HALF_EXTENT = 1.0  # m: workspace.half_extent per axis
MAX_OBJECT_SIZE = 2.0  # m: object radius, length, box edge, mesh bounding diameter
MAX_OBJECT_MASS = 1000.0  # kg
MAX_GRAVITY = 1000.0  # m/s^2, each component of [world] gravity
MAX_OBSTACLE_SIZE = 2.0 * MAX_POSITION  # m: the same for an obstacle
MAX_MESH_SCALE = 1000.0  # object and obstacle mesh ``scale``
MAX_OBSTACLES = 256  # [[obstacles]] tables
MAX_MU = 10.0  # contact.mu (friction coefficient)
MAX_FC_MARGIN = 1.0  # contact.fc_margin (force-closure quality; Q is a unit-force measure)
MAX_POSITION_TOL = 1.0  # m: goal.position_tol
MAX_ANGLE_TOL = math.pi  # rad: goal.angle_tol
MAX_TIME_LIMIT = 86_400.0  # s: planner.time_limit (one day)
SEED_LIMIT = 2**31  # planner.seed < SEED_LIMIT (OMPL's RNG is seeded with 31-bit values)
MAX_JOINTS = 256  # start.q entries
MAX_JOINT_VALUE = 1000.0  # |start.q[i]| (rad or m; joint limits are the hand's)
MAX_FINGERS = 32  # hand.fingertip_frames entries
#: m: hand.fingertip_radius, everywhere (scenario, Hand, plan files); larger
#: values are taken for a unit mistake
MAX_FINGERTIP_RADIUS = 0.05
MAX_COLLISION_EXCLUDE = 4096  # hand.collision_exclude pairs
MAX_EFFORT_LIMIT = 1e4  # N m: hand.effort_limits (one number or each entry)
MAX_HOLD_SHIFT = 0.05  # m: contact.hold_shift
MAX_URDF_BYTES = 50_000_000  # hand.urdf file size
MAX_NAME = 256  # characters of a name (scenario, obstacle, planner, frame, parameter)
MAX_PATH = 4096  # characters of a file name (hand.urdf; mesh paths likewise)
MAX_PACKAGE_DIRS = 64  # hand.package_dirs entries
MAX_PLANNER_PARAMS = 64  # planner.params entries
MAX_PARAM_INT = 2**53  # |integer planner.params value| (exact as a double, as OMPL stores it)
MAX_PARAM_FLOAT = 1e12  # |float planner.params value|

# ----------------------------------------------------------------------- fields
# The fields each table accepts; the parser rejects any other, and
# docs/scenario.md documents every one (tests/test_scenario_docs.py checks it).
HAND_BUILTIN_FIELDS = frozenset({"builtin", "effort_limits"})
HAND_URDF_FIELDS = frozenset(
    {
        "urdf",
        "fingertip_frames",
        "fingertip_radius",
        "collision_exclude",
        "effort_limits",
        "package_dirs",
        "root_link",
    }
)
HAND_MJCF_FIELDS = frozenset(
    {
        "mjcf",
        "fingertip_frames",
        "fingertip_radius",
        "collision_exclude",
        "effort_limits",
        "locked_joints",
    }
)
#: Fields of ``[hand]`` every kind of hand accepts.
HAND_COMMON_FIELDS = frozenset({"effort_limits"})
OBSTACLE_OWN_FIELDS = frozenset({"name", "pose_xyzquat"})  # beside its shape fields
OBJECT_OWN_FIELDS = frozenset({"mass"})  # a property of the object, not of its shape
SCENARIO_FIELDS: Mapping[str, frozenset[str]] = {
    "": frozenset(
        {
            "name",
            "hand",
            "object",
            "contact",
            "obstacles",
            "start",
            "goal",
            "planner",
            "workspace",
            "world",
        }
    ),
    # builtin, or urdf or mjcf and its fields
    "hand": HAND_BUILTIN_FIELDS | HAND_URDF_FIELDS | HAND_MJCF_FIELDS,
    "object": ALL_SHAPE_FIELDS | OBJECT_OWN_FIELDS,  # its shape kind's (SHAPE_FIELDS), mass
    "contact": frozenset(
        {
            "mu",
            "friction_edges",
            "fc_margin",
            "model",
            "torsion",
            "hold_shift",
            "hold_effort_share",
            "motion",
        }
    ),
    "obstacles": ALL_SHAPE_FIELDS | OBSTACLE_OWN_FIELDS,
    "start": frozenset({"object_pose_xyzquat", "q"}),
    "goal": frozenset({"object_pose_xyzquat", "position_tol", "angle_tol"}),
    "planner": frozenset({"name", "time_limit", "seed", "params", "space"}),
    "workspace": frozenset({"half_extent"}),
    "world": frozenset({"gravity"}),
}
"""Accepted fields per table (``""``: the top level; ``obstacles``: each ``[[obstacles]]``)."""


@dataclass(frozen=True)
class HandSpec:
    """Which hand: a builtin name, or a URDF or MJCF file with its fingertip frames."""

    builtin: str | None = "paper"
    urdf: Path | None = None
    fingertip_frames: tuple[str, ...] = ()
    fingertip_radius: float | None = None
    collision_exclude: tuple[tuple[str, str], ...] = ()
    #: ``[hand] effort_limits``: one limit (N m) for every joint, a table by
    #: joint name, or None (the URDF's own)
    effort_limits: float | Mapping[str, float] | None = None
    #: ``[hand] package_dirs``: folders ``package://`` mesh URIs resolve in
    #: (after the URDF's own folder, before ROS_PACKAGE_PATH)
    package_dirs: tuple[Path, ...] = ()
    #: ``[hand] mjcf``: the MJCF file (:mod:`dexplan.model.hand.mjcf`)
    mjcf: Path | None = None
    #: ``[hand] locked_joints``: MJCF joint values (rad, m) held fixed, by joint name
    locked_joints: Mapping[str, float] = field(default_factory=dict)
    #: ``[hand] root_link``: the link the hand hangs from in a whole robot's
    #: URDF (the rest of the robot is dropped), or None: the URDF's own root
    root_link: str | None = None


@dataclass(frozen=True)
class StartSpec:
    """Start: an object pose, and optionally the hand joints (else a grasp is found)."""

    object_pose_xyzquat: FloatArray
    q: FloatArray | None = None


@dataclass(frozen=True)
class GoalSpec:
    """Goal region: an object pose with position (m) and angle (rad) tolerances."""

    object_pose_xyzquat: FloatArray
    position_tol: float = 0.005
    angle_tol: float = 0.05


@dataclass(frozen=True)
class PlannerSpec:
    """OMPL planner and run settings."""

    name: str = "PRM"
    time_limit: float = 30.0
    seed: int = 1
    params: Mapping[str, Any] = field(default_factory=dict)
    space: Space = Space.PROJECTED


@dataclass(frozen=True)
class Scenario:
    """A complete planning problem as read from a scenario file.

    Attributes:
        name: scenario name.
        hand: hand specification.
        object: object shape dict (``dexplan.model.objects.shape_from_dict`` schema).
        mu: friction coefficient.
        friction_edges: edges of the linearized friction cones.
        obstacles: obstacle dicts (shape fields plus ``pose_xyzquat``).
        start: start specification.
        goal: goal region.
        planner: planner settings.
        workspace_half_extent: (3,) box around the start position the object
            centre stays in (m).
        fc_margin: minimum force-closure quality of every (n-1) subgrasp.
        base_dir: folder of the scenario file (relative paths resolve there).
        contact_model: ``"point"`` (Coulomb friction, the paper) or ``"soft"``
            (soft finger: also torsional friction about the normal).
        torsion: soft-finger torsion coefficient (m), ``|tau_n| <= torsion f_n``,
            in (0, ``MAX_TORSION``] for soft contacts; 0 for point contacts.
        object_mass: ``[object] mass`` (kg), or None (executing a plan then
            assumes :data:`dexplan.model.grasp.grip_forces.DEFAULT_MASS`).
        gravity: ``[world] gravity`` (m/s^2, world frame), or None
            (:data:`dexplan.model.grasp.grip_forces.DEFAULT_GRAVITY`).
        hold_shift: ``[contact] hold_shift`` (m): a hold counts only if it
            still holds with each contact moved this far along the surface
            (:mod:`dexplan.model.grasp.holds`).
        hold_effort_share: ``[contact] hold_effort_share``, in (0, 1]: the
            share of each joint's effort limit a hold may need when the
            planner lets a finger go (the verifier checks the full limits);
            below 1 it leaves torque headroom to execute the plan with.
        contact_motion: ``[contact] motion``: during transfers the contacts
            stay ``fixed`` on the object (the paper's; the fingertips slide)
            or the fingertips are ``rolling`` (:mod:`dexplan.model.grasp.rolling`).
    """

    name: str
    hand: HandSpec
    object: Mapping[str, Any]
    mu: float
    friction_edges: int
    obstacles: tuple[Mapping[str, Any], ...]
    start: StartSpec
    goal: GoalSpec
    planner: PlannerSpec
    workspace_half_extent: FloatArray
    fc_margin: float
    base_dir: Path
    contact_model: ContactModel = ContactModel.POINT
    torsion: float = 0.0
    object_mass: float | None = None
    gravity: tuple[float, float, float] | None = None
    hold_shift: float = 0.002
    hold_effort_share: float = 1.0
    contact_motion: ContactMotion = ContactMotion.FIXED
