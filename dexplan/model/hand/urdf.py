"""URDF hands: text and XML checks, capsule collision elements, model building.

:class:`dexplan.model.hand.hand.Hand` loads its URDF through these functions; the rules
they enforce are documented in ``docs/hands.md``. urdfdom and Pinocchio write
their complaints to file descriptor 2: those are captured
(:func:`dexplan.core.native_output.captured_stderr`) and the first line becomes part
of the :class:`~dexplan.core.errors.ModelError`.
"""

from __future__ import annotations

import difflib
import math
import re
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin

from dexplan.core.errors import ModelError, shorten
from dexplan.core.native_output import captured_stderr

#: Name of the fixed root link :func:`mount_urdf` adds in front of a URDF.
MOUNT_LINK = "dexplan_world"


@dataclass(frozen=True)
class _Capsule:
    """A ``<capsule>`` collision element (urdfdom cannot parse it).

    Attributes:
        radius: capsule radius (m).
        length: distance between the two cap centres (m), along local z.
        placement: pose of the capsule in its link frame (``<origin>``).
    """

    radius: float
    length: float
    placement: pin.SE3


@dataclass
class UrdfDescription:
    """What dexplan reads from the URDF XML itself.

    Attributes:
        collisions: per link name, its ``<collision>`` elements in file order:
            a :class:`_Capsule`, or a short description of an element left to
            Pinocchio (``"box"``, ``"mesh 'x.stl'"``).
        pinocchio_xml: the URDF without visuals and capsules, for Pinocchio.
    """

    collisions: dict[str, list[_Capsule | str]] = field(default_factory=dict)
    pinocchio_xml: str = ""


def urdf_text(data: object, what: str) -> str:
    """URDF text from ``str`` or UTF-8 ``bytes``.

    Raises:
        ModelError: not text, not UTF-8, or containing NUL characters.
    """
    if isinstance(data, bytes | bytearray):
        try:
            text = bytes(data).decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ModelError(
                f"{what} is not a UTF-8 text URDF "
                f"(byte {data[exc.start]:#04x} at offset {exc.start})"
            ) from None
    elif isinstance(data, str):
        text = data
        try:
            text.encode("utf-8")
        except UnicodeEncodeError as exc:
            raise ModelError(
                f"{what} is not a UTF-8 text URDF (unencodable character at offset {exc.start})"
            ) from None
    else:
        raise ModelError(f"{what} must be URDF text, got {type(data).__name__} {shorten(data)}")
    nul = text.find("\x00")
    if nul >= 0:
        raise ModelError(f"{what} is not a UTF-8 text URDF (NUL character at offset {nul})")
    return text[1:] if text.startswith("\ufeff") else text


def _floats(raw: str | None, n: int, what: str) -> list[float]:
    """``n`` finite floats from a URDF attribute (``None`` means zeros)."""
    if raw is None:
        return [0.0] * n
    try:
        vals = [float(t) for t in raw.split()]
    except ValueError:
        vals = []
    if len(vals) != n or not all(math.isfinite(v) for v in vals):
        raise ModelError(f"{what} must be {n} finite numbers, got {shorten(raw)}")
    return vals


def _origin(elem: ET.Element | None, what: str) -> pin.SE3:
    """SE3 of a URDF ``<origin xyz= rpy=>`` (identity when absent)."""
    if elem is None:
        return pin.SE3.Identity()
    xyz = _floats(elem.get("xyz"), 3, f"{what} xyz")
    rpy = _floats(elem.get("rpy"), 3, f"{what} rpy")
    return pin.SE3(pin.rpy.rpyToMatrix(*rpy), np.array(xyz))


def _parse_capsule(col: ET.Element, shape: ET.Element, link: str, name: str) -> _Capsule:
    """A :class:`_Capsule` from ``<collision><geometry><capsule radius= length=>``."""
    what = f"hand {name!r}: <capsule> of link {link!r}"
    vals = {}
    for key in ("radius", "length"):
        raw = shape.get(key)
        try:
            # any object: float() raises on the wrong ones, reported below
            v = float(raw)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            v = math.nan
        if not math.isfinite(v) or v < 0.0 or (key == "radius" and v == 0.0):
            bound = "> 0" if key == "radius" else ">= 0"
            raise ModelError(f"{what}: {key} must be a finite number {bound}, got {shorten(raw)}")
        vals[key] = v
    placement = _origin(col.find("origin"), f"{what}: origin")
    return _Capsule(vals["radius"], vals["length"], placement)


