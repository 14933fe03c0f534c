"""The builtin Allegro hands' physical model: effort limits and collision shapes.

The collision shapes are measured against the visual meshes the URDF ships
(example-robot-data's STL files). Those meshes are shells of parts, not solids:
the distal link's mesh is two side plates with nothing between them (the
fingertip's mesh fills the rest), the palm's is the finger motor blocks, the
thumb mount and the wrist. So a shape is measured against the convex hull of
its rigid body's meshes (its link's and those of the links fixed to it, as the
fingertip), in the link frame: every point of the shape lies within
:data:`FIT_TOL` of that hull.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import pytest
import trimesh

from dexplan.model.collision import CONTACT_PENETRATION_TOL
from dexplan.model.hand.builtin import (
    ALLEGRO_COLLISION_SHAPES,
    ALLEGRO_EFFORT_LIMITS,
    ALLEGRO_TIP_RADIUS,
    ALLEGRO_TIPS,
)
from dexplan.model.hand.hand import Hand

HANDS = ("allegro", "allegro_left")
#: Largest distance (m) of a collision shape's point from its body's meshes.
#: About a tenth of a phalanx's 27 mm width: the URDF's boxes kept for the
#: proximal and middle phalanges pass (they overshoot the narrower joint
#: tongues by up to 2.1 mm), the URDF's boxes replaced do not (distal 3.9 mm,
#: knuckles 3.2 and 4.0 mm, thumb base 9.9 mm, palm 25 mm).
FIT_TOL = 0.003
#: Spacing (m) of the points sampled on curved surfaces (spheres, capsules).
#: A distance is 1-Lipschitz, so a sampled maximum is within this of the true one.
SAMPLE_STEP = 0.0005


@pytest.fixture(scope="module", params=HANDS)
def hand(request: pytest.FixtureRequest) -> Hand:
    return Hand.builtin(request.param)


# ------------------------------------------------------------------ geometry
def _fibonacci_sphere(n: int) -> np.ndarray:
    """(n, 3) unit vectors spread evenly over the sphere."""
    i = np.arange(n) + 0.5
    polar = np.arccos(1.0 - 2.0 * i / n)
    azimuth = np.pi * (1.0 + 5.0**0.5) * i
    return np.c_[np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar), np.cos(polar)]


def _surface_points(shape: coal.CollisionGeometry) -> np.ndarray:
    """(n, 3) points of a shape's boundary, in its own frame, that reach its farthest points.

    A box's farthest point from a convex set is a corner (the distance is
    convex), so its corners suffice; curved surfaces are sampled every
    :data:`SAMPLE_STEP` or so.
    """
    if isinstance(shape, coal.Box):
        half = np.asarray(shape.halfSide)
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        return signs * half
    radius = float(shape.radius)
    n = int(4.0 * np.pi * radius**2 / SAMPLE_STEP**2) + 1
    ball = _fibonacci_sphere(max(n, 100)) * radius
    if isinstance(shape, coal.Sphere):
        return ball
    assert isinstance(shape, coal.Capsule), type(shape)
    half = float(shape.halfLength)
    angles = np.linspace(0.0, 2.0 * np.pi, int(2.0 * np.pi * radius / SAMPLE_STEP) + 1)
    heights = np.linspace(-half, half, int(2.0 * half / SAMPLE_STEP) + 2)
    a, h = np.meshgrid(angles, heights)
    side = np.c_[radius * np.cos(a.ravel()), radius * np.sin(a.ravel()), h.ravel()]
    top = ball[ball[:, 2] >= 0.0] + [0.0, 0.0, half]
    bottom = ball[ball[:, 2] <= 0.0] - [0.0, 0.0, half]
    return np.vstack([side, top, bottom])


def _origin(elem: ET.Element) -> pin.SE3:
    """The ``<origin>`` of a URDF element (identity when absent)."""
    o = elem.find("origin")
    xyz = [float(v) for v in (o.get("xyz", "0 0 0") if o is not None else "0 0 0").split()]
    rpy = [float(v) for v in (o.get("rpy", "0 0 0") if o is not None else "0 0 0").split()]
    return pin.SE3(pin.rpy.rpyToMatrix(*rpy), np.array(xyz))


def _visual_meshes(h: Hand) -> dict[str, list[trimesh.Trimesh]]:
    """Each link's visual meshes, placed in the link frame, from the hand's package dirs."""
    out: dict[str, list[trimesh.Trimesh]] = {}
    for link in ET.fromstring(h.urdf_xml).iter("link"):
        for visual in link.findall("visual"):
            mesh_elem = visual.find("geometry/mesh")
            assert mesh_elem is not None
            relative = mesh_elem.get("filename", "").removeprefix("package://")
            found = [Path(d) / relative for d in h.package_dirs if (Path(d) / relative).is_file()]
            assert found, f"mesh {relative!r} is in none of {h.package_dirs}"
            mesh = trimesh.load(found[0], force="mesh")
            mesh.apply_transform(_origin(visual).homogeneous)
            out.setdefault(link.get("name", ""), []).append(mesh)
    return out


def _body_hull(h: Hand, meshes: dict[str, list[trimesh.Trimesh]], frame: int) -> trimesh.Trimesh:
    """Convex hull of the visual meshes of every link on ``frame``'s joint, in ``frame``."""
    model = h.model
    link = model.frames[frame]
    parts = []
    for other in model.frames:
        if other.type == pin.FrameType.BODY and other.parentJoint == link.parentJoint:
            to_link = (link.placement.inverse() * other.placement).homogeneous
            for mesh in meshes.get(other.name, []):
                parts.append(mesh.copy().apply_transform(to_link))
    assert parts, f"link {link.name!r} has no visual mesh on its body"
    return trimesh.util.concatenate(parts).convex_hull


