"""What dexplan reads from an MJCF file's XML beside Pinocchio's MJCF reader.

Pinocchio builds the kinematic and collision models (:mod:`.mjcf`); it skips
``<include>`` elements, reads only the first body of ``<worldbody>``, and
ignores actuators, tendons and equality constraints. This module gives it a
single flattened document holding the hand alone (:func:`flatten_mjcf`) and
reads the rest from the XML:

- effort limits: per joint, the sum over the actuators driving it of
  ``|gear| * max|forcerange|`` (when force-limited), capped by the joint's
  ``actuatorfrcrange`` (:func:`effort_limits`);
- couplings: limited fixed tendons over joints and joint equality constraints
  (:func:`couplings`);
- contact filters: each collision geom's body, ``contype`` and ``conaffinity``,
  the ``<contact><exclude>`` body pairs and the ``<contact><pair>`` geom pairs
  (:func:`contact_filter`).

Attribute values follow MuJoCo's default classes: the element's own, else its
``class`` (or the nearest ``childclass`` above it), then that class's parents,
then ``main``.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from dexplan.core.errors import ModelError, shorten

__all__ = [
    "ContactFilter",
    "Coupling",
    "MjcfDocument",
    "actuated_joints",
    "body_of_names",
    "contact_filter",
    "couplings",
    "deepest_common_body",
    "effort_limits",
    "flatten_mjcf",
]

#: Actuator elements whose ``joint`` attribute names the joint they drive.
ACTUATOR_TAGS = frozenset(
    {"general", "motor", "position", "velocity", "intvelocity", "damper", "cylinder", "muscle"}
)
_MAX_INCLUDE_DEPTH = 16


@dataclass(frozen=True)
class MjcfDocument:
    """A flattened MJCF document and the default classes it defines.

    Attributes:
        root: the ``<mujoco>`` element, includes spliced in.
        defaults: per class name, its ``<default>`` element and its parent class.
    """

    root: ET.Element
    defaults: Mapping[str, tuple[ET.Element, str | None]]

    def attr(self, elem: ET.Element, key: str, active: str | None = None) -> str | None:
        """``key`` of ``elem`` after MuJoCo's defaults (``active``: childclass in force)."""
        if key in elem.attrib:
            return elem.get(key)
        cls: str | None = elem.get("class") or active or "main"
        tags = ACTUATOR_TAGS if elem.tag in ACTUATOR_TAGS else {elem.tag}
        while cls is not None and cls in self.defaults:
            node, parent = self.defaults[cls]
            for child in node:
                if child.tag in tags and key in child.attrib:
                    return child.get(key)
            cls = parent
        return None

    def floats(
        self, elem: ET.Element, key: str, what: str, active: str | None = None
    ) -> list[float]:
        """The numbers of attribute ``key`` (empty when absent)."""
        raw = self.attr(elem, key, active)
        if raw is None:
            return []
        try:
            vals = [float(t) for t in raw.split()]
        except ValueError:
            vals = [math.nan]
        if not all(math.isfinite(v) for v in vals):
            raise ModelError(f"{what}: {key} must be finite numbers, got {shorten(raw)}")
        return vals


def _splice_includes(elem: ET.Element, folder: Path, depth: int) -> None:
    """Replace every ``<include file=>`` below ``elem`` by the included file's children."""
    for k, child in reversed(list(enumerate(elem))):
        if child.tag != "include":
            _splice_includes(child, folder, depth)
            continue
        if depth >= _MAX_INCLUDE_DEPTH:
            raise ModelError(f"MJCF includes nest deeper than {_MAX_INCLUDE_DEPTH} files")
        path = folder / child.get("file", "")
        try:
            sub = ET.parse(path).getroot()
        except (OSError, ET.ParseError) as exc:
            raise ModelError(f"MJCF include {str(path)!r}: {' '.join(str(exc).split())}") from None
        _splice_includes(sub, folder, depth + 1)
        elem.remove(child)
        for j, item in enumerate(list(sub)):
            elem.insert(k + j, item)


