"""The MuJoCo model (MJCF text) of a plan: hand, object and obstacles, from the file alone.

:func:`build_mjcf` writes:

- the hand: one body per Pinocchio joint of the plan's embedded URDF (joint
  placements, inertias with fixed links merged, hinge or slide axes, URDF
  ranges), its collision geometry from the Pinocchio geometry model (boxes,
  spheres, cylinders, capsules; any other geometry by its local bounding box),
  gravity compensated on the hand's own links (``gravcomp``); hand-hand
  contacts are off (the planner checked them);
- one position actuator per joint (gain :data:`KP`, critically damped) whose
  torque, gravity compensation and grip-force feed-forward included, is
  clamped to the joint's effort limit in the plan's URDF (``forcerange`` and
  the joint's ``actuatorfrcrange``): the replay never squeezes harder than
  the hand can. A joint without an effort limit gets an unlimited actuator.
  The fingertip spheres are rigid: where a finger turns relative to the
  object, the plan's fixed contact asks the sphere to slide on the object by
  ``r (w_object - w_link) x n``, which friction resists and the plan does not
  model (a passive ball at the tip would roll instead, but a free ball
  transmits normal forces only);
- the object: a free body with the plan's shape and mass (uniform density);
  a mesh (the plan's mesh file) is one geom per convex part
  (:mod:`dexplan.execution.replay.convex_parts`: MuJoCo collides a mesh geom
  as its convex hull) with the mass distribution of the mesh itself;
  obstacles static, meshes split likewise;
- friction ``mu`` on every geom (MuJoCo takes the larger of a pair); point
  contacts ``condim 3``, soft contacts ``condim 4`` with the torsional friction
  ``torsion`` (m, as in dexplan); elliptic cones, ``impratio`` 10;
- MuJoCo's no-slip pass (:data:`NOSLIP_ITERATIONS`): MuJoCo's friction is a
  soft constraint, under which a contact loaded inside its friction cone
  still creeps (a velocity proportional to the load). Coulomb friction, which
  the plan's holds assume, has no such creep: a box on a 35 degree slope
  (``mu`` 0.8) crept 0.02 mm in 2 s, the suite's bean held by three
  fingertips through a regrasp up to 0.3 mm/s, until the contacts had moved
  off the planned ones and the hold let go (4 of the 5 bean plans of 20
  dropped closed loop went that way, and track with the pass). The pass
  re-solves the friction forces as hard constraints after each step; it
  adds no force a contact's cone does not allow.

The text needs no MuJoCo: :mod:`dexplan.execution.replay.simulation` compiles it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import coal
import numpy as np
import pinocchio as pin

from dexplan.core.typing import FloatArray
from dexplan.execution.replay.convex_parts import convex_parts, mass_properties
from dexplan.model.collision import CollisionWorld
from dexplan.model.hand.hand import Hand
from dexplan.model.hand.mimic import MimicJoint
from dexplan.model.objects import Mesh, Shape
from dexplan.planfile import shape_of

__all__ = [
    "ARMATURE",
    "KP",
    "NOSLIP_ITERATIONS",
    "TIMESTEP",
    "build_mjcf",
]

#: Simulation step (s), position gain (N m / rad), joint armature (kg m^2).
TIMESTEP = 0.001
KP = 10.0
ARMATURE = 1e-3
#: Iterations of MuJoCo's no-slip pass (``noslip_iterations``): friction without creep.
NOSLIP_ITERATIONS = 10


def _f(v: Any) -> str:
    """Numbers as MJCF attribute text: space-separated, 9 significant digits."""
    return " ".join(f"{float(x):.9g}" for x in np.asarray(v, dtype=float).reshape(-1))


def _i(v: Any) -> str:
    """Integers as MJCF attribute text, space-separated."""
    return " ".join(str(int(x)) for x in np.asarray(v).reshape(-1))


def _quat_wxyz(R: FloatArray) -> FloatArray:
    """(4,) MuJoCo's ``[w, x, y, z]`` unit quaternion of a (3, 3) rotation matrix."""
    q = pin.Quaternion(np.asarray(R, dtype=float))
    q.normalize()
    return np.array([q.w, q.x, q.y, q.z])


def _pose_attrs(M: pin.SE3) -> str:
    """MJCF ``pos`` and ``quat`` attributes of a placement (relative to the parent body)."""
    return f'pos="{_f(M.translation)}" quat="{_f(_quat_wxyz(M.rotation))}"'


