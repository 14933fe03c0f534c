"""Contact models: friction cones, soft-finger sets, their linearizations and wrenches.

Everything is in the **object frame**: contact points ``p_c`` (metres) and *inward*
unit normals ``n_c``, one row per contact. The derivations and bounds are in the
package docstring (:mod:`dexplan.model.grasp`) and docs/force_closure.md.

Contact models
--------------
``point`` (the paper): the force ``f_c`` lies in the Coulomb cone
``|f_t| <= mu f_n``, linearized by the pyramid of ``E`` unit edges ``u_ce``.

``soft`` (soft finger): the contact also transmits a torsional moment
``tau_c n_c`` about its normal. Its coordinates are ``x_c = (f_c, sigma_c)`` with
``sigma_c = tau_c / L`` (scaled like every torque of the wrench space), and the
elliptic soft-finger set is ``|f_t|^2 / mu^2 + tau^2 / torsion^2 <= f_n^2``, i.e.
with ``t = torsion / L``: ``|f_t|^2 / mu^2 + sigma^2 / t^2 <= f_n^2``. Its
linearization is the cone of the point edges ``(u_ce, 0)`` and the two torsional
generators ``(n_c, +t)``, ``(n_c, -t)``: on the plane ``f_n = 1`` a bipyramid over
the pyramid's ``E``-gon, every vertex on the ellipsoid, so the linear set is
inside the elliptic one. Its wrenches are ``[u_ce, (p_c x u_ce) / L]`` and
``[n_c, (p_c x n_c + s torsion n_c) / L]`` for ``s = +1, -1``.

H-representation of the bipyramid: facet ``(e, s)`` passes through polygon edge
``e`` (outward tangent ``m_e`` at angle ``2 pi (e + 1/2) / E``, apothem
``beta = mu cos(pi / E)``) and the apex ``s``; on ``f_n = 1`` it is
``m_e . f_t / beta + s sigma / t <= 1``, so the cone facet normal is
``(m_e - beta n_c, s beta / t)`` (unit-normalized).
"""

from __future__ import annotations

import math
from enum import StrEnum

import numpy as np
from scipy.spatial import ConvexHull

from dexplan.core.errors import InvalidInputError
from dexplan.core.typing import FloatArray, as_points, as_positive

__all__ = [
    "CONTACT_MODELS",
    "MAX_FRICTION_EDGES",
    "MAX_TORSION",
    "MIN_FRICTION_EDGES",
    "ContactModel",
    "check_contact_model",
    "check_grasp",
    "contact_wrenches",
    "ellipsoid_facets",
    "friction_cone_edges",
    "friction_cone_facets",
    "min_contacts",
    "pyramid_facets",
    "soft_finger_facets",
    "soft_pyramid_facets",
    "tangent_basis",
]

#: Allowed number of edges of a linearized friction cone (``friction_edges`` in
#: scenarios and plan files): fewer than 3 spans no cone, more than 64 only
#: costs time (the round cone is approximated within 0.12%).
MIN_FRICTION_EDGES = 3
MAX_FRICTION_EDGES = 64


class ContactModel(StrEnum):
    """What a contact transmits; a member equals its string (scenario and plan files).

    ``POINT``: a force in the Coulomb cone (the paper). ``SOFT``: also a
    torsional moment about the normal (soft finger).
    """

    POINT = "point"
    SOFT = "soft"


#: Values of ``contact_model``.
CONTACT_MODELS: tuple[ContactModel, ...] = tuple(ContactModel)
#: Largest soft-finger ``torsion`` (metres): ``|tau_n| <= torsion f_n``. The
#: torsion coefficient is about the radius of the contact patch; 5 cm is
#: already a palm-sized patch for a fingertip.
MAX_TORSION = 0.05


# ---------------------------------------------------------------------------
# Validation
# ---------------------------------------------------------------------------


def _check_mu(mu: object) -> float:
    return as_positive(mu, "mu", allow_zero=True)