def _absolute_asset_dirs(root: ET.Element, folder: Path) -> None:
    """Make ``meshdir`` absolute (relative to the main file's folder, as MuJoCo reads it)."""
    compiler = root.find("compiler")
    if compiler is None:
        compiler = ET.Element("compiler")
        root.insert(0, compiler)
    mesh = compiler.get("meshdir") or compiler.get("assetdir") or "."
    compiler.set("meshdir", str((folder / mesh).resolve()))
    compiler.attrib.pop("assetdir", None)


def _defaults(root: ET.Element) -> dict[str, tuple[ET.Element, str | None]]:
    out: dict[str, tuple[ET.Element, str | None]] = {}

    def walk(node: ET.Element, parent: str | None) -> None:
        name = node.get("class", "main")
        out[name] = (node, parent)
        for child in node.findall("default"):
            walk(child, name)

    for top in root.findall("default"):
        walk(top, None)
    return out


def flatten_mjcf(path: Path, keep_body: str | None = None) -> MjcfDocument:
    """Read an MJCF file, splice its includes and make its mesh folder absolute.

    Args:
        path: the MJCF file.
        keep_body: when given, ``<worldbody>`` keeps only its top-level body of
            this name (Pinocchio reads the first body only); its own geoms
            and sites (the floor, targets) are dropped: they are not the hand.

    Raises:
        ModelError: unreadable or malformed XML, a root other than ``<mujoco>``.
    """
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise ModelError(f"MJCF file {str(path)!r}: malformed XML: {exc}") from None
    except OSError as exc:
        raise ModelError(f"cannot read MJCF file {str(path)!r}: {exc.strerror}") from None
    if root.tag != "mujoco":
        raise ModelError(
            f"MJCF file {str(path)!r}: root element must be <mujoco>, got <{root.tag}>"
        )
    folder = path.resolve().parent
    _splice_includes(root, folder, 0)
    _absolute_asset_dirs(root, folder)
    if keep_body is not None:
        for world in root.findall("worldbody"):
            for child in list(world):
                if child.tag != "body" or child.get("name") != keep_body:
                    world.remove(child)
    return MjcfDocument(root, _defaults(root))


def body_of_names(doc: MjcfDocument) -> dict[str, str]:
    """Top-level ``<worldbody>`` body holding each named body, site and geom."""
    out: dict[str, str] = {}
    for world in doc.root.findall("worldbody"):
        for top in world.findall("body"):
            for elem in top.iter():
                if elem.tag in ("body", "site", "geom") and elem.get("name"):
                    out[elem.get("name", "")] = top.get("name", "")
    return out


def deepest_common_body(doc: MjcfDocument, frames: list[str]) -> str:
    """The deepest body above (or at) every named site or body: the hand's palm."""
    parent: dict[str, str] = {}
    owner: dict[str, str] = {}

    def walk(body: ET.Element, up: str) -> None:
        name = body.get("name", "")
        parent[name], owner[name] = up, name
        for child in body:
            if child.tag == "site" and child.get("name"):
                owner[child.get("name", "")] = name
            elif child.tag == "body":
                walk(child, name)

    for world in doc.root.findall("worldbody"):
        for top in world.findall("body"):
            walk(top, "")
    paths = []
    for frame in frames:
        path, body = [], owner[frame]
        while body:
            path.append(body)
            body = parent[body]
        paths.append(path[::-1])
    common = ""
    for level in zip(*paths, strict=False):
        if len(set(level)) != 1:
            break
        common = level[0]
    return common


# -------------------------------------------------------------- effort limits
def _joint_elements(doc: MjcfDocument) -> dict[str, tuple[ET.Element, str | None]]:
    """Each named joint with the childclass in force where it is declared."""
    out: dict[str, tuple[ET.Element, str | None]] = {}

    def walk(body: ET.Element, active: str | None) -> None:
        active = body.get("childclass") or active
        for child in body:
            if child.tag == "joint" and child.get("name"):
                out[child.get("name", "")] = (child, child.get("class") or active)
            elif child.tag == "body":
                walk(child, active)

    for world in doc.root.findall("worldbody"):
        walk(world, None)
    return out


