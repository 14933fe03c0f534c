"""The replay's concave objects: convex parts close to the mesh, the mesh's own mass and inertia."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from dexplan.model.hand.hand import Hand
from dexplan.model.objects import Mesh

mujoco = pytest.importorskip("mujoco")
pytest.importorskip("coacd")

from dexplan.execution.replay.convex_parts import convex_parts, mass_properties  # noqa: E402
from dexplan.execution.replay.mjcf import build_mjcf  # noqa: E402

#: The union of the parts stays this close to the mesh surface (m), both ways:
#: no point of a part's surface is farther outside the mesh, and no point of the
#: mesh's surface is farther from the parts.
SURFACE_TOL = 1e-3


def _l_prism(a: float = 0.04, h: float = 0.02) -> tuple[np.ndarray, np.ndarray]:
    """A closed L-shaped prism (a x a footprint, one a/2 x a/2 quarter cut away), h high."""
    poly = np.array([(0, 0), (2, 0), (2, 1), (1, 1), (1, 2), (0, 2)], dtype=float) * a / 2
    n = len(poly)
    v = np.vstack([np.c_[poly, np.zeros(n)], np.c_[poly, np.full(n, h)]])
    fan = [(3, 4, 5), (3, 5, 0), (3, 0, 1), (3, 1, 2)]  # from the reflex corner
    f = [t[::-1] for t in fan] + [tuple(i + n for i in t) for t in fan]
    for i in range(n):
        j = (i + 1) % n
        f += [(i, j, j + n), (i, j + n, i + n)]
    return v, np.array(f)


@pytest.fixture(scope="module")
def l_prism() -> tuple[np.ndarray, np.ndarray]:
    v, f = _l_prism()
    assert not trimesh.Trimesh(v, f).is_convex
    return v, f


@pytest.fixture(scope="module")
def parts(l_prism):
    return convex_parts(*l_prism)


def test_concave_mesh_gives_several_convex_parts_close_to_its_surface(l_prism, parts) -> None:
    """Each part is convex; the parts' union is within SURFACE_TOL of the mesh, both ways."""
    mesh = Mesh(*l_prism)
    assert len(parts) >= 2
    hulls = [trimesh.Trimesh(p.vertices, p.faces) for p in parts]
    assert all(h.is_convex and h.is_watertight for h in hulls)
    on_parts = np.vstack([h.sample(2000, seed=1) for h in hulls])
    outside = np.asarray(mesh.signed_distance(on_parts))
    assert outside.max() <= SURFACE_TOL
    on_mesh, _ = mesh.sample_surface(2000, np.random.default_rng(2))
    # trimesh: positive inside a hull; the distance to the union is the least over the parts
    to_union = np.min([-trimesh.proximity.signed_distance(h, on_mesh) for h in hulls], axis=0)
    assert to_union.max() <= SURFACE_TOL
    # the hull of the whole would not do: this point on it lies 10 mm outside the L
    hull_corner = np.array([0.03, 0.03, 0.01])
    assert float(mesh.signed_distance(hull_corner[None])[0]) > 5 * SURFACE_TOL


def test_same_mesh_same_parts(l_prism, parts) -> None:
    again = convex_parts(*l_prism)
    assert len(again) == len(parts)
    for a, b in zip(parts, again, strict=True):
        assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)


def test_convex_mesh_is_its_own_part() -> None:
    box = trimesh.creation.box(extents=(0.03, 0.02, 0.01))
    (part,) = convex_parts(np.asarray(box.vertices), np.asarray(box.faces))
    assert np.allclose(sorted(map(tuple, part.vertices)), sorted(map(tuple, box.vertices)))


def test_mass_properties_of_the_l(l_prism) -> None:
    """Two boxes' analytic mass, centre of mass and inertia (parallel axis theorem)."""
    mp = mass_properties(*l_prism, mass=0.3)
    a, h = 0.04, 0.02
    # the L = a 2x1 (in a/2 units) slab at y in [0, a/2] plus a 1x1 block at x in [0, a/2]
    boxes = [((a, a / 2, h), (a / 2, a / 4, h / 2)), ((a / 2, a / 2, h), (a / 4, 3 * a / 4, h / 2))]
    vols = np.array([np.prod(s) for s, _ in boxes])
    masses = 0.3 * vols / vols.sum()
    com = sum(m * np.array(c) for m, (_, c) in zip(masses, boxes, strict=True)) / 0.3
    inertia = np.zeros((3, 3))
    for m, (s, c) in zip(masses, boxes, strict=True):
        box_i = (
            m / 12 * np.diag([s[1] ** 2 + s[2] ** 2, s[0] ** 2 + s[2] ** 2, s[0] ** 2 + s[1] ** 2])
        )
        r = np.array(c) - com
        inertia += box_i + m * (r @ r * np.eye(3) - np.outer(r, r))
    assert mp.mass == pytest.approx(0.3)
    assert np.allclose(mp.center_of_mass, com, atol=1e-9)
    assert np.allclose(mp.inertia, inertia, rtol=1e-6, atol=1e-12)


def test_replay_model_of_a_concave_object(tmp_path: Path, l_prism, parts) -> None:
    """One MuJoCo geom per part on the object's body, whose mass and inertia are the mesh's."""
    trimesh.Trimesh(*l_prism).export(tmp_path / "l.obj")
    doc = {
        "mu": 0.8,
        "object": {"shape": "mesh", "path": "l.obj"},
        "start": {"object_pose_xyzquat": [0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0]},
        "obstacles": [],
    }
    xml, _ = build_mjcf(
        doc, Hand.builtin("paper"), mass=0.3, gravity=np.zeros(3), base_dir=tmp_path
    )
    m = mujoco.MjModel.from_xml_string(xml)
    body = m.body("object").id
    geoms = np.flatnonzero(m.geom_bodyid == body)
    assert len(geoms) == len(parts)
    mp = mass_properties(*l_prism, mass=0.3)
    assert m.body_mass[body] == pytest.approx(0.3)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    R = d.ximat[body].reshape(3, 3)  # the body's principal axes in the world (= object) frame
    assert np.allclose(d.xipos[body] - [0.0, 0.0, 0.1], mp.center_of_mass, atol=1e-9)
    assert np.allclose(R @ np.diag(m.body_inertia[body]) @ R.T, mp.inertia, rtol=1e-6, atol=1e-12)
    # the parts sit where the mesh is (MuJoCo recentres each part on its own
    # inertial frame and moves its geom to match): their bounds are the L's
    world = []
    for g in geoms:
        mid = m.geom_dataid[g]
        v0, nv = m.mesh_vertadr[mid], m.mesh_vertnum[mid]
        local = m.mesh_vert[v0 : v0 + nv]
        world.append(local @ d.geom_xmat[g].reshape(3, 3).T + d.geom_xpos[g])
    lo = np.vstack(world).min(axis=0) - [0.0, 0.0, 0.1]
    hi = np.vstack(world).max(axis=0) - [0.0, 0.0, 0.1]
    assert np.allclose(lo, l_prism[0].min(axis=0), atol=SURFACE_TOL)
    assert np.allclose(hi, l_prism[0].max(axis=0), atol=SURFACE_TOL)