def _check_joint_xml(joint: ET.Element, name: str) -> None:
    """Type and limits of a URDF ``<joint>``: 1-DOF with finite, ordered limits."""
    jname = joint.get("name", "")
    jtype = joint.get("type", "")
    if jtype == "fixed":
        return
    if jtype not in ("revolute", "prismatic"):
        raise ModelError(
            f"hand {name!r}: joint {shorten(jname)} has type {shorten(jtype)}; dexplan "
            "supports revolute and prismatic joints with finite limits, and fixed joints"
        )
    limit = joint.find("limit")
    if limit is None:
        raise ModelError(f"hand {name!r}: {jtype} joint {jname!r} has no <limit lower= upper=>")
    bounds = []
    for key in ("lower", "upper"):
        raw = limit.get(key, "0")  # the URDF default
        try:
            v = float(raw)
        except ValueError:
            v = math.nan
        if not math.isfinite(v):
            raise ModelError(
                f"hand {name!r}: joint {jname!r}: limit {key} must be a finite number, "
                f"got {shorten(raw)}"
            )
        bounds.append(v)
    if bounds[0] > bounds[1]:
        raise ModelError(
            f"hand {name!r}: joint {jname!r} has inverted limits: "
            f"lower={bounds[0]!r} > upper={bounds[1]!r}"
        )


def parse_urdf(text: str, name: str) -> UrdfDescription:
    """Check the XML and the joints; read the collision elements; strip capsules.

    Raises:
        ModelError: malformed XML (with the parser's line and column), a root
            element other than ``<robot>``, bad joints or bad capsules.
    """
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise ModelError(f"hand {name!r}: malformed URDF XML: {exc}") from None
    if root.tag != "robot":
        raise ModelError(
            f"hand {name!r}: the URDF's root element must be <robot>, got <{root.tag[:40]}>"
        )
    for joint in root.findall("joint"):
        _check_joint_xml(joint, name)
    desc = UrdfDescription()
    for link in root.findall("link"):
        lname = link.get("name", "")
        entries: list[_Capsule | str] = []
        for col in link.findall("collision"):
            geometry = col.find("geometry")
            shape = geometry[0] if geometry is not None and len(geometry) else None
            if shape is not None and shape.tag == "capsule":
                entries.append(_parse_capsule(col, shape, lname, name))
                link.remove(col)
            elif shape is None:
                entries.append("empty <geometry>")
            elif shape.tag == "mesh":
                entries.append(f"<mesh filename={shorten(shape.get('filename'))}>")
            else:
                entries.append(f"<{shape.tag[:40]}>")
        for visual in link.findall("visual"):  # never loaded; may hold capsules too
            link.remove(visual)
        desc.collisions[lname] = entries
    desc.pinocchio_xml = ET.tostring(root, encoding="unicode")
    return desc


def build_models(
    desc: UrdfDescription, name: str, package_dirs: Sequence[str | Path]
) -> tuple[pin.Model, pin.GeometryModel]:
    """Pinocchio model and collision model (capsules included, in URDF order).

    urdfdom and Pinocchio write to fd 2; that text is captured and its first
    line becomes part of the ModelError when loading fails.

    Raises:
        ModelError: Pinocchio rejects the URDF, joints that are not 1-DOF, no
            joints, or a collision element that was not loaded.
    """
    model, notes = _kinematic_model(desc, name)
    geom, geom_notes = _pinocchio_geometry(model, desc, name, package_dirs)
    loaded: dict[str, list[pin.GeometryObject]] = {}
    for go in geom.geometryObjects:
        loaded.setdefault(model.frames[go.parentFrame].name, []).append(go)
    out = pin.GeometryModel()
    for fid, frame in enumerate(model.frames):
        if frame.type != pin.FrameType.BODY:
            continue
        entries = desc.collisions.get(frame.name, [])
        native = [e for e in entries if not isinstance(e, _Capsule)]
        from_pin = loaded.get(frame.name, [])
        if len(from_pin) != len(native):
            hint = (
                notes
                or geom_notes
                or (
                    "mesh files are searched in package_dirs "
                    f"{shorten([str(p) for p in package_dirs], 120)}"
                )
            )
            raise ModelError(
                f"hand {name!r}: link {frame.name!r}: {len(from_pin)} of its {len(native)} "
                f"collision elements {shorten(native, 120)} loaded ({hint})"
            )
        for go in _link_geometry(frame, fid, entries, from_pin):
            out.addGeometryObject(go)
    return model, out