def _geom_xml(geom: Any) -> str | None:
    """MJCF type and size of a coal geometry (None: not a collision shape)."""
    if isinstance(geom, coal.Box):
        return f'type="box" size="{_f(geom.halfSide)}"'
    if isinstance(geom, coal.Sphere):
        return f'type="sphere" size="{geom.radius:.9g}"'
    if isinstance(geom, coal.Capsule):
        return f'type="capsule" size="{geom.radius:.9g} {geom.halfLength:.9g}"'
    if isinstance(geom, coal.Cylinder):
        return f'type="cylinder" size="{geom.radius:.9g} {geom.halfLength:.9g}"'
    try:
        geom.computeLocalAABB()
        box = geom.aabb_local
        c = 0.5 * (np.asarray(box.min_) + np.asarray(box.max_))
        h = 0.5 * (np.asarray(box.max_) - np.asarray(box.min_))
    except Exception:
        return None
    return f'type="box" size="{_f(np.maximum(h, 1e-4))}" pos="{_f(c)}"'


def _shape_xml(d: Mapping[str, Any], base_dir: Path, name: str) -> tuple[list[str], list[str]]:
    """(asset lines, geom attributes of each geom) of a plan shape table.

    A primitive is one geom. A mesh is one geom per convex part
    (:func:`dexplan.execution.replay.convex_parts.convex_parts`): MuJoCo
    collides a mesh geom as its convex hull, so a concave mesh in one piece
    would be a fuller body than the plan's. The parts' vertices are written
    inline (object frame, the plan's scale applied).
    """
    kind = d["shape"]
    if kind == "sphere":
        return [], [f'type="sphere" size="{float(d["radius"]):.9g}"']
    if kind == "box":
        return [], [f'type="box" size="{_f(np.asarray(d["size"], dtype=float) / 2)}"']
    if kind == "capsule":
        return [], [f'type="capsule" size="{float(d["radius"]):.9g} {float(d["length"]) / 2:.9g}"']
    if kind == "cylinder":
        return [], [f'type="cylinder" size="{float(d["radius"]):.9g} {float(d["length"]) / 2:.9g}"']
    mesh = shape_of(d, base_dir, name)
    assert isinstance(mesh, Mesh)
    assets, geoms = [], []
    for k, part in enumerate(convex_parts(mesh.vertices, mesh.faces)):
        assets.append(
            f'<mesh name="{name}_part{k}" vertex="{_f(part.vertices)}" face="{_i(part.faces)}"/>'
        )
        geoms.append(f'type="mesh" mesh="{name}_part{k}"')
    return assets, geoms


def _object_xml(
    doc: Mapping[str, Any], obj: Shape, mass: float, contact: str, base_dir: Path
) -> tuple[list[str], str]:
    """The object's mesh assets and its free body at the plan's start pose.

    Args:
        doc: a validated plan (its ``object`` and ``start``).
        obj: the plan's object shape.
        mass: object mass (kg).
        contact: the contact attributes (:func:`_contact_attrs`).
        base_dir: the plan's folder (mesh paths).
    """
    assets, geoms = _shape_xml(doc["object"], base_dir, "object")
    inertial = _object_inertial(obj, mass)
    # a mesh's mass is its body's <inertial>; a primitive's is its geom's
    geom_mass = 0.0 if inertial else mass
    start = np.asarray(doc["start"]["object_pose_xyzquat"], dtype=float)
    lines = [
        f'    <body name="object" pos="{_f(start[:3])}" quat="{_f(start[[6, 3, 4, 5]])}">',
        '      <freejoint name="object"/>',
        *([f"      {inertial}"] if inertial else []),
        *(
            f'      <geom name="{_part_name("object", k)}" {g} mass="{geom_mass:.9g}" '
            f'contype="2" conaffinity="3" {contact}/>'
            for k, g in enumerate(geoms)
        ),
        "    </body>",
    ]
    return assets, "\n".join(lines)


def _object_inertial(obj: Shape, mass: float) -> str:
    """The object's ``<inertial>``: of the mesh itself (not of its parts), or none.

    A primitive's geom carries the mass (MuJoCo's exact primitive inertia).
    """
    if not isinstance(obj, Mesh):
        return ""
    mp = mass_properties(obj.vertices, obj.faces, mass)
    full = mp.inertia[[0, 1, 2, 0, 0, 1], [0, 1, 2, 1, 2, 2]]
    return (
        f'<inertial pos="{_f(mp.center_of_mass)}" mass="{mp.mass:.9g}" fullinertia="{_f(full)}"/>'
    )


