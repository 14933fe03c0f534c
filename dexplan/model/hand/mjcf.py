"""MJCF hands: Pinocchio's MJCF reader, locked joints, and the URDF a plan carries.

An MJCF hand (``[hand] mjcf``) is read with ``pin.buildModelFromMJCF`` and
``pin.buildGeomFromMJCF`` (collision geoms: ``contype`` or ``conaffinity``
non-zero) from a flattened copy of the file (:mod:`.mjcf_xml`), then turned
into a URDF (:func:`mjcf_hand`) that :class:`~dexplan.model.hand.hand.Hand`
loads like any other. The plan file carries that URDF, so ``verify``,
``show``, ``export`` and ``replay`` need neither the MJCF nor its reader, and
planning and verification check the same model.

The rules (``docs/hands.md``, "MJCF hands"):

- the hand is the top-level ``<worldbody>`` body holding the fingertip frames
  (sites or bodies); other top-level bodies and the world's own geoms are not;
- the palm is the deepest body above every fingertip: its frame is the world
  frame, and the joints above it are locked (at ``[hand] locked_joints``'
  value, else at 0 clipped into the joint's range), as are the joints of
  fingers not listed;
- couplings (limited fixed tendons over several joints, joint equalities)
  follow :mod:`.couplings`: a joint that follows another becomes a URDF
  ``<mimic>`` joint, a tendon left with one free joint narrows its range,
  the rest is refused until one of its joints is locked;
- visual geoms become ``<visual>`` elements (the viewer's);
- effort limits are the actuators' (:func:`~.mjcf_xml.effort_limits`);
- link pairs MuJoCo never checks against each other (``contype`` /
  ``conaffinity``, parent and child bodies, ``<exclude>``) become
  ``collision_exclude`` pairs.
"""

from __future__ import annotations

import hashlib
import math
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import coal
import numpy as np
import pinocchio as pin

from dexplan.core.errors import ModelError, shorten
from dexplan.core.native_output import captured_stderr
from dexplan.model.hand.couplings import ResolvedJoints, resolve_couplings
from dexplan.model.hand.mjcf_xml import (
    MjcfDocument,
    actuated_joints,
    body_of_names,
    contact_filter,
    couplings,
    deepest_common_body,
    effort_limits,
    flatten_mjcf,
)
from dexplan.model.hand.packages import package_uri
from dexplan.model.scenario.spec import HandSpec

__all__ = ["MjcfHand", "mjcf_arguments", "mjcf_hand"]

#: Effort limit written for joints the MJCF gives none (``[hand] effort_limits`` overrides).
_NO_EFFORT = 1e4
_REVOLUTE = {"RX": (1.0, 0.0, 0.0), "RY": (0.0, 1.0, 0.0), "RZ": (0.0, 0.0, 1.0)}
_PRISMATIC = {"PX": (1.0, 0.0, 0.0), "PY": (0.0, 1.0, 0.0), "PZ": (0.0, 0.0, 1.0)}


@dataclass(frozen=True)
class MjcfHand:
    """An MJCF hand as dexplan loads it.

    Attributes:
        urdf_xml: the URDF exported from the Pinocchio model (palm at the
            world origin; locked joints frozen; ranges and effort limits set).
        collision_exclude: link pairs MuJoCo never checks against each other.
        locked: the locked joints and their values (rad or m).
        mimic: the joints that follow another (a coupling), by name: the joint followed.
        mesh_dirs: folders the URDF's relative mesh paths resolve in.
    """

    urdf_xml: str
    collision_exclude: tuple[tuple[str, str], ...]
    locked: Mapping[str, float]
    mimic: Mapping[str, str]
    mesh_dirs: tuple[str, ...]


def _load(doc: MjcfDocument, name: str) -> tuple[pin.Model, pin.GeometryModel, pin.GeometryModel]:
    """Pinocchio's model, collision model and visual model of the flattened document."""
    failure: Exception | None = None
    with tempfile.TemporaryDirectory(prefix="dexplan-mjcf-") as tmp:
        path = Path(tmp) / "hand.xml"
        path.write_text(ET.tostring(doc.root, encoding="unicode"))
        with captured_stderr() as err:
            try:
                model = pin.buildModelFromMJCF(str(path))
                geom = pin.buildGeomFromMJCF(model, str(path), pin.COLLISION)
                visual = pin.buildGeomFromMJCF(model, str(path), pin.VISUAL)
            except (RuntimeError, ValueError) as exc:
                failure = exc
    if failure is not None:
        detail = err.first_line() or " ".join(str(failure).split()).split("message: ")[-1]
        raise ModelError(f"cannot load MJCF hand {name!r}: {shorten(detail, 200)}") from failure
    return model, geom, visual


def _chain(model: pin.Model, jid: int) -> list[int]:
    out = []
    while jid > 0:
        out.append(jid)
        jid = model.parents[jid]
    return out[::-1]