def _kinematic_model(desc: UrdfDescription, name: str) -> tuple[pin.Model, str]:
    """The Pinocchio model and the first line urdfdom printed while loading it.

    Raises:
        ModelError: Pinocchio rejects the URDF, joints that are not 1-DOF, or no joints.
    """
    failure: Exception | None = None
    with captured_stderr() as err:
        try:
            # <mimic> joints (an MJCF hand's couplings, .couplings) follow
            # their joint exactly: one degree of freedom, as Pinocchio models it
            mimic = "<mimic" in desc.pinocchio_xml
            model = pin.buildModelFromXML(desc.pinocchio_xml, mimic=mimic)
        except (RuntimeError, ValueError) as exc:
            failure = exc
    if failure is not None:
        raise ModelError(
            f"cannot parse URDF for hand {name!r}: {err.first_line() or failure}"
        ) from failure
    if model.nq != model.nv:
        raise ModelError(
            f"hand {name!r}: only 1-DOF revolute/prismatic joints are supported "
            f"(nq={model.nq}, nv={model.nv})"
        )
    if model.nq == 0:
        raise ModelError(f"hand {name!r} has no actuated joints")
    return model, err.first_line()


def _pinocchio_geometry(
    model: pin.Model, desc: UrdfDescription, name: str, package_dirs: Sequence[str | Path]
) -> tuple[pin.GeometryModel, str]:
    """The collision elements Pinocchio loads itself (all but the capsules).

    Returns:
        The geometry model and the first line printed while loading it.

    Raises:
        ModelError: Pinocchio cannot build the collision model (the message names
            ``package_dirs`` when the URDF has meshes).
    """
    failure: Exception | None = None
    with captured_stderr() as err:
        try:
            geom = pin.buildGeomFromUrdfString(
                model,
                desc.pinocchio_xml,
                pin.COLLISION,
                package_dirs=[str(p) for p in package_dirs],
            )
        except (RuntimeError, ValueError) as exc:
            failure = exc
    if failure is not None:
        detail = err.first_line() or " ".join(str(failure).split())
        if any(
            e.startswith("<mesh")
            for es in desc.collisions.values()
            for e in es
            if isinstance(e, str)
        ):
            detail += f" (package_dirs: {shorten([str(p) for p in package_dirs], 120)})"
        raise ModelError(f"cannot build collision model of hand {name!r}: {detail}") from failure
    return geom, err.first_line()


def _link_geometry(
    frame: pin.Frame,
    fid: int,
    entries: Sequence[_Capsule | str],
    from_pin: Sequence[pin.GeometryObject],
) -> list[pin.GeometryObject]:
    """One link's collision objects in URDF order, named ``<link>_<k>``.

    Capsules are built here (coal capsules at the link's placement); the other
    entries are Pinocchio's objects ``from_pin``, in the same order.
    """
    out = []
    it = iter(from_pin)
    for k, entry in enumerate(entries):
        if isinstance(entry, _Capsule):
            go = pin.GeometryObject(
                f"{frame.name}_{k}",
                frame.parentJoint,
                fid,
                frame.placement * entry.placement,
                coal.Capsule(entry.radius, entry.length),
            )
        else:
            go = next(it)
            go.name = f"{frame.name}_{k}"
        out.append(go)
    return out


def _zero_length_body(model: pin.Model, jid: int) -> bool:
    """True when every child joint of joint ``jid`` sits at its origin (a virtual link)."""
    children = [c for c in range(1, model.njoints) if model.parents[c] == jid]
    return bool(children) and all(
        float(np.linalg.norm(model.jointPlacements[c].translation)) < 1e-9 for c in children
    )


