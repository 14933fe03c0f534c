"""Multi-fingered hand: Pinocchio model, fingertip kinematics and per-finger IK.

A :class:`Hand` is a fixed-base kinematic tree loaded from URDF whose palm frame
is the world frame. It has n fingers, each a serial chain of 1-DOF joints that
ends in a spherical fingertip; a finger is named by the frame at the centre of
its fingertip sphere. Fingers must not share joints, so finger i's tip moves
only with finger i's joints and the hand Jacobian is block diagonal.

Configuration ``q_hand: (nq,)`` follows :attr:`Hand.joint_names` (URDF joint
order as Pinocchio reads it). ``finger_q_index[i]`` gives the entries of
``q_hand`` that belong to finger i.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import metadata, resources
from pathlib import Path

import numpy as np
import pinocchio as pin

from dexplan.core.errors import DependencyError, InvalidInputError, ModelError, shorten
from dexplan.core.files import read_input_file
from dexplan.core.typing import FloatArray, IntArray, as_vector
from dexplan.model.hand.ik import FingerChain, SplitFingerIK, batch_dls
from dexplan.model.hand.reach import ReachVoxels
from dexplan.model.hand.urdf import (
    build_models,
    check_collision_exclude,
    check_finger_geometry,
    check_fingertip_radius,
    mount_urdf,
    parse_urdf,
    urdf_text,
)

#: Frames the builtin hands use for their fingertips.
PAPER_HAND_TIPS: tuple[str, ...] = ("f0_tip", "f1_tip", "f2_tip", "f3_tip")
PAPER_HAND_TIP_RADIUS = 0.012
THREE_FINGER_TIPS: tuple[str, ...] = ("f0_tip", "f1_tip", "f2_tip")
THREE_FINGER_TIP_RADIUS = 0.012
#: Allegro fingers: index, middle, ring, thumb. The joints follow Pinocchio's
#: order (index q[0:4], thumb q[4:8], middle q[8:12], ring q[12:16]).
ALLEGRO_TIPS: tuple[str, ...] = ("link_3.0_tip", "link_7.0_tip", "link_11.0_tip", "link_15.0_tip")
ALLEGRO_TIP_RADIUS = 0.012
#: The palm box and the thumb's second link overlap by design (for joint_12.0 < 0.9).
ALLEGRO_COLLISION_EXCLUDE: tuple[tuple[str, str], ...] = (("palm_link", "link_13.0"),)
#: Roll, pitch, yaw (URDF fixed-axis XYZ) of palm_link in the world frame: the
#: palm normal (palm_link +x) is world +z, the fingers (palm_link +z) point
#: along world +x, palm_link +y is world -y. palm_link's origin is the world origin.
ALLEGRO_MOUNT_RPY: tuple[float, float, float] = (math.pi, -math.pi / 2, 0.0)
BUILTIN_HANDS: tuple[str, ...] = ("paper", "three_finger", "allegro", "allegro_left")


def _halton(n: int, dims: int) -> FloatArray:
    """First ``n`` points of the Halton sequence in ``[0, 1)^dims`` (IK restarts)."""
    primes = (2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37)[:dims]
    out = np.empty((n, dims))
    for j, b in enumerate(primes):
        for i in range(n):
            f, r, k = 1.0, 0.0, i + 1
            while k:
                f /= b
                r += f * (k % b)
                k //= b
            out[i, j] = r
    return out


_HALTON = _halton(16, 12)


def _joint_limits(
    model: pin.Model, joint_names: Sequence[str], name: str
) -> tuple[FloatArray, FloatArray]:
    """(nq,) lower and upper joint limits, checked finite and ordered.

    Raises:
        ModelError: a joint without finite limits or with lower > upper.
    """
    lower = np.array(model.lowerPositionLimit, dtype=float)
    upper = np.array(model.upperPositionLimit, dtype=float)
    for j, joint in enumerate(joint_names):
        lo, hi = lower[j], upper[j]
        if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi:
            raise ModelError(
                f"hand {name!r}: joint {joint!r} needs finite limits with lower <= upper, "
                f"got lower={lo!r}, upper={hi!r}"
            )
    return lower, upper


def _fingertip_list(fingertip_frames: object, name: str) -> tuple[str, ...]:
    """The fingertip frame names as given: a list of at least 2, none repeated.

    Raises:
        ModelError: not a list, fewer than 2 frames, or a repeated frame.
    """
    if isinstance(fingertip_frames, str | bytes) or not isinstance(fingertip_frames, Sequence):
        raise ModelError(
            f"hand {name!r}: fingertip_frames must be a list of frame names, "
            f"got {shorten(fingertip_frames)}"
        )
    tips = list(fingertip_frames)
    if len(tips) < 2:
        raise ModelError(f"hand {name!r} needs at least 2 fingertip frames, got {shorten(tips)}")
    if len(set(map(repr, tips))) != len(tips):
        raise ModelError(f"hand {name!r}: fingertip_frames repeat a frame: {shorten(tips)}")
    return tuple(tips)


def _fingertip_frame_id(model: pin.Model, tip: object, name: str) -> int:
    """Pinocchio frame id of the fingertip frame ``tip``.

    Raises:
        ModelError: ``tip`` is not the name of a frame of the model.
    """
    frames = [f.name for f in model.frames]
    if not isinstance(tip, str) or tip not in frames:
        raise ModelError(
            f"unknown fingertip frame {shorten(tip)} in hand {name!r}; "
            f"frames are {shorten(frames, 200)}"
        )
    return int(model.getFrameId(tip))


def _finger_chain(model: pin.Model, fid: int, tip: str) -> list[int]:
    """Sorted ``q`` indices of the joints between the root and frame ``fid``.

    Raises:
        ModelError: no joint moves the frame.
    """
    chain = []
    jid = model.frames[fid].parentJoint
    while jid > 0:
        chain.append(model.joints[jid].idx_q)
        jid = model.parents[jid]
    chain.sort()
    if not chain:
        raise ModelError(f"fingertip frame {tip!r} is not moved by any joint")
    return chain


@dataclass(frozen=True)
class IKResult:
    """Outcome of a per-finger inverse kinematics solve.

    Attributes:
        q_finger: (m,) joint values of the finger, always within limits.
        success: True when the tip reached the target within tolerance.
        residual: |p_tip - p_target| in metres at ``q_finger``.
        iterations: solver iterations used (over all restarts).
    """

    q_finger: FloatArray
    success: bool
    residual: float
    iterations: int


class Hand:
    """A fixed-palm multi-fingered hand loaded from URDF.

    The URDF's root link is fixed in the world frame (the scenario's palm
    frame); see ``docs/hands.md`` for the rules a URDF hand must follow.

    Args:
        urdf_xml: full URDF text (``str``; UTF-8 ``bytes`` are decoded).
            Collision geometry may be boxes, spheres, cylinders, meshes
            Pinocchio can load (``package_dirs`` resolves ``package://``) and
            ``<capsule radius= length=>`` elements, which dexplan parses itself
            (``length`` between the cap centres, along the local z axis).
        fingertip_frames: one frame name per finger, at the fingertip sphere centre.
        fingertip_radius: radius of the fingertip spheres (m), in
            ``(0, dexplan.model.hand.urdf.MAX_FINGERTIP_RADIUS]`` (0.05 m).
        collision_exclude: link-name pairs never checked against each other
            (beyond adjacent links, which are always excluded).
        name: human-readable name.
        package_dirs: directories searched for mesh files.

    Raises:
        ModelError: text that is not UTF-8, malformed XML, an invalid URDF (the
            message carries urdfdom's first line), joints that are not 1-DOF
            with finite, ordered limits, collision elements that could not be
            loaded, a finger link without collision geometry, unknown
            fingertip frames or ``collision_exclude`` links, fingers that share
            joints, or an implausible fingertip radius.
    """

    def __init__(
        self,
        urdf_xml: str,
        fingertip_frames: Sequence[str],
        fingertip_radius: float,
        *,
        collision_exclude: Sequence[tuple[str, str]] = (),
        name: str = "hand",
        package_dirs: Sequence[str | Path] = (),
    ) -> None:
        self.name = name
        self.urdf_xml = urdf_text(urdf_xml, f"URDF of hand {name!r}")
        self.fingertip_radius = check_fingertip_radius(fingertip_radius, name)
        description = parse_urdf(self.urdf_xml, name)
        #: folders the URDF's mesh files were found in (viewers load its visual meshes there)
        self.package_dirs: tuple[str, ...] = tuple(str(d) for d in package_dirs)
        self.model, self.geom_model = build_models(description, name, package_dirs)
        self.data: pin.Data = self.model.createData()

        self.joint_names: tuple[str, ...] = tuple(self.model.names[1:])
        self.lower, self.upper = _joint_limits(self.model, self.joint_names, name)
        links = {f.name for f in self.model.frames if f.type == pin.FrameType.BODY}
        self.collision_exclude = check_collision_exclude(collision_exclude, links, name)
        self.fingertip_frames: tuple[str, ...] = _fingertip_list(fingertip_frames, name)
        self.tip_frame_ids: tuple[int, ...] = ()
        finger_q_index: list[IntArray] = []
        used: set[int] = set()
        for tip in self.fingertip_frames:
            fid = _fingertip_frame_id(self.model, tip, name)
            self.tip_frame_ids += (fid,)
            chain = _finger_chain(self.model, fid, tip)
            if used.intersection(chain):
                raise ModelError(f"fingertip frame {tip!r} shares joints with another finger")
            used.update(chain)
            finger_q_index.append(np.array(chain, dtype=np.int64))
            check_finger_geometry(self.model, self.geom_model, fid, self.fingertip_radius, name)
        self.finger_q_index: tuple[IntArray, ...] = tuple(finger_q_index)
        self.neutral: FloatArray = np.clip(pin.neutral(self.model), self.lower, self.upper)
        self._init_ik()

    def _init_ik(self) -> None:
        """Per-finger IK solvers: closed form where the structure allows it.

        ``_PlanarFingerIK`` for planar 3-joint fingers; otherwise the vectorised
        kinematics of :mod:`dexplan.model.hand.ik` (closed form also for 4-joint fingers,
        redundancy on a grid, else batched DLS).
        """
        self._analytic_ik: list[_PlanarFingerIK | None] = [
            _PlanarFingerIK.detect(self, i) for i in range(self.n_fingers)
        ]
        self._chains: list[FingerChain | None] = [
            FingerChain.from_model(self.model, fid) for fid in self.tip_frame_ids
        ]
        self._split_ik: list[SplitFingerIK | None] = [
            None
            if self._analytic_ik[i] is not None
            else SplitFingerIK.detect(
                self._chains[i],
                self.lower[self.finger_q_index[i]],
                self.upper[self.finger_q_index[i]],
            )
            for i in range(self.n_fingers)
        ]
        self._reach: list[ReachVoxels | None] = [None] * self.n_fingers

    # ------------------------------------------------------------------ loading
    @classmethod
    def from_urdf_file(
        cls,
        path: str | Path,
        fingertip_frames: Sequence[str],
        fingertip_radius: float,
        **kwargs: object,
    ) -> Hand:
        """Load a hand from a URDF file; mesh paths resolve relative to its folder.

        Raises:
            ModelError: the file is missing, unreadable or not UTF-8 text, or
                :class:`Hand` rejects it.
        """
        path = Path(path)
        data = read_input_file(path, "URDF", ModelError)
        text = urdf_text(data, f"URDF file {str(path)!r}")
        kwargs.setdefault("name", path.stem)
        kwargs.setdefault("package_dirs", [str(path.parent)])
        return cls(text, fingertip_frames, fingertip_radius, **kwargs)  # type: ignore[arg-type]

    @classmethod
    def builtin(cls, name: str = "paper") -> Hand:
        """Return a builtin hand (see :data:`BUILTIN_HANDS`).

        ``"paper"`` (4 x 3 DOF, after the paper) and ``"three_finger"``
        (3 x 3 DOF, capsule links) ship with dexplan; ``"allegro"`` and
        ``"allegro_left"`` (4 x 4 DOF) are read from the installed
        ``example-robot-data`` distribution and mounted palm-up (see
        :data:`ALLEGRO_MOUNT_RPY`).

        Raises:
            InvalidInputError: unknown name.
            DependencyError: an Allegro hand without ``example-robot-data``.
        """
        if name == "paper":
            text = _data_text("paper_hand.urdf")
            return cls(text, PAPER_HAND_TIPS, PAPER_HAND_TIP_RADIUS, name="paper")
        if name == "three_finger":
            text = _data_text("three_finger.urdf")
            return cls(text, THREE_FINGER_TIPS, THREE_FINGER_TIP_RADIUS, name="three_finger")
        if name in ("allegro", "allegro_left"):
            return _allegro_hand(left=name == "allegro_left")
        raise InvalidInputError(
            f"hand.builtin must be one of {list(BUILTIN_HANDS)}, got {shorten(name)}"
        )

    # --------------------------------------------------------------- properties
    @property
    def n_fingers(self) -> int:
        """Number of fingers n."""
        return len(self.tip_frame_ids)

    @property
    def nq(self) -> int:
        """Number of hand joints."""
        return self.model.nq

    def check_q(self, q_hand: object, name: str = "q") -> FloatArray:
        """Return ``q_hand`` as a finite (nq,) array or raise InvalidInputError."""
        return as_vector(q_hand, name, self.nq)

    def within_limits(self, q_hand: FloatArray, tol: float = 0.0) -> bool:
        """True when every joint of ``q_hand: (nq,)`` lies within its limits (+- tol)."""
        return bool(np.all(q_hand >= self.lower - tol) and np.all(q_hand <= self.upper + tol))

    # --------------------------------------------------------------- kinematics
    def fingertip_positions(self, q_hand: FloatArray) -> FloatArray:
        """Fingertip sphere centres ``p_tip_world: (n, 3)`` in the palm/world frame."""
        pin.forwardKinematics(self.model, self.data, q_hand)
        out = np.empty((self.n_fingers, 3))
        for i, fid in enumerate(self.tip_frame_ids):
            out[i] = pin.updateFramePlacement(self.model, self.data, fid).translation
        return out

    def fingertip_jacobians(self, q_hand: FloatArray) -> tuple[FloatArray, list[FloatArray]]:
        """Fingertip centres and their position Jacobians.

        Args:
            q_hand: (nq,) hand configuration.

        Returns:
            ``p_tip_world: (n, 3)`` and, per finger i, ``J_i: (3, m_i)`` the
            derivative of finger i's tip centre (world frame) with respect to
            its own joints ``q_hand[finger_q_index[i]]``.
        """
        model, data = self.model, self.data
        pin.computeJointJacobians(model, data, q_hand)
        p = np.empty((self.n_fingers, 3))
        jacs = []
        for i, fid in enumerate(self.tip_frame_ids):
            p[i] = pin.updateFramePlacement(model, data, fid).translation
            J = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
            jacs.append(J[:3, self.finger_q_index[i]])
        return p, jacs

    def joint_origin(self, q_index: int, q_hand: FloatArray) -> FloatArray:
        """World position ``(3,)`` of the joint whose value is ``q_hand[q_index]``."""
        jid = next(j for j in range(1, self.model.njoints) if self.model.idx_qs[j] == q_index)
        pin.forwardKinematics(self.model, self.data, q_hand)
        return self.data.oMi[jid].translation.copy()

    def frame_placements(self, q_hand: FloatArray) -> dict[str, pin.SE3]:
        """World placement of every body frame (link) at ``q_hand``."""
        pin.framesForwardKinematics(self.model, self.data, q_hand)
        return {
            f.name: self.data.oMf[i].copy()
            for i, f in enumerate(self.model.frames)
            if f.type == pin.FrameType.BODY
        }

    def finger_ik_fast(
        self,
        finger: int,
        p_target_world: FloatArray,
        q_hand: FloatArray,
        approach: FloatArray | None = None,
    ) -> FloatArray | None:
        """:meth:`finger_ik` for inner loops: no input checks, None on failure.

        Closed-form fingers skip the FK confirmation (the solver was checked
        against FK when the hand was loaded); others run :meth:`finger_ik`.

        Args:
            finger: finger index.
            p_target_world: (3,) fingertip-centre target, world frame.
            q_hand: (nq,) configuration whose finger values break branch ties.
            approach: (3,) unit direction the fingertip presses in (inward
                surface normal, world frame): redundant fingers use it to keep
                the last link pointing into the surface (see
                ``dexplan.model.hand.ik.SplitFingerIK.solve_near``); others ignore it.

        Returns:
            ``q_finger: (m,)`` within limits, or None.
        """
        analytic = self._analytic_ik[finger]
        if analytic is not None:
            return analytic.solve(p_target_world, q_hand[self.finger_q_index[finger]])
        split = self._split_ik[finger]
        if split is not None:
            return split.solve_near(p_target_world, q_hand[self.finger_q_index[finger]], approach)
        res = self.finger_ik(finger, p_target_world, q_hand)
        return res.q_finger if res.success else None

    def finger_ik_alternatives(
        self, finger: int, p_target_world: FloatArray, q_hand: FloatArray, approach: FloatArray
    ) -> FloatArray:
        """IK solutions one tracking step from ``q_hand``, best posture first.

        For redundant closed-form fingers, the solutions with every joint
        within ``dexplan.model.hand.ik.TRACK_MAX_STEP`` of ``q_hand``'s, sorted as
        ``dexplan.model.hand.ik.SplitFingerIK.options_near`` does; other fingers have
        none (an empty ``(0, m)`` array).

        Args:
            finger: finger index.
            p_target_world: (3,) fingertip-centre target, world frame.
            q_hand: (nq,) previous hand configuration.
            approach: (3,) unit inward surface normal, world frame.
        """
        split = self._split_ik[finger]
        idx = self.finger_q_index[finger]
        if split is None:
            return np.zeros((0, len(idx)))
        return split.options_near(p_target_world, q_hand[idx], approach)

    def reach_voxels(self, finger: int) -> ReachVoxels:
        """Where ``finger``'s fingertip centre can be (built on first use; see :mod:`.reach`)."""
        voxels = self._reach[finger]
        if voxels is None:
            voxels = self._reach[finger] = ReachVoxels.of_finger(self, finger)
        return voxels

    def has_closed_form_ik(self, finger: int) -> bool:
        """True when ``finger`` is solved in closed form (see :meth:`finger_ik`).

        Redundant 4-joint fingers whose other three joints have a closed form
        count (``dexplan.model.hand.ik.SplitFingerIK``; docs/hands.md, "IK and redundancy").
        """
        return self._analytic_ik[finger] is not None or self._split_ik[finger] is not None

    def finger_ik_candidates(
        self, finger: int, p_targets_world: FloatArray
    ) -> tuple[FloatArray, np.ndarray]:
        """Several IK solutions of one finger per target (all branches, free-joint grid).

        Args:
            finger: finger index.
            p_targets_world: (N, 3) fingertip-centre targets, world frame.

        Returns:
            ``q_finger: (N, C, m)`` within limits and ``ok: (N, C)``. Closed-form
            redundant fingers give every branch at every grid value of the free
            joint; other fingers one solution per target (C = 1).
        """
        targets = np.asarray(p_targets_world, dtype=float).reshape(-1, 3)
        split = self._split_ik[finger]
        if split is not None:
            return split.candidates(targets)
        q, ok = self.finger_ik_batch(finger, targets)
        return q[:, None, :], ok[:, None]

    def finger_ik_batch(
        self, finger: int, p_targets_world: FloatArray, q_init: FloatArray | None = None
    ) -> tuple[FloatArray, np.ndarray]:
        """IK of one finger for many targets at once.

        Args:
            finger: finger index.
            p_targets_world: (N, 3) fingertip-centre targets, world frame.
            q_init: (nq,) hand configuration used as the start of iterative solves.

        Returns:
            ``q_finger: (N, m)`` within limits and ``ok: (N,)`` success flags.
            Closed-form fingers are solved vectorized (a redundant finger
            gives the solution nearest the middle of its joint ranges, see
            :meth:`finger_ik_candidates`); other revolute fingers by batched
            damped least squares from ``q_init``; the rest call
            :meth:`finger_ik` per target.
        """
        targets = np.asarray(p_targets_world, dtype=float).reshape(-1, 3)
        analytic = self._analytic_ik[finger]
        if analytic is not None:
            return analytic.solve_batch(targets)
        split = self._split_ik[finger]
        if split is not None:
            return split.solve(targets)
        idx = self.finger_q_index[finger]
        chain = self._chains[finger]
        if chain is not None:
            q0 = (self.neutral if q_init is None else q_init)[idx]
            q_b, ok_b = batch_dls(chain, targets, q0, self.lower[idx], self.upper[idx])
            if not ok_b.all():  # deterministic restart from the middle of the ranges
                bad = np.flatnonzero(~ok_b)
                mid = 0.5 * (self.lower[idx] + self.upper[idx])
                q_b[bad], ok_b[bad] = batch_dls(
                    chain, targets[bad], mid, self.lower[idx], self.upper[idx]
                )
            return q_b, ok_b
        m = len(self.finger_q_index[finger])
        q_out = np.zeros((len(targets), m))
        ok = np.zeros(len(targets), dtype=bool)
        for k, t in enumerate(targets):
            res = self.finger_ik(finger, t, q_init)
            q_out[k], ok[k] = res.q_finger, res.success
        return q_out, ok

    def _finger_tip(self, finger: int, q_hand: FloatArray) -> tuple[FloatArray, FloatArray]:
        fid = self.tip_frame_ids[finger]
        J = pin.computeFrameJacobian(self.model, self.data, q_hand, fid, pin.LOCAL_WORLD_ALIGNED)
        p = self.data.oMf[fid].translation.copy()
        return p, J[:3, self.finger_q_index[finger]]

    def finger_ik(
        self,
        finger: int,
        p_target_world: object,
        q_init: FloatArray | None = None,
        *,
        tol: float = 1e-7,
        max_iter: int = 60,
        restarts: int = 4,
    ) -> IKResult:
        """Damped least squares IK of one finger's tip centre, within joint limits.

        Fingers of the "abduction + planar two-link" kind (as on the builtin
        paper hand), and 4-joint fingers that are of that kind once one free
        joint is fixed (the Allegro's, ``dexplan.model.hand.ik.SplitFingerIK``: the
        solution nearest ``q_init``), are solved in closed form first (checked
        against FK when the hand is loaded); others, and targets the closed
        form cannot reach within limits, use Levenberg-Marquardt steps
        ``dq = J^T (J J^T + lambda I)^-1 e`` with
        ``lambda = |e|^2 + 1e-9`` (damping vanishes near a solution, so the
        convergence is quadratic there, and stays bounded at singularities),
        clipped to the joint limits. When a run stalls, it restarts from the
        limits' midpoint and then from deterministic pseudo-random points, so
        the same call always gives the same answer.

        Args:
            finger: finger index in ``[0, n)``.
            p_target_world: (3,) target of the fingertip centre, world frame.
            q_init: (nq,) full hand configuration to start from (the other
                fingers' values are kept); defaults to the neutral configuration.
            tol: success threshold on the position error (m).
            max_iter: iterations per start.
            restarts: extra starts after the first.

        Returns:
            An :class:`IKResult`; an unreachable target gives ``success=False``
            and the closest configuration found, never an exception.

        Raises:
            InvalidInputError: bad finger index or non-finite target.
        """
        if not 0 <= finger < self.n_fingers:
            raise InvalidInputError(f"finger must be in [0, {self.n_fingers}), got {finger!r}")
        target = as_vector(p_target_world, "p_target_world", 3)
        q = self.neutral.copy() if q_init is None else self.check_q(q_init, "q_init").copy()
        idx = self.finger_q_index[finger]
        analytic = self._analytic_ik[finger]
        if analytic is not None:
            q_f = analytic.solve(target, q[idx])
            if q_f is not None:
                q[idx] = q_f
                err = float(np.linalg.norm(self._finger_tip(finger, q)[0] - target))
                if err < tol:
                    return IKResult(q_f, True, err, 1)
        split = self._split_ik[finger]
        if split is not None:
            q_f = split.solve_near(target, q[idx])
            if q_f is None:  # the free joint anywhere in its range
                q_all, ok_all = split.solve(target[None], q[idx])
                q_f = q_all[0] if ok_all[0] else None
            if q_f is not None:
                q_try = q.copy()
                q_try[idx] = q_f
                err = float(np.linalg.norm(self._finger_tip(finger, q_try)[0] - target))
                if err < tol:
                    return IKResult(q_f, True, err, 1)
        lo, hi = self.lower[idx], self.upper[idx]
        eye = np.eye(3)
        best_q, best_err, iters = np.clip(q[idx], lo, hi), math.inf, 0
        for attempt in range(restarts + 1):
            if attempt == 0:
                q[idx] = best_q
            elif attempt == 1:
                q[idx] = 0.5 * (lo + hi)
            else:  # deterministic pseudo-random restarts: same call, same answer
                q[idx] = lo + (hi - lo) * _HALTON[(attempt - 2) % len(_HALTON), : len(idx)]
            for _ in range(max_iter):
                iters += 1
                p, J = self._finger_tip(finger, q)
                e = target - p
                err = math.sqrt(e @ e)
                if err < best_err:
                    best_err, best_q = err, q[idx].copy()
                if err < tol:
                    return IKResult(best_q, True, best_err, iters)
                dq = J.T @ np.linalg.solve(J @ J.T + (err * err + 1e-9) * eye, e)
                q_new = np.clip(q[idx] + dq, lo, hi)
                if np.max(np.abs(q_new - q[idx])) < 1e-12:
                    break  # stalled against a limit or in a local minimum
                q[idx] = q_new
        return IKResult(best_q, best_err < tol, best_err, iters)


class _PlanarFingerIK:
    """Closed-form IK of an abduction joint followed by a planar 2R chain.

    Geometry read off the model at q = 0: abduction axis ``a0`` through ``o0``;
    the flexion joints' origins and the tip lie on the ray from ``o0`` along
    ``e`` (perpendicular to ``a0``) at distances ``k``, ``k + l1`` and
    ``k + l1 + l2``; both flexion axes are perpendicular to ``a0`` and ``e``.
    :meth:`detect` verifies the solver against FK before it is used.
    """

    def __init__(self, o0, a0, e, k, l1, l2, s, lo, hi) -> None:
        self.o0, self.a0, self.e = o0, a0, e
        self.b = np.cross(a0, e)
        self.k, self.l1, self.l2, self.s = k, l1, l2, s
        self.lo, self.hi = lo, hi

    @classmethod
    def detect(cls, hand: Hand, finger: int) -> _PlanarFingerIK | None:
        idx = hand.finger_q_index[finger]
        if len(idx) != 3:
            return None
        model, data = hand.model, hand.data
        q0 = np.zeros(hand.nq)
        pin.forwardKinematics(model, data, q0)
        fid = hand.tip_frame_ids[finger]
        tip = pin.updateFramePlacement(model, data, fid).translation.copy()
        jids = [j for i in idx for j in range(1, model.njoints) if model.idx_qs[j] == i]
        origins = [data.oMi[j].translation.copy() for j in jids]
        J = pin.computeJointJacobians(model, data, q0)
        axes = [J[3:, int(i)].copy() for i in idx]
        o0, a0 = origins[0], axes[0]
        ray = tip - o0
        if np.linalg.norm(ray) < 1e-9 or abs(ray @ a0) > 1e-7 * np.linalg.norm(ray):
            return None
        e = ray / np.linalg.norm(ray)
        k = float((origins[1] - o0) @ e)
        l1 = float((origins[2] - origins[1]) @ e)
        l2 = float((tip - origins[2]) @ e)
        f = axes[1]
        s = float(np.cross(f, e) @ a0)
        if min(l1, l2) <= 0 or abs(abs(s) - 1) > 1e-7 or np.linalg.norm(axes[2] - f) > 1e-7:
            return None
        solver = cls(o0, a0, e, k, l1, l2, s, hand.lower[idx], hand.upper[idx])
        rng = np.random.default_rng(0)
        q = hand.neutral.copy()
        for _ in range(20):
            q[idx] = rng.uniform(solver.lo, solver.hi)
            target = hand.fingertip_positions(q)[finger]
            sol = solver.solve(target, q[idx])
            if sol is None:
                return None
            q2 = q.copy()
            q2[idx] = sol
            if np.linalg.norm(hand.fingertip_positions(q2)[finger] - target) > 1e-8:
                return None
        return solver

    def solve(self, target: FloatArray, q_near: FloatArray) -> FloatArray | None:
        """Joint values within limits reaching ``target`` (closest to ``q_near``), or None."""
        p = target - self.o0
        u = float(p @ self.a0) * self.s
        pe, pb = float(p @ self.e), float(p @ self.b)
        r = math.hypot(pe, pb)
        base = math.atan2(pb, pe)
        best, best_d = None, math.inf
        l1, l2 = self.l1, self.l2
        for th0, w in ((base, r - self.k), (base - math.copysign(math.pi, base), -r - self.k)):
            c2 = (w * w + u * u - l1 * l1 - l2 * l2) / (2 * l1 * l2)
            if abs(c2) > 1.0:
                continue
            for th2 in (math.acos(c2), -math.acos(c2)):
                th1 = math.atan2(u, w) - math.atan2(l2 * math.sin(th2), l1 + l2 * math.cos(th2))
                th1 = (th1 + math.pi) % (2 * math.pi) - math.pi
                sol = np.array([th0, th1, th2])
                if np.all(sol >= self.lo - 1e-12) and np.all(sol <= self.hi + 1e-12):
                    d = float(np.sum((sol - q_near) ** 2))
                    if d < best_d:
                        best, best_d = np.clip(sol, self.lo, self.hi), d
        return best

    def solve_batch(self, targets: FloatArray) -> tuple[FloatArray, np.ndarray]:
        """Vectorized :meth:`solve` without the nearest-solution preference.

        Args:
            targets: (N, 3) fingertip-centre targets, world frame.

        Returns:
            ``q: (N, 3)`` and ``ok: (N,)``; among the branches within limits
            the first found is returned (abduction on the target's side first).
        """
        p = targets - self.o0
        u = (p @ self.a0) * self.s
        pe, pb = p @ self.e, p @ self.b
        r = np.hypot(pe, pb)
        base = np.arctan2(pb, pe)
        l1, l2 = self.l1, self.l2
        q_out = np.zeros((len(targets), 3))
        ok = np.zeros(len(targets), dtype=bool)
        lo, hi = self.lo - 1e-12, self.hi + 1e-12
        # elbow signs the third joint's limits allow at all (pruned for speed)
        signs = [sg for sg in (1.0, -1.0) if sg * hi[2] >= 0.0 or sg * lo[2] >= 0.0]
        for th0, w in ((base, r - self.k), (base - np.copysign(np.pi, base), -r - self.k)):
            cand = (th0 >= lo[0]) & (th0 <= hi[0]) & ~ok
            if not cand.any():
                continue
            c2 = (w * w + u * u - l1 * l1 - l2 * l2) / (2 * l1 * l2)
            cand &= np.abs(c2) <= 1.0
            a2 = np.arccos(np.clip(c2, -1.0, 1.0))
            for sg in signs:
                th2 = sg * a2
                th1 = np.arctan2(u, w) - np.arctan2(l2 * np.sin(th2), l1 + l2 * np.cos(th2))
                th1 = (th1 + np.pi) % (2 * np.pi) - np.pi
                new = cand & ~ok & (th1 >= lo[1]) & (th1 <= hi[1]) & (th2 >= lo[2]) & (th2 <= hi[2])
                q_out[new, 0] = th0[new]
                q_out[new, 1] = th1[new]
                q_out[new, 2] = th2[new]
                ok |= new
        return np.clip(q_out, self.lo, self.hi), ok


def _data_text(filename: str) -> str:
    """Text of ``dexplan/data/hands/<filename>``."""
    return resources.files("dexplan").joinpath(f"data/hands/{filename}").read_text(encoding="utf-8")


# -------------------------------------------------------------- Allegro hands
_ERD = "example-robot-data"
_ERD_PIP = "pip install 'dexplan[allegro]' (or: pip install example-robot-data)"


def example_robot_data_share(robot_file: Path | None = None) -> Path:
    """The folder ``package://example-robot-data/robots/...`` mesh URIs resolve against.

    Args:
        robot_file: a file of the distribution,
            ``.../share/example-robot-data/robots/<robot>/<folder>/<file>``
            (default: the Allegro right hand's URDF).

    Raises:
        DependencyError: example-robot-data is not installed.
    """
    if robot_file is None:
        robot_file = example_robot_data_file(
            "allegro_hand_description/urdf/allegro_right_hand.urdf"
        )
    return robot_file.parents[4]


def example_robot_data_file(relative: str) -> Path:
    """Path of a file the installed ``example-robot-data`` distribution ships.

    example-robot-data 4.4 and later install no Python module, only files under
    ``<site-packages>/cmeel.prefix/share/example-robot-data/robots/``; they are
    found through the distribution's file list (``importlib.metadata``).

    Args:
        relative: path below ``robots/``, e.g.
            ``"allegro_hand_description/urdf/allegro_right_hand.urdf"``.

    Raises:
        DependencyError: the distribution is not installed or lacks the file.
    """
    try:
        dist = metadata.distribution(_ERD)
    except metadata.PackageNotFoundError:
        raise DependencyError(f"{_ERD} is not installed: {_ERD_PIP}") from None
    suffix = f"robots/{relative}"
    candidates = [
        Path(str(dist.locate_file(f))) for f in dist.files or () if str(f).endswith(suffix)
    ]
    candidates.append(Path(str(dist.locate_file(f"cmeel.prefix/share/{_ERD}/robots/{relative}"))))
    for path in candidates:
        if path.is_file():
            return path
    raise DependencyError(
        f"{_ERD} {dist.version} is installed but has no {relative!r}: "
        "pip install --upgrade 'dexplan[allegro]'"
    )


def _allegro_hand(*, left: bool) -> Hand:
    """The Allegro right (or left) hand from example-robot-data, mounted palm-up."""
    hand_name = "allegro_left" if left else "allegro"
    side = "left" if left else "right"
    try:
        path = example_robot_data_file(f"allegro_hand_description/urdf/allegro_{side}_hand.urdf")
    except DependencyError as exc:
        raise DependencyError(f"hand {hand_name!r}: {exc}") from None
    text = urdf_text(path.read_bytes(), f"URDF file {str(path)!r}")
    return Hand(
        mount_urdf(text, ALLEGRO_MOUNT_RPY),
        ALLEGRO_TIPS,
        ALLEGRO_TIP_RADIUS,
        collision_exclude=ALLEGRO_COLLISION_EXCLUDE,
        name=hand_name,
        package_dirs=[str(example_robot_data_share(path))],
    )