def _locks(
    model: pin.Model,
    tips: Sequence[int],
    given: Mapping[str, float],
    doc: MjcfDocument,
    name: str,
) -> tuple[ResolvedJoints, int]:
    """Locked, following and free joints with their ranges; and the palm's joint."""
    names = list(model.names)
    ranges = {
        names[j]: (
            float(model.lowerPositionLimit[model.idx_qs[j]]),
            float(model.upperPositionLimit[model.idx_qs[j]]),
        )
        for j in range(1, model.njoints)
    }
    for joint, value in given.items():
        if joint not in ranges:
            raise ModelError(
                f"hand {name!r}: locked_joints names unknown joint {shorten(joint)} "
                f"(joints: {shorten(names[1:], 200)})"
            )
        lo, hi = ranges[joint]
        if not lo - 1e-9 <= value <= hi + 1e-9:
            raise ModelError(
                f"hand {name!r}: locked_joints[{joint!r}] = {value!r} is outside the joint's "
                f"range [{lo:g}, {hi:g}]"
            )
    chains = [_chain(model, model.frames[f].parentJoint) for f in tips]
    common = 0
    for level in zip(*chains, strict=False):
        if len(set(level)) != 1:
            break
        common = level[0]
    above = set(_chain(model, common))
    fingers = {j for c in chains for j in c if j not in above}
    locked: dict[str, float] = {}
    for j in range(1, model.njoints):
        if names[j] in given:
            locked[names[j]] = float(given[names[j]])
        elif j not in fingers:  # above the palm, or a finger not listed
            locked[names[j]] = float(np.clip(0.0, *ranges[names[j]]))
    resolved = resolve_couplings(couplings(doc), locked, ranges, actuated_joints(doc), name)
    return resolved, common


# ------------------------------------------------------------------- URDF export
def _xyz_rpy(m: pin.SE3) -> str:
    xyz = " ".join(repr(float(v)) for v in m.translation)
    rpy = " ".join(repr(float(v)) for v in pin.rpy.matrixToRpy(m.rotation))
    return f'<origin xyz="{xyz}" rpy="{rpy}"/>'


def _geometry_xml(go: pin.GeometryObject, mesh_dirs: Sequence[Path], name: str) -> str:
    g = go.geometry
    if isinstance(g, coal.Sphere):
        return f'<sphere radius="{g.radius!r}"/>'
    if isinstance(g, coal.Box):
        size = " ".join(repr(2.0 * float(v)) for v in g.halfSide)
        return f'<box size="{size}"/>'
    if isinstance(g, coal.Capsule):  # dexplan's <capsule>: length between the cap centres
        return f'<capsule radius="{g.radius!r}" length="{2.0 * g.halfLength!r}"/>'
    if isinstance(g, coal.Cylinder):
        return f'<cylinder radius="{g.radius!r}" length="{2.0 * g.halfLength!r}"/>'
    if go.meshPath and Path(go.meshPath).is_file():
        scale = " ".join(repr(float(v)) for v in go.meshScale)
        return f'<mesh filename="{_mesh_uri(Path(go.meshPath), mesh_dirs)}" scale="{scale}"/>'
    raise ModelError(
        f"hand {name!r}: collision geom {go.name!r} is a {type(g).__name__}; dexplan reads "
        "sphere, box, capsule, cylinder and mesh geoms"
    )


def _mesh_uri(path: Path, mesh_dirs: Sequence[Path]) -> str:
    """A ``package://`` URI inside an installed Python package, else relative to the MJCF."""
    uri = package_uri(path)
    if uri is not None:
        return uri
    for d in mesh_dirs:
        try:
            return path.resolve().relative_to(d.resolve()).as_posix()
        except ValueError:
            continue
    return str(path.resolve())


@dataclass(frozen=True)
class _Export:
    model: pin.Model
    geom: pin.GeometryModel
    visual: pin.GeometryModel  # drawn by the viewer, never checked
    base: int  # the palm's BODY frame
    joints: ResolvedJoints
    efforts: Mapping[str, float]
    mesh_dirs: tuple[Path, ...]
    name: str


def _own_body(model: pin.Model, j: int) -> int | None:
    """The BODY frame a joint moves directly (its MJCF body), or None."""
    for i, f in enumerate(model.frames):
        if f.type == pin.FrameType.BODY and f.parentJoint == j:
            prev = model.frames[f.parentFrame]
            if prev.type == pin.FrameType.JOINT and prev.parentJoint == j:
                return i
    return None