def check_finger_geometry(
    model: pin.Model, geom: pin.GeometryModel, tip_frame: int, name: str
) -> None:
    """Every link of a finger carries collision geometry.

    Rules: the child link of every joint of the finger's chain has a collision
    element of its own, except a zero-length link (its child joints sit at its
    joint's origin, as between the two joints of a universal knuckle) that
    does not hold the fingertip. The fingertip sphere itself is
    :mod:`dexplan.model.hand.fingertips`' business.

    Raises:
        ModelError: naming the first link without geometry.
    """
    frames = model.frames
    tip = frames[tip_frame].name
    own = {go.parentFrame for go in geom.geometryObjects}
    jid = frames[tip_frame].parentJoint
    distal = True
    while jid > 0:
        link_id = next(
            (
                i
                for i, f in enumerate(frames)
                if f.type == pin.FrameType.BODY and f.parentJoint == jid
            ),
            None,
        )
        if (
            link_id is not None
            and link_id not in own
            and (distal or not _zero_length_body(model, jid))
        ):
            raise ModelError(
                f"hand {name!r}: link {frames[link_id].name!r} (moved by joint "
                f"{model.names[jid]!r}, finger {tip!r}) has no collision geometry; every "
                "finger link needs a <collision> element"
            )
        distal = False
        jid = model.parents[jid]


def check_collision_exclude(
    pairs: object, links: set[str], name: str
) -> tuple[tuple[str, str], ...]:
    """``collision_exclude`` as link-name pairs, every name a link of the model."""
    try:
        # any object: list() raises on a non-iterable, reported below
        items = list(pairs)  # type: ignore[call-overload]
    except TypeError:
        items = None
    if items is None or isinstance(pairs, str | bytes):
        raise ModelError(
            f"hand {name!r}: collision_exclude must be a list of [link, link] pairs, "
            f"got {shorten(pairs)}"
        )
    out = []
    for k, pair in enumerate(items):
        if isinstance(pair, str | bytes) or not isinstance(pair, Sequence) or len(pair) != 2:
            raise ModelError(
                f"hand {name!r}: collision_exclude[{k}] must be a [link, link] pair, "
                f"got {shorten(pair)}"
            )
        for link in pair:
            if not isinstance(link, str) or link not in links:
                close = difflib.get_close_matches(str(link), sorted(links), n=1)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                raise ModelError(
                    f"hand {name!r}: collision_exclude[{k}] names unknown link "
                    f"{shorten(link)}{hint} (links: {shorten(sorted(links), 160)})"
                )
        out.append((pair[0], pair[1]))
    return tuple(out)


# ------------------------------------------------------------ world placement
def mount_urdf(
    urdf_xml: str,
    rpy: Sequence[float],
    xyz: Sequence[float] = (0.0, 0.0, 0.0),
    *,
    root_link: str = MOUNT_LINK,
) -> str:
    """The URDF text with its root link fixed in a new world link.

    Adds ``<link name=root_link/>`` and a fixed joint ``<root_link>_mount``
    from it to the URDF's root link, right after the ``<robot>`` tag; the rest
    of the text is unchanged. The placement is part of the URDF text, so a plan
    file that carries it is self-contained.

    Args:
        urdf_xml: URDF text.
        rpy: roll, pitch, yaw (URDF fixed-axis XYZ) of the old root in the world.
        xyz: position (m) of the old root's origin in the world.
        root_link: name of the new root link.

    Returns:
        The mounted URDF text.

    Raises:
        ModelError: malformed XML, no single root link, or ``root_link`` taken.
    """
    try:
        root = ET.fromstring(urdf_xml)
    except ET.ParseError as exc:
        raise ModelError(f"cannot mount URDF: malformed XML: {exc}") from None
    links = [ln.get("name", "") for ln in root.findall("link")]
    children = {c.get("link") for j in root.findall("joint") for c in j.findall("child")}
    roots = [ln for ln in links if ln not in children]
    if root_link in links:
        raise ModelError(f"cannot mount URDF: it already has a link named {root_link!r}")
    if len(roots) != 1:
        raise ModelError(f"cannot mount URDF: expected one root link, got {shorten(roots)}")
    rpy_v = _floats(" ".join(map(repr, map(float, rpy))), 3, "mount rpy")
    xyz_v = _floats(" ".join(map(repr, map(float, xyz))), 3, "mount xyz")
    masked = re.sub(r"<!--.*?-->", lambda m: " " * len(m.group()), urdf_xml, flags=re.S)
    tag = re.search(r"<robot\b[^>]*>", masked)
    if tag is None or tag.group().endswith("/>"):
        raise ModelError("cannot mount URDF: no <robot> element with content")
    mount = (
        f"\n  <!-- dexplan: {roots[0]} fixed in the world frame -->"
        f'\n  <link name="{root_link}"/>'
        f'\n  <joint name="{root_link}_mount" type="fixed">'
        f'\n    <parent link="{root_link}"/>'
        f'\n    <child link="{roots[0]}"/>'
        f'\n    <origin xyz="{" ".join(map(repr, xyz_v))}" rpy="{" ".join(map(repr, rpy_v))}"/>'
        "\n  </joint>"
    )
    return urdf_xml[: tag.end()] + mount + urdf_xml[tag.end() :]