def build_mjcf(
    doc: Mapping[str, Any],
    hand: Hand,
    *,
    mass: float,
    gravity: FloatArray,
    base_dir: str | Path = ".",
) -> tuple[str, list[int]]:
    """MJCF text of the plan's hand, object and obstacles; and the fingertip geom ids.

    Geoms are named ``hand{k}`` in the order of ``hand.geom_model``, the
    object ``object`` (a concave mesh's further convex parts ``object_part{k}``),
    obstacles ``obstacle{k}`` (likewise ``obstacle{k}_part{j}``); bodies
    ``b_<joint>``; position actuators ``a_<joint>`` in ``hand.joint_names`` order.

    Args:
        doc: a validated plan.
        hand: its :class:`~dexplan.model.hand.hand.Hand`.
        mass: object mass (kg).
        gravity: (3,) gravity (m/s^2), world frame.
        base_dir: the plan's folder (mesh paths).
    """
    base_dir = Path(base_dir)
    model = hand.model
    contact = _contact_attrs(doc)
    obj = shape_of(doc["object"], base_dir, "object")
    world = CollisionWorld(hand, obj)
    tips = list(world.tip_geoms)

    geoms_of = _hand_geoms(hand.geom_model, contact)
    children: dict[int, list[int]] = {}
    for j in range(1, model.njoints):
        children.setdefault(int(model.parents[j]), []).append(j)
    a_obj, body = _object_xml(doc, obj, mass, contact, base_dir)
    obstacle_assets, obstacles = _obstacles_xml(doc, base_dir, contact)
    assets = [*a_obj, *obstacle_assets]
    actuators = "\n".join(_actuator_xml(model, n) for n in hand.joint_names)
    palm = "\n".join("    " + g for g in geoms_of.get(0, []))
    mimic = hand.mimic_joints  # coupled joints follow through a joint equality
    tree = "\n".join(
        _body_xml(model, c, "    ", geoms_of, children, mimic) for c in children.get(0, [])
    )
    equality = "\n".join(
        f'    <joint joint1="{n}" joint2="{m.primary}" '
        f'polycoef="{m.offset!r} {m.multiplier!r} 0 0 0"/>'
        for n, m in mimic.items()
    )
    xml = f"""<mujoco model="dexplan replay">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{TIMESTEP:g}" gravity="{_f(gravity)}" cone="elliptic" impratio="10"
          integrator="implicitfast" noslip_iterations="{NOSLIP_ITERATIONS}"/>
  <asset>
{chr(10).join(a for a in assets if a)}
  </asset>
  <worldbody>
{palm}
{chr(10).join(obstacles)}
{body}
{tree}
  </worldbody>
  <actuator>
{actuators}
  </actuator>
  <equality>
{equality}
  </equality>
</mujoco>
"""
    return xml, tips


def _effort(model: pin.Model, j: int) -> float | None:
    """Joint ``j``'s effort limit (N m or N) from the plan's URDF, None where it has none."""
    e = float(model.effortLimit[model.joints[j].idx_v])
    return e if math.isfinite(e) and e > 0.0 else None


def _actuator_xml(model: pin.Model, name: str) -> str:
    """The position actuator of joint ``name``, its force within the joint's effort limit.

    The grip-force feed-forward goes through the actuator as a control offset
    (``ctrl = target + tau_ff / KP``) so that the limit bounds the total torque;
    the control range is the joint range widened by ``effort / KP``, beyond
    which the force is at the limit anyway.
    """
    j = model.getJointId(name)
    iq = model.joints[j].idx_q
    lo, hi = float(model.lowerPositionLimit[iq]), float(model.upperPositionLimit[iq])
    e = _effort(model, j)
    if e is None:
        return f'    <position name="a_{name}" joint="{name}" kp="{KP:g}" dampratio="1"/>'
    return (
        f'    <position name="a_{name}" joint="{name}" kp="{KP:g}" dampratio="1" '
        f'ctrlrange="{lo - e / KP:.9g} {hi + e / KP:.9g}" forcerange="{-e:.9g} {e:.9g}"/>'
    )


def _contact_attrs(doc: Mapping[str, Any]) -> str:
    """MJCF contact attributes of every geom: ``condim``, friction ``mu`` (and torsion), solver.

    Args:
        doc: a validated plan (``mu``, ``contact_model``, ``torsion``).
    """
    mu = float(doc["mu"])
    soft = doc.get("contact_model", "point") == "soft"
    torsion = float(doc.get("torsion", 0.0))
    condim = 4 if soft else 3
    fr = f'friction="{mu:.6g} {max(torsion, 1e-6) if soft else 0.0:.6g} 0"'
    return f'condim="{condim}" {fr} solref="0.002 1" solimp="0.95 0.99 0.001"'


def _hand_geoms(gm: pin.GeometryModel, contact: str) -> dict[int, list[str]]:
    """MJCF geoms of the hand's collision geometry, by parent joint.

    Args:
        gm: the hand's Pinocchio geometry model.
        contact: the contact attributes (:func:`_contact_attrs`).

    Returns:
        Per Pinocchio joint, its ``<geom name="hand{k}" .../>`` lines (geometry
        that is no collision shape is left out).
    """
    geoms_of: dict[int, list[str]] = {}
    for k, go in enumerate(gm.geometryObjects):
        g = _geom_xml(go.geometry)
        if g is None:
            continue
        pos = _pose_attrs(go.placement)
        if ' pos="' in g:  # a bounding box centred off the geometry frame
            c = np.array([float(x) for x in g.split(' pos="')[1].split('"')[0].split()])
            M = go.placement * pin.SE3(np.eye(3), c)
            g = g.split(' pos="')[0]
            pos = _pose_attrs(M)
        geoms_of.setdefault(int(go.parentJoint), []).append(
            f'<geom name="hand{k}" {g} {pos} contype="1" conaffinity="2" {contact}/>'
        )
    return geoms_of