def _limited(doc: MjcfDocument, elem: ET.Element, key: str, range_key: str) -> bool:
    """MuJoCo's ``*limited`` flag: explicit true/false, else auto (a range given)."""
    flag = doc.attr(elem, key)
    if flag in ("true", "false"):
        return flag == "true"
    return doc.attr(elem, range_key) is not None


def effort_limits(doc: MjcfDocument) -> dict[str, float]:
    """Joint effort limits (N m, N) the MJCF states, by joint name.

    Joints no force-limited actuator drives and without ``actuatorfrcrange``
    are left out.
    """
    out: dict[str, float] = {}
    for act in doc.root.iter("actuator"):
        for a in act:
            joint = a.get("joint")
            if a.tag not in ACTUATOR_TAGS or not joint:
                continue
            what = f"MJCF actuator {a.get('name', a.tag)!r}"
            force = doc.floats(a, "forcerange", what)
            if not _limited(doc, a, "forcelimited", "forcerange") or len(force) != 2:
                continue
            gear = (doc.floats(a, "gear", what) or [1.0])[0]
            out[joint] = out.get(joint, 0.0) + abs(gear) * max(abs(force[0]), abs(force[1]))
    for name, (j, active) in _joint_elements(doc).items():
        rng = doc.floats(j, "actuatorfrcrange", f"MJCF joint {name!r}", active)
        if len(rng) == 2 and (rng[0] != 0.0 or rng[1] != 0.0):
            cap = max(abs(rng[0]), abs(rng[1]))
            out[name] = min(out.get(name, cap), cap)
    return {k: v for k, v in out.items() if v > 0.0}


def actuated_joints(doc: MjcfDocument) -> set[str]:
    """The joints an actuator drives (its ``joint`` attribute)."""
    return {
        a.get("joint", "")
        for act in doc.root.iter("actuator")
        for a in act
        if a.tag in ACTUATOR_TAGS and a.get("joint")
    }


# ------------------------------------------------------------------ couplings
@dataclass(frozen=True)
class Coupling:
    """A constraint of the MJCF between joint values.

    Attributes:
        kind: ``"tendon"`` (``lo <= sum coef_j q_j <= hi``) or ``"equality"``
            (``q_a = sum_k poly_k q_b^k``, ``joints = (a, b)`` or ``(a,)``).
        name: the element's name (or a description of it).
        joints: the joints it couples.
        coefs: tendon coefficients per joint, or the equality's polynomial.
        bounds: the tendon's range (``(-inf, inf)`` for an equality).
    """

    kind: str
    name: str
    joints: tuple[str, ...]
    coefs: tuple[float, ...]
    bounds: tuple[float, float] = (-math.inf, math.inf)

    def describe(self) -> str:
        """One line: the constraint as the MJCF states it."""
        if self.kind == "tendon":
            terms = " + ".join(
                f"{c:g} q[{j!r}]" for j, c in zip(self.joints, self.coefs, strict=True)
            )
            return (
                f"fixed tendon {self.name!r} ({self.bounds[0]:g} <= {terms} <= {self.bounds[1]:g})"
            )
        rhs = f"poly({self.joints[1]!r})" if len(self.joints) > 1 else f"{self.coefs[0]:g}"
        return f"joint equality {self.name!r} (q[{self.joints[0]!r}] = {rhs})"