# --------------------------------------------------------------- effort limits
#: Largest effort limit accepted (N m or N): larger values are taken for a unit mistake.
MAX_EFFORT_LIMIT = 1e4


def with_effort_limits(
    urdf_xml: str, limits: float | Mapping[str, float], *, what: str = "hand.effort_limits"
) -> str:
    """The URDF text with its joints' ``<limit effort=...>`` replaced.

    The planner, ``verify`` and ``export`` read the effort limits from the
    URDF a plan carries, so a scenario's override is written into that text.

    Args:
        urdf_xml: URDF text.
        limits: one limit (N m; N for prismatic joints) for every actuated
            joint, or a table by joint name (the others keep the URDF's).
        what: the field named in error messages.

    Returns:
        The URDF text with the new ``effort`` attributes (comments kept).

    Raises:
        ModelError: a limit that is not a finite number in (0, 1e4], a joint
            name the URDF has not (with the closest names), or an actuated
            joint without a ``<limit>`` element.
    """
    try:
        root = ET.fromstring(
            urdf_xml, parser=ET.XMLParser(target=ET.TreeBuilder(insert_comments=True))
        )
    except ET.ParseError as exc:
        raise ModelError(f"{what}: malformed URDF XML: {exc}") from None
    joints = {
        j.get("name", ""): j
        for j in root.iter("joint")
        if j.get("type") in ("revolute", "continuous", "prismatic")
    }
    table = (
        dict.fromkeys(joints, limits)
        if not isinstance(limits, Mapping)
        else {str(k): v for k, v in limits.items()}
    )
    for name, value in table.items():
        if name not in joints:
            close = difflib.get_close_matches(name, list(joints), n=3, cutoff=0.5)
            hint = f" (did you mean {', '.join(map(repr, close))}?)" if close else ""
            raise ModelError(
                f"{what}: the hand has no actuated joint {shorten(name)}{hint}; "
                f"its joints: {shorten(sorted(joints), 200)}"
            )
        v = _effort_value(value, f"{what}[{name!r}]" if isinstance(limits, Mapping) else what)
        elem = joints[name].find("limit")
        if elem is None:
            raise ModelError(f"{what}: joint {name!r} has no <limit> element to set")
        elem.set("effort", repr(v))
    return ET.tostring(root, encoding="unicode")


def _effort_value(value: object, what: str) -> float:
    """``value`` as an effort limit in (0, :data:`MAX_EFFORT_LIMIT`], else ModelError."""
    ok = isinstance(value, int | float) and not isinstance(value, bool)
    v = float(value) if ok else math.nan  # type: ignore[arg-type]
    if not (math.isfinite(v) and 0.0 < v <= MAX_EFFORT_LIMIT):
        raise ModelError(
            f"{what} must be a finite number in (0, {MAX_EFFORT_LIMIT:g}] (N m), "
            f"got {shorten(value)}"
        )
    return v