def _urdf(ex: _Export, tips: Sequence[str]) -> str:
    """The URDF text: one link per joint (its body's name), fixed links for the rest.

    Every placement Pinocchio gives is relative to a joint frame; ``frame[L]``
    is link L's frame relative to its joint's (the identity for a joint's own
    link, whose frame is the joint frame; the palm's placement for the root).
    """
    model = ex.model
    base = model.frames[ex.base]
    link_of_joint = {0: base.name}
    frame = {base.name: base.placement}
    for j in range(1, model.njoints):
        own = _own_body(model, j)
        link_of_joint[j] = model.frames[own].name if own is not None else f"{model.names[j]}_link"
        frame[link_of_joint[j]] = pin.SE3.Identity()
    links: list[str] = list(dict.fromkeys(link_of_joint.values()))
    fixed: list[str] = []
    for f in model.frames:
        is_tip = f.type == pin.FrameType.OP_FRAME and f.name in tips
        if not (f.type == pin.FrameType.BODY or is_tip) or f.name in frame or f.name == "universe":
            continue
        parent = link_of_joint[f.parentJoint]
        frame[f.name] = f.placement
        links.append(f.name)
        fixed.append(
            f'<joint name="{f.name}_fixed" type="fixed"><parent link="{parent}"/>'
            f'<child link="{f.name}"/>{_xyz_rpy(frame[parent].inverse() * f.placement)}</joint>'
        )
    collisions: dict[str, list[str]] = {}
    for tag, gm in (("visual", ex.visual), ("collision", ex.geom)):
        for go in gm.geometryObjects:
            body = model.frames[go.parentFrame].name
            link = body if body in frame and body in links else link_of_joint[go.parentJoint]
            place = frame[link].inverse() * go.placement
            try:
                shape = _geometry_xml(go, ex.mesh_dirs, ex.name)
            except ModelError:
                if tag == "visual":  # a shape URDF lacks only changes how the hand looks
                    continue
                raise
            collisions.setdefault(link, []).append(
                f"<{tag}>{_xyz_rpy(place)}<geometry>{shape}</geometry></{tag}>"
            )
    inertials = {
        link_of_joint[j]: _inertial_xml(model.inertias[j]) for j in range(1, model.njoints)
    }
    parts = [f'<robot name="{ex.name}">']
    parts += [
        f'<link name="{k}">{inertials.get(k, "")}{"".join(collisions.get(k, []))}</link>'
        for k in links
    ]
    for j in range(1, model.njoints):
        origin = frame[link_of_joint[model.parents[j]]].inverse() * model.jointPlacements[j]
        parts.append(_joint_xml(ex, j, link_of_joint, origin))
    return "\n".join([*parts, *fixed, "</robot>"])


def _inertial_xml(inertia: pin.Inertia) -> str:
    """A joint link's ``<inertial>``: the MJCF bodies it moves, merged by Pinocchio.

    The replay's physics needs them; planning does not.
    """
    rows = np.asarray(inertia.inertia, dtype=float).tolist()  # about the centre of mass
    com = " ".join(repr(float(v)) for v in inertia.lever)
    return (
        f'<inertial><origin xyz="{com}" rpy="0 0 0"/><mass value="{float(inertia.mass)!r}"/>'
        f'<inertia ixx="{rows[0][0]!r}" ixy="{rows[0][1]!r}" ixz="{rows[0][2]!r}" '
        f'iyy="{rows[1][1]!r}" iyz="{rows[1][2]!r}" izz="{rows[2][2]!r}"/></inertial>'
    )


def _joint_xml(ex: _Export, j: int, link_of_joint: Mapping[int, str], origin: pin.SE3) -> str:
    model, jname = ex.model, ex.model.names[j]
    jm = model.joints[j]
    short = jm.shortname().replace("JointModel", "")
    if short in _REVOLUTE or short in _PRISMATIC:
        kind = "revolute" if short in _REVOLUTE else "prismatic"
        axis = _REVOLUTE.get(short) or _PRISMATIC[short]
    elif short in ("RevoluteUnaligned", "PrismaticUnaligned"):
        kind = "revolute" if short.startswith("Revolute") else "prismatic"
        x, y, z = (float(v) for v in jm.extract().axis)
        axis = (x, y, z)
    else:
        raise ModelError(
            f"hand {ex.name!r}: joint {jname!r} is a {short} joint; dexplan plans hinge and "
            "slide joints (lock it with [hand] locked_joints)"
        )
    lo, hi = ex.joints.ranges[jname]
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ModelError(f"hand {ex.name!r}: joint {jname!r} has no finite range in the MJCF")
    effort = ex.efforts.get(jname, _NO_EFFORT)
    m = ex.joints.mimic.get(jname)
    mimic = ""
    if m is not None:  # the coupling it comes from, as a comment (no "--" in XML comments)
        source = m.source.replace("--", "- -")
        mimic = (
            f'<!-- {source} --><mimic joint="{m.primary}" multiplier="{m.multiplier!r}" '
            f'offset="{m.offset!r}"/>'
        )
    return (
        f'<joint name="{jname}" type="{kind}"><parent link="{link_of_joint[model.parents[j]]}"/>'
        f'<child link="{link_of_joint[j]}"/>{_xyz_rpy(origin)}'
        f'<axis xyz="{" ".join(repr(a) for a in axis)}"/>'
        f'<limit lower="{lo!r}" upper="{hi!r}" effort="{effort!r}" velocity="10"/>{mimic}</joint>'
    )