def couplings(doc: MjcfDocument) -> list[Coupling]:
    """Limited fixed tendons and active joint equalities, in file order.

    Raises:
        ModelError: an active ``connect``/``weld`` equality or a limited
            spatial tendon (closed loops dexplan does not model).
    """
    out: list[Coupling] = []
    for tendons in doc.root.iter("tendon"):
        for t in tendons:
            name = t.get("name") or f"<{t.tag}> #{len(out)}"
            if not _limited(doc, t, "limited", "range"):
                continue
            if t.tag == "spatial":
                raise ModelError(
                    f"MJCF spatial tendon {name!r} is limited: dexplan models fixed tendons "
                    "over joints only"
                )
            if t.tag != "fixed":
                continue
            rng = doc.floats(t, "range", f"MJCF tendon {name!r}")
            joints = tuple(j.get("joint", "") for j in t.findall("joint"))
            what = f"MJCF tendon {name!r}"
            coefs = tuple((doc.floats(j, "coef", what) or [0.0])[0] for j in t.findall("joint"))
            if len(rng) == 2 and joints:
                out.append(Coupling("tendon", name, joints, coefs, (rng[0], rng[1])))
    for eq in doc.root.iter("equality"):
        for e in eq:
            name = e.get("name") or f"<{e.tag}>"
            if doc.attr(e, "active") == "false":
                continue
            if e.tag == "joint":
                joints = tuple(j for j in (e.get("joint1"), e.get("joint2")) if j)
                what = f"MJCF equality {name!r}"
                poly = tuple(doc.floats(e, "polycoef", what) or [0.0, 1.0, 0.0, 0.0, 0.0])
                out.append(Coupling("equality", name, joints, poly))
            elif e.tag in ("connect", "weld", "distance"):
                raise ModelError(
                    f"MJCF equality <{e.tag}> {name!r} closes a kinematic loop: dexplan plans "
                    'for tree-shaped hands (remove it, or set active="false")'
                )
    return out


# ------------------------------------------------------------ contact filters
@dataclass(frozen=True)
class ContactFilter:
    """MuJoCo's contact filtering, per collision geom.

    Attributes:
        geoms: per body name, ``(contype, conaffinity)`` of each of its geoms
            Pinocchio loads as collision geometry, in file order.
        excluded: body-name pairs of ``<contact><exclude>``.
        pairs: body-name pairs with an explicit ``<contact><pair>``.
        parent: per body name, its parent body's name.
    """

    geoms: Mapping[str, list[tuple[int, int]]]
    excluded: frozenset[frozenset[str]]
    pairs: frozenset[frozenset[str]]
    parent: Mapping[str, str]

    def bodies_collide(self, a: str, b: str) -> bool:
        """True when MuJoCo checks some geom of body ``a`` against one of body ``b``."""
        pair = frozenset((a, b))
        if pair in self.pairs:
            return True
        if pair in self.excluded or self.parent.get(a) == b or self.parent.get(b) == a:
            return False
        return any(
            (t1 & c2) or (t2 & c1)
            for t1, c1 in self.geoms.get(a, [])
            for t2, c2 in self.geoms.get(b, [])
        )


def contact_filter(doc: MjcfDocument) -> ContactFilter:
    """Read each body's collision geoms (contype or conaffinity non-zero) and the contact lists."""
    geoms: dict[str, list[tuple[int, int]]] = {}
    parent: dict[str, str] = {}
    geom_body: dict[str, str] = {}

    def walk(body: ET.Element, active: str | None) -> None:
        active = body.get("childclass") or active
        bname = body.get("name", "")
        for child in body:
            if child.tag == "geom":
                cls = child.get("class") or active
                t = int(float(doc.attr(child, "contype", cls) or 1))
                c = int(float(doc.attr(child, "conaffinity", cls) or 1))
                if t or c:
                    geoms.setdefault(bname, []).append((t, c))
                if child.get("name"):
                    geom_body[child.get("name", "")] = bname
            elif child.tag == "body":
                parent[child.get("name", "")] = bname
                walk(child, active)

    for world in doc.root.findall("worldbody"):
        for top in world.findall("body"):
            walk(top, None)
    excluded, pairs = set(), set()
    for contact in doc.root.iter("contact"):
        for e in contact.findall("exclude"):
            excluded.add(frozenset((e.get("body1", ""), e.get("body2", ""))))
        for p in contact.findall("pair"):
            b1, b2 = geom_body.get(p.get("geom1", "")), geom_body.get(p.get("geom2", ""))
            if b1 and b2:
                pairs.add(frozenset((b1, b2)))
    return ContactFilter(geoms, frozenset(excluded), frozenset(pairs), parent)