def _check_edges(edges: object) -> int:
    if isinstance(edges, bool) or not isinstance(edges, int | np.integer):
        raise InvalidInputError(f"edges must be an integer >= 3, got {edges!r}")
    if edges < 3:
        raise InvalidInputError(f"edges must be an integer >= 3, got {edges!r}")
    return int(edges)


def _check_normals(normals: object, name: str = "normals") -> FloatArray:
    arr = as_points(normals, name)
    n2 = np.einsum("ij,ij->i", arr, arr)
    if n2.size and not n2.min() >= 1e-24:
        row = int(np.argmin(n2))
        raise InvalidInputError(
            f"{name} must have non-zero length, got row {row} = {arr[row].tolist()}"
        )
    return arr / np.sqrt(n2)[:, None]


def check_grasp(
    points: object, normals: object, mu: object, edges: object, torque_scale: object
) -> tuple[FloatArray, FloatArray, float, int, float]:
    """A grasp's arrays and settings, checked.

    Args:
        points: (k, 3) contact points, object frame, metres; k >= 1.
        normals: (k, 3) inward contact normals, object frame (normalized here).
        mu: friction coefficient, >= 0.
        edges: pyramid edges per contact, >= 3.
        torque_scale: length dividing torques (m), or None for the largest
            ``|points|`` (1 if every point is at the origin).

    Returns:
        ``(points, unit normals, mu, edges, torque scale)``.

    Raises:
        InvalidInputError: bad shapes, non-finite values, zero-length normal,
            ``mu < 0``, ``edges < 3`` or ``torque_scale <= 0``.
    """
    pts = as_points(points, "points")
    if pts.shape[0] == 0:
        raise InvalidInputError("points must hold at least one contact, got shape (0, 3)")
    nrm = _check_normals(normals, "normals")
    if pts.shape != nrm.shape:
        raise InvalidInputError(
            f"points and normals must have the same shape, got {pts.shape} and {nrm.shape}"
        )
    mu_f = _check_mu(mu)
    e = _check_edges(edges)
    if torque_scale is None:
        scale = math.sqrt(float(np.einsum("ij,ij->i", pts, pts).max()))
        scale = scale if scale > 0.0 else 1.0
    else:
        scale = as_positive(torque_scale, "torque_scale")
    return pts, nrm, mu_f, e, scale


# ---------------------------------------------------------------------------
# Cones and wrenches
# ---------------------------------------------------------------------------


