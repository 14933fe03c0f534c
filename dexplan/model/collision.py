"""Collision world: hand links, the grasped object and static obstacles, with coal.

The world is one Pinocchio ``GeometryModel`` (coal geometries) holding the
hand's collision geometry, the object (attached to the universe, its placement
set per query) and the obstacles. Collision pairs are fixed at construction:

- hand-hand pairs, except links on the same or on adjacent joints and the
  pairs named in ``Hand.collision_exclude``;
- every hand geometry against the object and against every obstacle;
- the object against every obstacle.

Per query, the fingertip-object pair of each *contact* finger is switched off:
that contact is the GSn constraint, not a collision. The fingertip is the
sphere at the tip frame only; the rest of the distal link is always checked.
The contact's penetration is still measured (signed distance of the tip centre
to the object surface minus the tip radius) and reported as a collision beyond
:data:`CONTACT_PENETRATION_TOL`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from dexplan.core.errors import InvalidInputError
from dexplan.core.typing import FloatArray, as_vector
from dexplan.model.hand.hand import Hand
from dexplan.model.objects import Shape

#: Penetration of a contact fingertip into the object tolerated (m).
CONTACT_PENETRATION_TOL = 1e-3


@dataclass(frozen=True)
class Obstacle:
    """A static obstacle.

    Attributes:
        shape: geometry in its own frame.
        pose_xyzquat: (7,) pose in the world frame, quaternion XYZW.
        name: label used in reports.
    """

    shape: Shape
    pose_xyzquat: tuple[float, ...]
    name: str = "obstacle"


@dataclass(frozen=True)
class CollisionReport:
    """Result of :meth:`CollisionWorld.check`.

    Attributes:
        free: no collision and no contact penetration beyond tolerance.
        pair: names of the first colliding pair found, or None.
        max_penetration: largest penetration of a contact fingertip (m, >= 0).
    """

    free: bool
    pair: tuple[str, str] | None
    max_penetration: float


def pose_to_se3(pose_xyzquat: FloatArray) -> pin.SE3:
    """SE3 of ``pose_xyzquat: (7,)`` (position, quaternion XYZW, normalised here)."""
    x, y, z, qx, qy, qz, qw = np.asarray(pose_xyzquat, dtype=float)[:7].tolist()
    n = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    if n == 0.0:
        raise InvalidInputError("pose_xyzquat quaternion must be non-zero, got [0, 0, 0, 0]")
    return pin.XYZQUATToSE3(np.array([x, y, z, qx / n, qy / n, qz / n, qw / n]))


class CollisionWorld:
    """Hand, object and obstacles with fixed collision pairs.

    Args:
        hand: the hand; its collision geometry is copied.
        obj: the object shape (object frame).
        obstacles: static obstacles in the world frame.
    """

    def __init__(self, hand: Hand, obj: Shape, obstacles: Sequence[Obstacle] = ()) -> None:
        self.hand = hand
        self.obj = obj
        self.obstacles = tuple(obstacles)
        gm = self._geometry_model()
        self.geom_model = gm
        self._link_of = [hand.model.frames[go.parentFrame].name for go in gm.geometryObjects]
        self._find_finger_geoms()
        self._add_collision_pairs()
        self._finger_of_geom: dict[int, int] = {
            g: i for i, geoms in enumerate(self.finger_geoms) for g in geoms
        }
        self._finger_of_name = {self.geometry_name(g): i for g, i in self._finger_of_geom.items()}
        self.geom_data = pin.GeometryData(gm)
        self._tip_mask: tuple[bool, ...] | None = None  # unknown: set on first check
        # contacts on (EPA): without them coal 3.0.3 can miss box-box
        # penetrations of millimetres once the same pair has been queried at
        # other placements, so a colliding configuration would pass
        for req in self.geom_data.collisionRequests:
            req.enable_contact = True
        # places the obstacles once (they never move)
        pin.updateGeometryPlacements(hand.model, hand.data, gm, self.geom_data, hand.neutral)

    def _geometry_model(self) -> pin.GeometryModel:
        """The hand's geometries (copied), then the object, then the obstacles.

        Sets ``_n_hand_geoms``, ``object_geom`` and ``obstacle_geoms``.
        """
        gm = pin.GeometryModel()
        for go in self.hand.geom_model.geometryObjects:
            gm.addGeometryObject(go.copy())
        self._n_hand_geoms = gm.ngeoms
        ident = pin.SE3.Identity()
        self.object_geom = gm.addGeometryObject(
            pin.GeometryObject("object", 0, 0, ident, self.obj.to_coal())
        )
        self.obstacle_geoms = [
            gm.addGeometryObject(
                pin.GeometryObject(
                    f"{ob.name}_{k}",
                    0,
                    0,
                    pose_to_se3(as_vector(ob.pose_xyzquat, f"obstacles[{k}].pose_xyzquat", 7)),
                    ob.shape.to_coal(),
                )
            )
            for k, ob in enumerate(self.obstacles)
        ]
        return gm

    def _find_finger_geoms(self) -> None:
        """Each finger's geometries (``finger_geoms``) and its fingertip sphere (``tip_geoms``).

        The fingertip is the sphere at the tip frame (:attr:`Hand.tip_geom_ids`,
        the same index here: the hand's geometries are copied first, in order).
        Only that sphere's pair with the object is switched off for a contact
        finger; the rest of the distal link stays checked against the object.
        """
        hand, gm, model = self.hand, self.geom_model, self.hand.model
        self.tip_geoms: list[int] = list(hand.tip_geom_ids)
        self.finger_geoms: list[list[int]] = []
        for fid in hand.tip_frame_ids:
            joints = {model.frames[fid].parentJoint} | _ancestors(
                model, model.frames[fid].parentJoint
            )
            self.finger_geoms.append(
                [
                    g
                    for g in range(self._n_hand_geoms)
                    if gm.geometryObjects[g].parentJoint in joints - {0}
                ]
            )

    def _add_collision_pairs(self) -> None:
        """Every pair that :meth:`_skip_pair` keeps, in (a, b) order; ``_pair_of`` indexes them."""
        gm = self.geom_model
        excluded = {frozenset(p) for p in self.hand.collision_exclude}
        self._pair_of: dict[tuple[int, int], int] = {}
        n = gm.ngeoms
        for a in range(n):
            for b in range(a + 1, n):
                if self._skip_pair(a, b, excluded):
                    continue
                gm.addCollisionPair(pin.CollisionPair(a, b))
                self._pair_of[(a, b)] = len(gm.collisionPairs) - 1
        self._tip_object_pairs = [self._pair_of[(g, self.object_geom)] for g in self.tip_geoms]

    # -------------------------------------------------------------- internals
    def _skip_pair(self, a: int, b: int, excluded: set[frozenset[str]]) -> bool:
        nh = self._n_hand_geoms
        if a >= nh and b >= nh:  # object vs obstacle only; obstacles never move
            return a != self.object_geom
        if a >= nh or b >= nh:
            return False
        ja = self.geom_model.geometryObjects[a].parentJoint
        jb = self.geom_model.geometryObjects[b].parentJoint
        parents = self.hand.model.parents
        if ja == jb or parents[ja] == jb or parents[jb] == ja:
            return True
        return frozenset((self._link_of[a], self._link_of[b])) in excluded

    def _place(self, q_hand: FloatArray, object_pose_xyzquat: FloatArray) -> pin.SE3:
        pin.updateGeometryPlacements(
            self.hand.model, self.hand.data, self.geom_model, self.geom_data, q_hand
        )
        M = pose_to_se3(object_pose_xyzquat)
        self.geom_data.oMg[self.object_geom] = M
        return M

    def _set_tip_pairs(self, contact_fingers: tuple[bool, ...]) -> None:
        # toggling pairs is a C++ call per finger: only when the mask changes
        if contact_fingers == self._tip_mask:
            return
        gd = self.geom_data
        for i, pair in enumerate(self._tip_object_pairs):
            if contact_fingers[i]:
                gd.deactivateCollisionPair(pair)
            else:
                gd.activateCollisionPair(pair)
        self._tip_mask = contact_fingers

    def geometry_name(self, g: int) -> str:
        """Readable name of geometry ``g`` (link name, ``object`` or obstacle name)."""
        go = self.geom_model.geometryObjects[g]
        return self._link_of[g] if g < self._n_hand_geoms else go.name

    def finger_of(self, name: str) -> int | None:
        """Finger owning the geometry called ``name`` (a link name), or None."""
        return self._finger_of_name.get(name)

    # ------------------------------------------------------------------ queries
    def check(
        self,
        q_hand: FloatArray,
        object_pose_xyzquat: FloatArray,
        contact_fingers: Sequence[bool],
        *,
        first_only: bool = True,
    ) -> CollisionReport:
        """Check a configuration for collisions.

        Args:
            q_hand: (nq,) hand configuration.
            object_pose_xyzquat: (7,) object pose in the world frame, XYZW.
            contact_fingers: per finger, True when its tip is in contact with
                the object (that pair is then measured, not collision-checked).
            first_only: stop at the first colliding pair.

        Returns:
            A :class:`CollisionReport`.
        """
        M = self._place(q_hand, object_pose_xyzquat)
        gd = self.geom_data
        mask = tuple(bool(c) for c in contact_fingers)
        self._set_tip_pairs(mask)
        penetration = 0.0
        if any(mask):
            # forward kinematics is fresh from _place: only the tip frames are updated
            hand = self.hand
            R, t = M.rotation, M.translation
            sdf = self.obj._sdf_grad_xyz
            worst = np.inf
            for i, fid in enumerate(hand.tip_frame_ids):
                if mask[i]:
                    p = pin.updateFramePlacement(hand.model, hand.data, fid).translation
                    x, y, z = ((p - t) @ R).tolist()
                    worst = min(worst, sdf(x, y, z)[0])
            penetration = max(0.0, hand.fingertip_radius - worst)
        pair_names = None
        if pin.computeCollisions(self.geom_model, gd, first_only):
            for k, res in enumerate(gd.collisionResults):
                if res.isCollision():
                    cp = self.geom_model.collisionPairs[k]
                    pair_names = (self.geometry_name(cp.first), self.geometry_name(cp.second))
                    break
        free = pair_names is None and penetration <= CONTACT_PENETRATION_TOL
        return CollisionReport(free, pair_names, penetration)

    def is_free(
        self,
        q_hand: FloatArray,
        object_pose_xyzquat: FloatArray,
        contact_fingers: Sequence[bool],
    ) -> bool:
        """True when :meth:`check` finds no collision (stops at the first one)."""
        return self.check(q_hand, object_pose_xyzquat, contact_fingers).free

    def finger_pairs(self, finger: int) -> list[int]:
        """Collision pairs of a finger's links against the palm, the object and the obstacles.

        The fingertip-object pair (the contact) and pairs with other fingers
        are left out: those move with the other fingers. What a finger placed
        alone (the sampler's pools, landing tracks) must keep clear of.
        """
        mine = set(self.finger_geoms[finger])
        on_fingers = {g for geoms in self.finger_geoms for g in geoms}
        tip = self.tip_geoms[finger]
        out = []
        for k, cp in enumerate(self.geom_model.collisionPairs):
            for g, other in ((cp.first, cp.second), (cp.second, cp.first)):
                if g not in mine or other in on_fingers:
                    continue
                if other == self.object_geom and g == tip:
                    continue
                out.append(k)
        return out

    def free_finger_pairs(self, finger: int) -> list[int]:
        """The collision pairs a move of ``finger`` alone can change, while it is free.

        Every pair with a geometry on the finger (its fingertip-object pair
        included, as a free finger's is checked), except the other fingers'
        fingertip-object pairs, which a contact mask with only ``finger`` free
        switches off.
        """
        mine = set(self.finger_geoms[finger])
        off = {k for j, k in enumerate(self._tip_object_pairs) if j != finger}
        return [
            k
            for k, cp in enumerate(self.geom_model.collisionPairs)
            if (cp.first in mine or cp.second in mine) and k not in off
        ]

    def pairs_data(self, pairs: Sequence[int]) -> pin.GeometryData:
        """Geometry data of this world with only the collision pairs ``pairs`` active.

        For :meth:`pairs_collide`: one C++ call checks a subset of the pairs
        (a Python loop over ``pin.computeCollision`` cost about 3x more).
        Collision requests are the world's own (contacts on).
        """
        gd = pin.GeometryData(self.geom_model)
        for req, own in zip(gd.collisionRequests, self.geom_data.collisionRequests, strict=True):
            req.enable_contact = own.enable_contact
        gd.deactivateAllCollisionPairs()
        for k in pairs:
            gd.activateCollisionPair(int(k))
        return gd

    def pairs_collide(self, gd: pin.GeometryData, q_hand: FloatArray, M_obj: pin.SE3) -> bool:
        """True when an active pair of ``gd`` (from :meth:`pairs_data`) collides.

        Args:
            gd: the pair subset's geometry data.
            q_hand: (nq,) hand configuration.
            M_obj: the object's placement in the world frame.
        """
        pin.updateGeometryPlacements(self.hand.model, self.hand.data, self.geom_model, gd, q_hand)
        gd.oMg[self.object_geom] = M_obj
        return bool(pin.computeCollisions(self.geom_model, gd, True))

    def object_collides(self, object_pose_xyzquat: FloatArray) -> bool:
        """True when the object at ``object_pose_xyzquat`` touches an obstacle."""
        if not self.obstacle_geoms:
            return False
        M = pose_to_se3(object_pose_xyzquat)
        gd, gm = self.geom_data, self.geom_model
        gd.oMg[self.object_geom] = M
        for g in self.obstacle_geoms:
            k = self._pair_of[(self.object_geom, g)]
            if pin.computeCollision(gm, gd, k):
                return True
        return False

    def object_overlaps(self, object_pose_xyzquat: FloatArray) -> list[tuple[str, bool, float]]:
        """What the object at a pose intersects, other than the fingers.

        The palm's geometries (those on no finger: they never move) and the
        obstacles: an object there cannot be grasped, whatever the fingers do.

        Returns:
            ``(name, is_palm, depth)`` per intersected geometry: its link name
            or the obstacle's (as the scenario names it), whether it is part
            of the palm, and the penetration depth (m, > 0; 0 where coal does
            not measure it).
        """
        gd, gm = self.geom_data, self.geom_model
        pin.updateGeometryPlacements(self.hand.model, self.hand.data, gm, gd, self.hand.neutral)
        gd.oMg[self.object_geom] = pose_to_se3(object_pose_xyzquat)
        on_finger = {g for geoms in self.finger_geoms for g in geoms}
        palm = [g for g in range(self._n_hand_geoms) if g not in on_finger]
        out = []
        names = {g: ob.name for g, ob in zip(self.obstacle_geoms, self.obstacles, strict=True)}
        for g in [*palm, *self.obstacle_geoms]:
            k = self._pair_of.get((min(g, self.object_geom), max(g, self.object_geom)))
            if k is None or not pin.computeCollision(gm, gd, k):
                continue
            res = gd.collisionResults[k]  # contacts are on (see __init__): coal's depth
            depth = abs(float(res.getContact(0).penetration_depth)) if res.numContacts() else 0.0
            out.append((names.get(g, self.geometry_name(g)), g < self._n_hand_geoms, depth))
        return out

    def object_clearance(self, object_pose_xyzquat: FloatArray) -> float:
        """Distance (m) from the object at a pose to the nearest obstacle (inf without any).

        Negative values are penetration depths where coal can compute them.
        """
        if not self.obstacle_geoms:
            return float("inf")
        gd, gm = self.geom_data, self.geom_model
        gd.oMg[self.object_geom] = pose_to_se3(object_pose_xyzquat)
        best = float("inf")
        for g in self.obstacle_geoms:
            k = self._pair_of[(self.object_geom, g)]
            best = min(best, float(pin.computeDistance(gm, gd, k).min_distance))
        return best

    def object_signed_distance(
        self, p_world: FloatArray, object_pose_xyzquat: FloatArray
    ) -> FloatArray:
        """Signed distance of world points ``p_world: (N, 3)`` to the object surface."""
        M = pose_to_se3(object_pose_xyzquat)
        p_obj = (np.asarray(p_world) - M.translation) @ M.rotation
        return np.atleast_1d(self.obj.signed_distance(p_obj))

    def finger_object_distance(
        self, q_hand: FloatArray, object_pose_xyzquat: FloatArray, finger: int
    ) -> float:
        """Minimum distance (m) between any geometry of ``finger`` and the object.

        Negative values are penetration depths where coal can compute them.
        """
        if not 0 <= finger < self.hand.n_fingers:
            raise InvalidInputError(f"finger must be in [0, {self.hand.n_fingers}), got {finger!r}")
        self._place(q_hand, object_pose_xyzquat)
        best = np.inf
        for g in self.finger_geoms[finger]:
            k = self._pair_of[(g, self.object_geom)]
            res = pin.computeDistance(self.geom_model, self.geom_data, k)
            best = min(best, res.min_distance)
        return float(best)


def _ancestors(model: pin.Model, jid: int) -> set[int]:
    out = set()
    while jid > 0:
        jid = model.parents[jid]
        out.add(jid)
    return out