def _excluded_links(doc: MjcfDocument, links: Sequence[str]) -> tuple[tuple[str, str], ...]:
    """Link pairs MuJoCo's filters never let touch (contype/conaffinity, parent-child, exclude)."""
    filt = contact_filter(doc)
    with_geoms = [b for b in links if filt.geoms.get(b)]
    out = []
    for k, a in enumerate(with_geoms):
        for b in with_geoms[k + 1 :]:
            if not filt.bodies_collide(a, b):
                out.append((a, b))
    return tuple(out)


def mjcf_hand(
    path: Path,
    fingertip_frames: Sequence[str],
    locked_joints: Mapping[str, float] | None = None,
    *,
    name: str = "hand",
) -> MjcfHand:
    """Load an MJCF hand and export the URDF dexplan plans with.

    Args:
        path: the MJCF file.
        fingertip_frames: per finger, a site or body at its fingertip sphere's centre.
        locked_joints: joint values (rad, m) to lock, by MJCF joint name.
        name: the hand's name, for messages and the URDF's ``<robot name>``.

    Raises:
        ModelError: unreadable MJCF, unknown fingertip frames or joints, a
            coupling between joints that are not locked, a joint that is
            neither hinge nor slide, a geom dexplan cannot represent.
    """
    path = Path(path)
    tops = body_of_names(flatten_mjcf(path))
    hand_bodies = {tops[t] for t in fingertip_frames if t in tops}
    missing = [t for t in fingertip_frames if t not in tops]
    if missing or len(hand_bodies) != 1:
        what = (
            f"unknown fingertip frame {missing[0]!r}" if missing else "fingertips on several bodies"
        )
        raise ModelError(
            f"hand {name!r}: {what} in MJCF file {str(path)!r} (sites and bodies: "
            f"{shorten(sorted(tops), 200)})"
        )
    doc = flatten_mjcf(path, keep_body=hand_bodies.pop())
    full, geom, visual = _load(doc, name)
    tip_ids = [full.getFrameId(t) for t in fingertip_frames]
    joints, palm_joint = _locks(full, tip_ids, dict(locked_joints or {}), doc, name)
    q_ref = pin.neutral(full)
    for joint, value in joints.locked.items():
        q_ref[full.idx_qs[full.getJointId(joint)]] = value
    palm_name = deepest_common_body(doc, list(fingertip_frames))
    if full.frames[full.getFrameId(palm_name)].parentJoint != palm_joint:
        raise ModelError(
            f"hand {name!r}: the fingertips' deepest common body {palm_name!r} is not "
            "moved by the joints above every finger only"
        )
    lock_ids = [full.getJointId(j) for j in joints.locked]
    model, (geom, visual) = pin.buildReducedModel(full, [geom, visual], lock_ids, q_ref)
    mesh_dirs = (path.resolve().parent,)
    efforts = effort_limits(doc)
    palm = model.getFrameId(palm_name)
    ex = _Export(model, geom, visual, palm, joints, efforts, mesh_dirs, name)
    locks = ", ".join(f"{k}={v:.6g}" for k, v in joints.locked.items()) or "none"
    note = (
        f"<!-- dexplan: exported from MJCF {path.name} (sha256 "
        f"{hashlib.sha256(path.read_bytes()).hexdigest()}); palm {palm_name!r} at the origin; "
        f"locked joints: {locks} -->"
    )
    urdf = _urdf(ex, fingertip_frames).replace(">", ">\n" + note, 1)
    links = [f.name for f in model.frames if f.type == pin.FrameType.BODY]
    return MjcfHand(
        urdf,
        _excluded_links(doc, links),
        dict(joints.locked),
        {k: m.primary for k, m in joints.mimic.items()},
        tuple(str(d) for d in mesh_dirs),
    )


def mjcf_arguments(spec: HandSpec) -> tuple[str, dict[str, Any]]:
    """The URDF text and the keyword arguments of the :class:`Hand` a ``[hand] mjcf`` names."""
    assert spec.mjcf is not None
    name = spec.mjcf.stem
    m = mjcf_hand(spec.mjcf, spec.fingertip_frames, spec.locked_joints, name=name)
    return m.urdf_xml, {
        "collision_exclude": (*m.collision_exclude, *spec.collision_exclude),
        "name": name,
        "package_dirs": m.mesh_dirs,
        "effort_limits": spec.effort_limits,
    }