def _distance_to_hull(hull: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """Distance of each point from the convex solid ``hull`` (0 inside)."""
    offsets = points @ hull.face_normals.T - np.sum(hull.triangles[:, 0] * hull.face_normals, 1)
    _, distance, _ = trimesh.proximity.closest_point(hull, points)
    return np.where(offsets.max(axis=1) <= 0.0, 0.0, distance)


def _shape_in_link(h: Hand, go: pin.GeometryObject) -> tuple[np.ndarray, pin.SE3]:
    """A geometry's boundary points in its link's frame, and its placement there."""
    placement = h.model.frames[go.parentFrame].placement.inverse() * go.placement
    points = _surface_points(go.geometry) @ placement.rotation.T + placement.translation
    return points, placement


# ------------------------------------------------------------------- tests
def test_collision_shapes_follow_the_visual_meshes(hand: Hand) -> None:
    meshes = _visual_meshes(hand)
    misfits = {}
    hulls: dict[int, trimesh.Trimesh] = {}
    for go in hand.geom_model.geometryObjects:
        if go.parentFrame not in hulls:
            hulls[go.parentFrame] = _body_hull(hand, meshes, go.parentFrame)
        points, _ = _shape_in_link(hand, go)
        worst = float(_distance_to_hull(hulls[go.parentFrame], points).max())
        if worst > FIT_TOL:
            misfits[go.name] = round(worst * 1000.0, 2)
    assert not misfits, f"shapes farther than {FIT_TOL * 1000} mm from their meshes (mm): {misfits}"


def test_the_check_sees_a_shape_out_of_its_mesh(hand: Hand) -> None:
    """The URDF's distal box, reaching the fingertip centre, sticks out of the fingertip."""
    frame = hand.model.getFrameId("link_3.0")
    hull = _body_hull(hand, _visual_meshes(hand), frame)
    urdf_box = coal.Box(0.0196, 0.0275, 0.0267)
    centre = np.array([0.0, 0.0, 0.01335])  # in link_3.0: from the joint to the fingertip centre
    distance = _distance_to_hull(hull, _surface_points(urdf_box) + centre)
    assert distance.max() == pytest.approx(0.0039, abs=0.0002)


def test_replaced_links_carry_exactly_the_fitted_shapes(hand: Hand) -> None:
    links = {link.get("name"): link for link in ET.fromstring(hand.urdf_xml).iter("link")}
    for name, shapes in ALLEGRO_COLLISION_SHAPES.items():
        kinds = [shape.tag for shape in links[name].iterfind("collision/geometry/*")]
        assert kinds == [s.kind for s in shapes], name


def test_effort_limits_are_the_drivers_caps(hand: Hand) -> None:
    model = hand.model
    limits = {
        model.names[j]: float(model.effortLimit[model.joints[j].idx_v])
        for j in range(1, model.njoints)
    }
    assert limits == pytest.approx(ALLEGRO_EFFORT_LIMITS, rel=1e-12)
    assert set(limits) == set(ALLEGRO_EFFORT_LIMITS)
    # index, middle and ring share the caps; the thumb's differ
    for first in (0, 4, 8):
        caps = [ALLEGRO_EFFORT_LIMITS[f"joint_{first + k}.0"] for k in range(4)]
        assert caps == pytest.approx([0.3125, 0.5625, 0.375, 0.2375])
    thumb = [ALLEGRO_EFFORT_LIMITS[f"joint_{12 + k}.0"] for k in range(4)]
    assert thumb == pytest.approx([0.4375, 0.3375, 0.225, 0.225])


def _distal_shapes(h: Hand) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """Per finger: its distal link's name, shape points and fingertip centre, in the link frame.

    The distal link carries the fingertip frame; its shapes are every geometry
    on the fingertip's joint but the fingertip sphere.
    """
    out = []
    model = h.model
    for tip in ALLEGRO_TIPS:
        tip_frame = model.frames[model.getFrameId(tip)]
        link_id = model.getFrameId(tip.removesuffix("_tip"))
        centre = (model.frames[link_id].placement.inverse() * tip_frame.placement).translation
        shapes = [
            go
            for go in h.geom_model.geometryObjects
            if go.parentJoint == tip_frame.parentJoint and go.parentFrame == link_id
        ]
        assert shapes, tip
        points = np.vstack([_shape_in_link(h, go)[0] for go in shapes])
        out.append((model.frames[link_id].name, points, centre))
    return out


def test_distal_shapes_are_no_wider_than_the_fingertip(hand: Hand) -> None:
    for link, points, centre in _distal_shapes(hand):
        # the link's z axis runs through the fingertip centre, along the finger
        assert np.allclose(centre[:2], 0.0, atol=1e-9), link
        radial = np.linalg.norm(points[:, :2], axis=1)
        assert radial.max() <= ALLEGRO_TIP_RADIUS + 1e-9, (link, radial.max())


def test_a_touching_fingertip_keeps_its_distal_link_off_the_object(hand: Hand) -> None:
    """Towards any contact normal on the fingertip's front half (up to 90 degrees from
    the finger's axis), the distal shapes stay behind the fingertip sphere by more
    than the penetration a contact may have, so a contact never makes the distal
    link collide with a convex object."""
    front = _fibonacci_sphere(4000)
    front = front[front[:, 2] >= 0.0]
    for link, points, centre in _distal_shapes(hand):
        reach = ((points - centre) @ front.T).max(axis=0)
        assert reach.max() < ALLEGRO_TIP_RADIUS - CONTACT_PENETRATION_TOL, (link, reach.max())
