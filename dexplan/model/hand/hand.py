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

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin

from dexplan.core.errors import InvalidInputError, ModelError
from dexplan.core.typing import FloatArray, IntArray, as_vector
from dexplan.model.hand.builtin import builtin_hand
from dexplan.model.hand.extract import read_urdf
from dexplan.model.hand.fingertips import fingertip_spheres
from dexplan.model.hand.frames import (
    finger_joint_indices,
    fingertip_frame_id,
    fingertip_list,
    joint_limits,
    joint_names,
)
from dexplan.model.hand.ik import (
    FingerChain,
    FingerSolvers,
    IKResult,
    PlanarFingerIK,
    SplitFingerIK,
    batch_dls,
    branch_solutions,
    finger_dls,
)
from dexplan.model.hand.mimic import MimicJoint, mimic_joints
from dexplan.model.hand.mjcf import mjcf_arguments
from dexplan.model.hand.packages import mesh_sha256, search_dirs
from dexplan.model.hand.reach import ReachVoxels, grown_voxels, reach_samples
from dexplan.model.hand.urdf import (
    build_models,
    check_collision_exclude,
    check_finger_geometry,
    parse_urdf,
    urdf_text,
    with_effort_limits,
)
from dexplan.model.scenario.spec import HandSpec


class Hand:
    """A fixed-palm multi-fingered hand loaded from URDF.

    The URDF's root link is fixed in the world frame (the scenario's palm
    frame); see ``docs/hands.md`` for the rules a URDF hand must follow.

    Inverse kinematics, one method per use (the solver behind each is chosen
    per finger when the hand is loaded: closed form where the geometry allows,
    damped least squares otherwise):

    - :meth:`finger_ik`: one target, inputs checked, a full :class:`IKResult`;
    - :meth:`finger_ik_fast`: one target in an inner loop, unchecked, None on failure;
    - :meth:`finger_ik_alternatives`: the solutions one tracking step away
      (a redundant finger following a moving contact);
    - :meth:`finger_ik_batch`: one solution per target for many targets;
    - :meth:`finger_ik_candidates`: every branch per target for many targets
      (the sampler and the landing choice try them all; fingers without a
      closed form: seeded solves, :mod:`dexplan.model.hand.ik.branches`).

    Args:
        urdf_xml: full URDF text (``str``; UTF-8 ``bytes`` are decoded).
            Collision geometry may be boxes, spheres, cylinders, meshes
            Pinocchio can load (``package_dirs`` resolves ``package://``) and
            ``<capsule radius= length=>`` elements, which dexplan parses itself
            (``length`` between the cap centres, along the local z axis).
        fingertip_frames: one frame name per finger, at the fingertip sphere centre.
        fingertip_radius: radius of the fingertip spheres (m), in ``(0, 0.05]``;
            None reads it from the URDF's ``<sphere>`` at the tip frames. Tip
            frames without such a sphere get one added to the collision model
            (:mod:`dexplan.model.hand.fingertips`); a URDF sphere of another
            radius is refused.
        collision_exclude: link-name pairs never checked against each other
            (beyond adjacent links, which are always excluded).
        name: human-readable name.
        package_dirs: folders ``package://`` URIs and relative mesh paths are
            searched in first (then ROS_PACKAGE_PATH and the description
            wheels' share folders, see :mod:`dexplan.model.hand.packages`).
        effort_limits: joint effort limits (N m) replacing the URDF's: one for
            every joint, or a table by joint name (written into ``urdf_xml``).
        solvers: build the fingers' IK solvers now (False: on first use; a
            hand rebuilt from a plan file to check it never solves IK).

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
        fingertip_radius: float | None = None,
        *,
        collision_exclude: Sequence[tuple[str, str]] = (),
        name: str = "hand",
        package_dirs: Sequence[str | Path] = (),
        effort_limits: float | Mapping[str, float] | None = None,
        solvers: bool = True,
    ) -> None:
        self.name = name
        self.urdf_xml = urdf_text(urdf_xml, f"URDF of hand {name!r}")
        if effort_limits is not None:  # written into the URDF text a plan carries
            self.urdf_xml = with_effort_limits(self.urdf_xml, effort_limits)
        description = parse_urdf(self.urdf_xml, name)
        #: folders the URDF's mesh files are searched in: ``package_dirs``, then ROS_PACKAGE_PATH's
        #: and the description wheels' (:mod:`.packages`); viewers load the visual meshes there too
        self.package_dirs: tuple[str, ...] = search_dirs(package_dirs)
        self.model, self.geom_model = build_models(description, name, self.package_dirs)
        #: SHA-256 of each collision mesh by URI as the URDF gives it (plan files carry it)
        self.mesh_sha256: dict[str, str] = mesh_sha256(self.urdf_xml, self.package_dirs)
        self.data: pin.Data = self.model.createData()
        #: joints that follow another (URDF ``<mimic>``, an MJCF coupling), not in ``q``
        self.mimic_joints: dict[str, MimicJoint] = mimic_joints(self.urdf_xml)

        self.joint_names: tuple[str, ...] = joint_names(self.model)
        self.lower, self.upper = joint_limits(self.model, self.joint_names, name)
        links = {f.name for f in self.model.frames if f.type == pin.FrameType.BODY}
        self.collision_exclude = check_collision_exclude(collision_exclude, links, name)
        self.fingertip_frames: tuple[str, ...] = fingertip_list(fingertip_frames, name)
        self.tip_frame_ids: tuple[int, ...] = ()
        finger_q_index: list[IntArray] = []
        used: set[int] = set()
        for tip in self.fingertip_frames:
            fid = fingertip_frame_id(self.model, tip, name)
            self.tip_frame_ids += (fid,)
            chain = finger_joint_indices(self.model, fid, tip)
            if used.intersection(chain):
                raise ModelError(f"fingertip frame {tip!r} shares joints with another finger")
            used.update(chain)
            finger_q_index.append(np.array(chain, dtype=np.int64))
            check_finger_geometry(self.model, self.geom_model, fid, name)
        self.finger_q_index: tuple[IntArray, ...] = tuple(finger_q_index)
        tips = fingertip_spheres(
            self.model, self.geom_model, self.tip_frame_ids, fingertip_radius, name
        )
        self.fingertip_radius: float = tips.radius
        #: per finger, the fingertip sphere's index in ``geom_model`` (see
        #: :mod:`dexplan.model.hand.fingertips`: the URDF's, or added by dexplan)
        self.tip_geom_ids: tuple[int, ...] = tips.geom_ids
        self.neutral: FloatArray = np.clip(pin.neutral(self.model), self.lower, self.upper)
        self._init_ik(solvers)

    def _init_ik(self, now: bool) -> None:
        """Per-finger IK solvers: closed form where the structure allows it.

        :class:`~dexplan.model.hand.ik.PlanarFingerIK` for planar 3-joint fingers; else the
        closed forms of :mod:`dexplan.model.hand.ik` (4-joint fingers, a grid for the redundancy;
        offset 3-joint and planar 2-joint fingers) or batched DLS from several seeds.

        Built with the hand, or on first use (:attr:`_ik`) for a hand built
        with ``solvers=False``: detecting the closed forms costs 5 ms on the
        paper's hand and 45 ms on the Allegro, and a hand rebuilt from a plan
        file to verify it never solves IK.
        """
        self._reach: list[ReachVoxels | None] = [None] * self.n_fingers
        self._ik_solvers: FingerSolvers | None = None
        if now:
            self._ik_solvers = self._ik

    @property
    def _ik(self) -> FingerSolvers:
        """The fingers' IK solvers and vectorised chains (built on first use)."""
        if self._ik_solvers is None:
            args = (self.finger_q_index, self.tip_frame_ids, self.lower, self.upper, self.neutral)
            self._ik_solvers = FingerSolvers.detect(self.model, *args)
        return self._ik_solvers

    # ------------------------------------------------------------------ loading
    @classmethod
    def from_spec(cls, spec: HandSpec) -> Hand:
        """The hand a scenario's ``[hand]`` table names: builtin, a URDF or an MJCF file."""
        if spec.builtin is not None:
            return cls.builtin(spec.builtin, effort_limits=spec.effort_limits)
        if spec.mjcf is not None:  # exported to the URDF plan files carry (.mjcf)
            urdf_xml, kwargs = mjcf_arguments(spec)
            return cls(urdf_xml, spec.fingertip_frames, spec.fingertip_radius, **kwargs)
        assert spec.urdf is not None
        return cls.from_urdf_file(
            spec.urdf,
            spec.fingertip_frames,
            spec.fingertip_radius,
            collision_exclude=spec.collision_exclude,
            effort_limits=spec.effort_limits,
            package_dirs=[spec.urdf.parent, *spec.package_dirs],
            root_link=spec.root_link,
        )

    @classmethod
    def from_urdf_file(
        cls,
        path: str | Path,
        fingertip_frames: Sequence[str],
        fingertip_radius: float | None = None,
        root_link: str | None = None,
        **kwargs: object,
    ) -> Hand:
        """Load a hand from a URDF file (a robot's: below ``root_link``); meshes resolve beside it.

        Raises:
            ModelError: the file is missing, unreadable or not UTF-8 text, an
                unknown ``root_link``, or :class:`Hand` rejects it.
        """
        path = Path(path)
        text = read_urdf(path, root_link)
        kwargs.setdefault("name", path.stem)
        kwargs.setdefault("package_dirs", [str(path.parent)])
        # the keyword arguments are Hand's own, checked there
        return cls(text, fingertip_frames, fingertip_radius, **kwargs)  # type: ignore[arg-type]

    @classmethod
    def builtin(
        cls, name: str = "paper", effort_limits: float | Mapping[str, float] | None = None
    ) -> Hand:
        """Return a builtin hand (see :data:`~dexplan.model.hand.builtin.BUILTIN_HANDS`).

        ``"paper"`` (4 x 3 DOF, after the paper) and ``"three_finger"``
        (3 x 3 DOF, capsule links) ship with dexplan; ``"allegro"`` and
        ``"allegro_left"`` (4 x 4 DOF) are read from the installed
        ``example-robot-data`` distribution and mounted palm-up (see
        :data:`~dexplan.model.hand.builtin.ALLEGRO_MOUNT_RPY`).

        Raises:
            InvalidInputError: unknown name.
            DependencyError: an Allegro hand without ``example-robot-data``.
        """
        spec = builtin_hand(name)
        return cls(
            spec.urdf_xml,
            spec.fingertip_frames,
            spec.fingertip_radius,
            collision_exclude=spec.collision_exclude,
            name=spec.name,
            package_dirs=spec.package_dirs,
            effort_limits=effort_limits,
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
        analytic = self._ik.analytic[finger]
        if analytic is not None:
            return analytic.solve(p_target_world, q_hand[self.finger_q_index[finger]])
        split = self._ik.split[finger]
        if split is not None:
            return split.solve_near(p_target_world, q_hand[self.finger_q_index[finger]], approach)
        offset = self._ik.offset[finger]
        if offset is not None:
            q_f, ok = offset.nearest(p_target_world, q_hand[self.finger_q_index[finger]])
            return q_f[0] if ok[0] else None
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
        split = self._ik.split[finger]
        idx = self.finger_q_index[finger]
        if split is None:
            return np.zeros((0, len(idx)))
        return split.options_near(p_target_world, q_hand[idx], approach)

    def reach_voxels(self, finger: int) -> ReachVoxels:
        """Where ``finger``'s fingertip centre can be (built on first use; see :mod:`.reach`)."""
        voxels = self._reach[finger]
        if voxels is None:
            idx, chain = self.finger_q_index[finger], self._ik.chains[finger]
            voxels = self._reach[finger] = (
                ReachVoxels.from_tips(self._reach_tips(finger))
                if chain is None
                else grown_voxels(chain.tips, finger, self.lower[idx], self.upper[idx])
            )
        return voxels

    def _reach_tips(self, finger: int) -> FloatArray:
        """Fingertip centres ``(2000, 3)`` of a finger without a chain, by Pinocchio."""
        idx, q = self.finger_q_index[finger], self.neutral.copy()
        tips = np.empty((2000, 3))
        for k, v in enumerate(reach_samples(finger, self.lower[idx], self.upper[idx])[:2000]):
            q[idx] = v
            tips[k] = self.fingertip_positions(q)[finger]
        return tips

    def has_closed_form_ik(self, finger: int) -> bool:
        """True when ``finger`` is solved in closed form (see :meth:`finger_ik`).

        Redundant 4-joint fingers whose other three joints have a closed form
        count (``dexplan.model.hand.ik.SplitFingerIK``; docs/hands.md, "IK and redundancy").
        """
        return (
            self._ik.analytic[finger] is not None
            or self._ik.split[finger] is not None
            or self._ik.offset[finger] is not None
        )

    def planar_ik(self, finger: int) -> PlanarFingerIK | None:
        """``finger``'s closed-form 3-joint solver, or None (see :mod:`dexplan.model.hand.ik`)."""
        return self._ik.analytic[finger]

    def split_ik(self, finger: int) -> SplitFingerIK | None:
        """``finger``'s closed-form solver with a free joint, or None."""
        return self._ik.split[finger]

    def finger_chain(self, finger: int) -> FingerChain | None:
        """``finger``'s vectorised forward kinematics, or None when not all revolute."""
        return self._ik.chains[finger]

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
            joint; revolute fingers without a closed form every branch their
            seeded solves find (:mod:`dexplan.model.hand.ik.branches`); planar
            closed-form fingers one solution per target (C = 1).
        """
        targets = np.asarray(p_targets_world, dtype=float).reshape(-1, 3)
        split = self._ik.split[finger]
        if split is not None:
            return split.candidates(targets)
        offset = self._ik.offset[finger]
        if offset is not None:
            return offset.branches(targets)
        chain = self._ik.chains[finger]
        if self._ik.analytic[finger] is None and chain is not None:
            idx = self.finger_q_index[finger]
            return branch_solutions(chain, targets, self.lower[idx], self.upper[idx])
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
        analytic = self._ik.analytic[finger]
        if analytic is not None:
            return analytic.solve_batch(targets)
        split = self._ik.split[finger]
        if split is not None:
            return split.solve(targets)
        idx = self.finger_q_index[finger]
        offset = self._ik.offset[finger]
        if offset is not None:  # the branch nearest q_init's (the middle of the ranges)
            near = 0.5 * (self.lower[idx] + self.upper[idx]) if q_init is None else q_init[idx]
            return offset.nearest(targets, near)
        chain = self._ik.chains[finger]
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
        analytic = self._ik.analytic[finger]
        if analytic is not None:
            q_f = analytic.solve(target, q[idx])
            if q_f is not None:
                q[idx] = q_f
                err = float(np.linalg.norm(self._finger_tip(finger, q)[0] - target))
                if err < tol:
                    return IKResult(q_f, True, err, 1)
        offset = self._ik.offset[finger]
        if offset is not None:
            q_all, ok_all = offset.nearest(target, q[idx])
            q[idx] = q_all[0]
            err = float(np.linalg.norm(self._finger_tip(finger, q)[0] - target))
            if ok_all[0] and err < tol:
                return IKResult(q_all[0], True, err, 1)
        split = self._ik.split[finger]
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

        def tip_jacobian(q_f: FloatArray) -> tuple[FloatArray, FloatArray]:
            q[idx] = q_f
            return self._finger_tip(finger, q)

        return finger_dls(
            tip_jacobian,
            target,
            q[idx],
            self.lower[idx],
            self.upper[idx],
            tol=tol,
            max_iter=max_iter,
            restarts=restarts,
        )