def _body_xml(
    model: pin.Model,
    j: int,
    indent: str,
    geoms_of: Mapping[int, list[str]],
    children: Mapping[int, list[int]],
    mimic: Mapping[str, MimicJoint],
) -> str:
    """MJCF body of Pinocchio joint ``j`` and, nested, of every joint below it.

    Args:
        model: the hand's Pinocchio model.
        j: the joint.
        indent: the body's indentation.
        geoms_of: the hand geoms by joint (:func:`_hand_geoms`).
        children: the child joints of each joint.
        mimic: the hand's mimic joints (``Hand.mimic_joints``).
    """
    name = model.names[j]
    jm = model.joints[j]
    short = jm.shortname()
    kind = "slide" if "Prismatic" in short or short.startswith("JointModelP") else "hinge"
    axis: tuple[float, ...] | None = {"X": (1, 0, 0), "Y": (0, 1, 0), "Z": (0, 0, 1)}.get(short[-1])
    follower = mimic.get(name)
    if follower is not None:  # Pinocchio does not expose a mimic joint's own axis
        kind = "slide" if follower.kind == "prismatic" else "hinge"
        axis = follower.axis
    elif axis is None:
        axis = tuple(np.asarray(jm.extract().axis, dtype=float))
    inertia = model.inertias[j]
    m = max(float(inertia.mass), 1e-4)
    Ic = np.asarray(inertia.inertia, dtype=float)
    Ic = Ic + np.eye(3) * 1e-8
    full = [Ic[0, 0], Ic[1, 1], Ic[2, 2], Ic[0, 1], Ic[0, 2], Ic[1, 2]]
    iq = jm.idx_q
    lo, hi = float(model.lowerPositionLimit[iq]), float(model.upperPositionLimit[iq])
    # the joint's total actuator torque, the links' gravity compensation included,
    # is clamped to the effort limit: a real hand's motors do both
    e = _effort(model, j) if follower is None else None
    if follower is not None:
        lo, hi = follower.lower, follower.upper
    limit = "" if e is None else f' actuatorgravcomp="true" actuatorfrcrange="{-e:.9g} {e:.9g}"'
    parts = [
        f'{indent}<body name="b_{name}" {_pose_attrs(model.jointPlacements[j])} gravcomp="1">',
        f'{indent}  <inertial pos="{_f(inertia.lever)}" mass="{m:.9g}" fullinertia="{_f(full)}"/>',
        f'{indent}  <joint name="{name}" type="{kind}" axis="{_f(axis)}" range="{lo:.9g} '
        f'{hi:.9g}" armature="{ARMATURE:g}" damping="0.01" limited="true"{limit}/>',
    ]
    parts += [indent + "  " + g for g in geoms_of.get(j, [])]
    for c in children.get(j, []):
        parts.append(_body_xml(model, c, indent + "  ", geoms_of, children, mimic))
    parts.append(f"{indent}</body>")
    return "\n".join(parts)


def _obstacles_xml(
    doc: Mapping[str, Any], base_dir: Path, contact: str
) -> tuple[list[str], list[str]]:
    """The obstacles' mesh assets and static geoms.

    Args:
        doc: a validated plan (its ``obstacles``).
        base_dir: the plan's folder (mesh paths).
        contact: the contact attributes (:func:`_contact_attrs`).

    Returns:
        ``(assets, geoms)``: the mesh asset lines (one per convex part of a
        mesh obstacle) and the ``<geom name="obstacle{k}" .../>`` lines.
    """
    assets: list[str] = []
    geoms = []
    for k, ob in enumerate(doc.get("obstacles", [])):
        sh = {kk: v for kk, v in ob.items() if kk not in ("pose_xyzquat", "name")}
        a, g = _shape_xml(sh, base_dir, f"obstacle{k}")
        assets += a
        p = np.asarray(ob["pose_xyzquat"], dtype=float)
        geoms += [
            f'    <geom name="{_part_name(f"obstacle{k}", j)}" {gj} pos="{_f(p[:3])}" '
            f'quat="{_f(p[[6, 3, 4, 5]])}" contype="2" conaffinity="1" {contact}/>'
            for j, gj in enumerate(g)
        ]
    return assets, geoms


def _part_name(name: str, k: int) -> str:
    """Geom name of part ``k`` of a shape: the shape's own name for the first."""
    return name if k == 0 else f"{name}_part{k}"