def tangent_basis(normals: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Orthonormal tangent vectors built from each unit normal alone.

    Duff et al. (2017) branchless basis: ``(t1, t2, n)`` is right-handed and depends
    only on ``n`` (never on a world axis), so the same object-frame normal always gets
    the same pyramid.

    Args:
        normals: (k, 3) unit normals, any frame.

    Returns:
        ``(t1, t2)``, each (k, 3), in the frame of ``normals``.
    """
    t = _tangents(np.asarray(normals, dtype=np.float64))
    return t[:, 0], t[:, 1]


def _tangents(n: FloatArray) -> FloatArray:
    """(k, 2, 3) rows ``t1, t2`` of :func:`tangent_basis` for unit normals (k, 3)."""
    x, y, z = n[:, 0], n[:, 1], n[:, 2]
    s = np.where(z >= 0.0, 1.0, -1.0)
    a = -1.0 / (s + z)
    b = x * y * a
    t = np.empty((n.shape[0], 2, 3))
    t[:, 0, 0] = 1.0 + s * x * x * a
    t[:, 0, 1] = s * b
    t[:, 0, 2] = -s * x
    t[:, 1, 0] = b
    t[:, 1, 1] = s + y * y * a
    t[:, 1, 2] = -y
    return t


_CIRCLES: dict[tuple[int, float], FloatArray] = {}


def _circle(edges: int, offset: float) -> FloatArray:
    """(edges, 2) rows ``(cos, sin)`` of the angles ``2 pi (e + offset) / edges``."""
    key = (edges, offset)
    out = _CIRCLES.get(key)
    if out is None:
        ang = 2.0 * np.pi * (np.arange(edges) + offset) / edges
        out = _CIRCLES[key] = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    return out


def friction_cone_edges(normals_in: object, mu: float, edges: int = 8) -> FloatArray:
    """Unit edge directions of the linearized friction cones.

    Edge ``e`` of contact ``c`` is ``cos(a) n_c + sin(a) (cos(t_e) t1_c + sin(t_e) t2_c)``
    with ``tan(a) = mu``, ``t_e = 2 pi e / edges`` and ``(t1_c, t2_c)`` from
    :func:`tangent_basis` (a function of ``n_c`` only). With ``mu = 0`` every edge is
    the normal.

    Args:
        normals_in: (k, 3) inward contact normals (into the object), object frame; they
            are normalized.
        mu: Coulomb friction coefficient, >= 0.
        edges: number of pyramid edges, >= 3.

    Returns:
        (k, edges, 3) unit edge directions, object frame.

    Raises:
        InvalidInputError: bad shape, non-finite or zero-length normal, ``mu < 0``,
            ``edges < 3``.
    """
    n = _check_normals(normals_in, "normals_in")
    mu_f = _check_mu(mu)
    e = _check_edges(edges)
    return _edges(n, mu_f, e)


def _edges(n: FloatArray, mu: float, edges: int) -> FloatArray:
    ca = 1.0 / math.sqrt(1.0 + mu * mu)
    radial = _circle(edges, 0.0) @ _tangents(n)  # (k, edges, 3)
    return ca * n[:, None, :] + (mu * ca) * radial


def friction_cone_facets(normals_in: object, mu: float, edges: int = 8) -> FloatArray:
    """Outward unit normals of the pyramid facets (H-representation of the cones).

    Facet ``e`` joins edges ``e`` and ``e + 1``; a force ``f`` is in the pyramid of
    contact ``c`` iff ``a_ce . f <= 0`` for every ``e``. For ``mu > 0`` this is
    ``a_ce = (m_ce - beta n_c) / sqrt(1 + beta^2)`` with ``m_ce`` the unit tangent at
    angle ``t_e + pi / edges`` and ``beta = mu cos(pi / edges)``. (With ``mu = 0`` these
    rows only force the tangential part to zero; the quality code then uses the
    normal force itself as the variable.)

    Args:
        normals_in: (k, 3) inward contact normals, object frame.
        mu: friction coefficient, >= 0.
        edges: number of pyramid edges, >= 3.

    Returns:
        (k, edges, 3) outward facet normals, object frame.
    """
    n = _check_normals(normals_in, "normals_in")
    mu_f = _check_mu(mu)
    e = _check_edges(edges)
    return pyramid_facets(n, mu_f, e)


def pyramid_facets(n: FloatArray, mu: float, edges: int) -> FloatArray:
    """:func:`friction_cone_facets` of unit normals ``n: (k, 3)`` without input checks."""
    beta = mu * math.cos(math.pi / edges)
    inv = 1.0 / math.sqrt(1.0 + beta * beta)
    radial = _circle(edges, 0.5) @ _tangents(n)  # (k, edges, 3)
    return inv * radial - (beta * inv) * n[:, None, :]


def contact_wrenches(
    points: object,
    normals_in: object,
    mu: float,
    edges: int = 8,
    torque_scale: float | None = None,
    *,
    contact_model: ContactModel | str = ContactModel.POINT,
    torsion: float = 0.0,
) -> FloatArray:
    """Wrenches of the generators of the linearized contact sets, torques / ``L``.

    Point contacts: row ``c * edges + e`` is ``[u_ce, (p_c x u_ce) / L]``. Soft
    contacts: ``edges + 2`` rows per contact, the point rows then
    ``[n_c, (p_c x n_c + s torsion n_c) / L]`` for ``s = +1, -1`` (module docstring).

    Args:
        points: (k, 3) contact points, object frame, metres.
        normals_in: (k, 3) inward contact normals, object frame.
        mu: friction coefficient, >= 0.
        edges: pyramid edges per contact, >= 3.
        torque_scale: length ``L`` dividing the torques (metres); callers pass the
            object's characteristic length. Default: the largest distance of the
            points from the object-frame origin, or 1 if all points are at the origin.
        contact_model: ``"point"`` or ``"soft"``.
        torsion: soft-finger torsion coefficient (m), in (0, ``MAX_TORSION``];
            0 for point contacts.

    Returns:
        (k * edges, 6) wrenches ``[force, torque / L]`` in the object frame, or
        (k * (edges + 2), 6) for soft contacts.

    Raises:
        InvalidInputError: bad shapes, non-finite values, zero-length normal,
            ``mu < 0``, ``edges < 3``, ``torque_scale <= 0`` or a bad contact model.
    """
    pts, nrm, mu_f, e, scale = check_grasp(points, normals_in, mu, edges, torque_scale)
    torsion_f = check_contact_model(contact_model, torsion)
    u = _edges(nrm, mu_f, e)
    if torsion_f is not None:
        twist = (torsion_f * nrm)[:, None, :] * np.array([1.0, -1.0])[None, :, None]
        u = np.concatenate([u, np.repeat(nrm[:, None, :], 2, axis=1)], axis=1)
    torque = np.cross(pts[:, None, :], u)
    if torsion_f is not None:
        torque[:, e:] += twist
    return np.concatenate([u, torque / scale], axis=2).reshape(-1, 6)


# ---------------------------------------------------------------------------
# Contact models
# ---------------------------------------------------------------------------


def check_contact_model(contact_model: object, torsion: object) -> float | None:
    """Validate a contact model: None for ``point``, the torsion (m) for ``soft``.

    Args:
        contact_model: ``"point"`` or ``"soft"``.
        torsion: soft-finger torsion coefficient in metres (``|tau_n| <= torsion
            f_n``): in ``(0, MAX_TORSION]`` for ``soft``, 0 for ``point``.

    Raises:
        InvalidInputError: an unknown model, or a torsion outside its range.
    """
    if contact_model == "point":
        if torsion == 0.0 and not isinstance(torsion, bool):
            return None
        raise InvalidInputError(
            f"torsion applies to soft contacts only: contact_model 'point' needs torsion 0, "
            f"got {torsion!r}"
        )
    if contact_model != "soft":
        raise InvalidInputError(
            f"contact_model must be one of {', '.join(CONTACT_MODELS)}, got {contact_model!r}"
        )
    t = as_positive(torsion, "torsion")
    if t > MAX_TORSION:
        raise InvalidInputError(
            f"torsion must be in (0, {MAX_TORSION:g}] m for soft contacts, got {torsion!r}"
        )
    return t


def min_contacts(mu: float, contact_model: ContactModel | str = ContactModel.POINT) -> int:
    """Fewest contacts that can be force closure (the screens return 0 below it).

    Force closure needs the contact cones to span the 6-D wrench space positively,
    hence at least 7 generators and ``rank G = 6``:

    - point with friction: 3 (two contacts leave the torque about the line through
      them free: every contact force meets that line);
    - point, frictionless: 7 (one generator per contact);
    - soft with friction: 2 (the torsional moments about two opposed normals supply
      that torque);
    - soft, frictionless: 4 (two generators per contact, ``(n, +t)`` and ``(n, -t)``).
    """
    if contact_model == "soft":
        return 2 if mu > 0.0 else 4
    return 3 if mu > 0.0 else 7


def soft_finger_facets(
    normals_in: object, mu: float, torsion: float, edges: int = 8, torque_scale: float = 1.0
) -> FloatArray:
    """Outward unit facet normals of the linearized soft-finger cones.

    A contact vector ``x = (f, sigma)`` (force, torsional moment ``tau_n / L``) is in
    the bipyramid cone of contact ``c`` iff ``a . x <= 0`` for every row ``a``
    (module docstring); with ``mu = 0`` the cone is ``|sigma| <= t f_n`` and the
    rows act on ``(f_n, sigma)``.

    Args:
        normals_in: (k, 3) inward contact normals, object frame.
        mu: friction coefficient, >= 0.
        torsion: torsion coefficient (m), > 0.
        edges: pyramid edges, >= 3.
        torque_scale: the torque scale ``L`` (m) dividing ``tau_n``.

    Returns:
        (k, 2 edges, 4) rows ``(force part, sigma part)`` in the object frame for
        ``mu > 0``; (k, 2, 2) rows on ``(f_n, sigma)`` for ``mu = 0``.
    """
    n = _check_normals(normals_in, "normals_in")
    mu_f = _check_mu(mu)
    e = _check_edges(edges)
    t = as_positive(torsion, "torsion") / as_positive(torque_scale, "torque_scale")
    return soft_pyramid_facets(n, mu_f, e, t)


def soft_pyramid_facets(n: FloatArray, mu: float, edges: int, t: float) -> FloatArray:
    """:func:`soft_finger_facets` of unit normals ``n: (k, 3)``, ``t = torsion / L``, unchecked."""
    k = n.shape[0]
    if mu == 0.0:
        inv = 1.0 / math.sqrt(1.0 + t * t)
        rows = np.empty((k, 2, 2))
        rows[:, :, 0] = -t * inv
        rows[:, 0, 1] = inv
        rows[:, 1, 1] = -inv
        return rows
    beta = mu * math.cos(math.pi / edges)
    radial = _circle(edges, 0.5) @ _tangents(n)  # (k, edges, 3): m_e
    sig = beta / t
    inv = 1.0 / math.sqrt(1.0 + beta * beta + sig * sig)
    rows = np.empty((k, 2 * edges, 4))
    force = inv * (radial - beta * n[:, None, :])
    rows[:, :edges, :3] = force
    rows[:, edges:, :3] = force
    rows[:, :edges, 3] = sig * inv
    rows[:, edges:, 3] = -sig * inv
    return rows


def ellipsoid_facets(n: FloatArray, mu: float, t: float, outer: bool) -> FloatArray:
    """Unit facet rows (k, F, 4) of a dense polytope of the elliptic soft-finger set.

    The polytope is the image under ``v -> (mu v_1, mu v_2, t v_3)`` (tangent
    coordinates in the basis of :func:`tangent_basis`, ``f_n = 1``) of the hull of
    a latitude-longitude grid of unit vectors: inscribed in the elliptic set, or,
    with ``outer``, scaled by ``1 / inradius`` so that it contains it. Needs
    ``mu > 0`` (frictionless soft sets are exactly linear).
    """
    facets, inradius = _sphere_polytope()
    a, b = facets[:, :3], facets[:, 3]
    if outer:
        b = b / inradius
    radial = (a[:, :2] / mu) @ _tangents(n)  # (k, F, 3)
    rows = np.empty((n.shape[0], a.shape[0], 4))
    rows[:, :, :3] = radial - b[None, :, None] * n[:, None, :]
    rows[:, :, 3] = a[:, 2] / t
    rows /= np.linalg.norm(rows, axis=2, keepdims=True)
    return rows


#: Resolution of the dense elliptic polytope (azimuths, latitude bands).
ELLIPSOID_GRID = (48, 12)
_SPHERE: list[tuple[FloatArray, float]] = []


def _sphere_polytope() -> tuple[FloatArray, float]:
    """Facets ``a . v <= b`` (F, 4) of a grid polytope in the unit sphere (cached).

    Returns ``(facets, inradius)``: rows ``(a, b)`` with ``|a| = 1``, and ``min b``.
    """
    if not _SPHERE:
        n_az, n_lat = ELLIPSOID_GRID
        lat = np.pi * (np.arange(1, n_lat) / n_lat - 0.5)
        az = 2.0 * np.pi * np.arange(n_az) / n_az
        ring = np.stack(
            [
                np.outer(np.cos(lat), np.cos(az)).ravel(),
                np.outer(np.cos(lat), np.sin(az)).ravel(),
                np.repeat(np.sin(lat), n_az),
            ],
            axis=1,
        )
        verts = np.vstack([ring, [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]])
        eq = ConvexHull(verts).equations  # a . v + c <= 0 inside, |a| = 1
        facets = np.concatenate([eq[:, :3], -eq[:, 3:]], axis=1)
        _SPHERE.append((facets, float(facets[:, 3].min())))
    return _SPHERE[0]
