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
from importlib import resources
from pathlib import Path

import numpy as np
import pinocchio as pin

from dexplan.exceptions import DependencyError, InvalidInputError, ModelError
from dexplan.typing import FloatArray, IntArray, as_positive, as_vector

#: Frames the builtin hands use for their fingertips.
PAPER_HAND_TIPS: tuple[str, ...] = ("f0_tip", "f1_tip", "f2_tip", "f3_tip")
PAPER_HAND_TIP_RADIUS = 0.012
BUILTIN_HANDS: tuple[str, ...] = ("paper", "allegro")


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

    Args:
        urdf_xml: full URDF text; collision geometry must be primitives or
            meshes Pinocchio can load (``package_dirs`` resolves ``package://``).
        fingertip_frames: one frame name per finger, at the fingertip sphere centre.
        fingertip_radius: radius of the fingertip spheres (m).
        collision_exclude: link-name pairs never checked against each other
            (beyond adjacent links, which are always excluded).
        name: human-readable name.
        package_dirs: directories searched for mesh files.

    Raises:
        ModelError: unparsable URDF, unknown frame, multi-DOF joints or fingers
            that share joints.
        InvalidInputError: non-positive fingertip radius.
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
        self.urdf_xml = urdf_xml
        self.name = name
        self.fingertip_radius = as_positive(fingertip_radius, "fingertip_radius")
        self.collision_exclude: tuple[tuple[str, str], ...] = tuple(
            (str(a), str(b)) for a, b in collision_exclude
        )
        try:
            self.model: pin.Model = pin.buildModelFromXML(urdf_xml)
        except (RuntimeError, ValueError) as exc:
            raise ModelError(f"cannot parse URDF for hand {name!r}: {exc}") from exc
        if self.model.nq != self.model.nv:
            raise ModelError(
                f"hand {name!r}: only 1-DOF revolute/prismatic joints are supported "
                f"(nq={self.model.nq}, nv={self.model.nv})"
            )
        if self.model.nq == 0:
            raise ModelError(f"hand {name!r} has no actuated joints")
        try:
            self.geom_model: pin.GeometryModel = pin.buildGeomFromUrdfString(
                self.model, urdf_xml, pin.COLLISION, package_dirs=[str(p) for p in package_dirs]
            )
        except (RuntimeError, ValueError) as exc:
            raise ModelError(f"cannot build collision model of hand {name!r}: {exc}") from exc
        self.data: pin.Data = self.model.createData()

        self.joint_names: tuple[str, ...] = tuple(self.model.names[1:])
        self.lower: FloatArray = np.array(self.model.lowerPositionLimit, dtype=float)
        self.upper: FloatArray = np.array(self.model.upperPositionLimit, dtype=float)
        if not (np.all(np.isfinite(self.lower)) and np.all(np.isfinite(self.upper))):
            raise ModelError(f"hand {name!r}: every joint needs finite position limits")

        frames = [f.name for f in self.model.frames]
        if len(fingertip_frames) < 2:
            raise ModelError(f"hand {name!r} needs at least 2 fingertip frames")
        self.fingertip_frames: tuple[str, ...] = tuple(fingertip_frames)
        self.tip_frame_ids: tuple[int, ...] = ()
        finger_q_index: list[IntArray] = []
        used: set[int] = set()
        for tip in self.fingertip_frames:
            if tip not in frames:
                raise ModelError(
                    f"unknown fingertip frame {tip!r} in hand {name!r}; frames are {frames}"
                )
            fid = self.model.getFrameId(tip)
            self.tip_frame_ids += (fid,)
            chain = []
            jid = self.model.frames[fid].parentJoint
            while jid > 0:
                chain.append(self.model.joints[jid].idx_q)
                jid = self.model.parents[jid]
            chain.sort()
            if not chain:
                raise ModelError(f"fingertip frame {tip!r} is not moved by any joint")
            if used.intersection(chain):
                raise ModelError(f"fingertip frame {tip!r} shares joints with another finger")
            used.update(chain)
            finger_q_index.append(np.array(chain, dtype=np.int64))
        self.finger_q_index: tuple[IntArray, ...] = tuple(finger_q_index)
        self.neutral: FloatArray = np.clip(pin.neutral(self.model), self.lower, self.upper)
        self._analytic_ik: list[_PlanarFingerIK | None] = [
            _PlanarFingerIK.detect(self, i) for i in range(self.n_fingers)
        ]

    # ------------------------------------------------------------------ loading
    @classmethod
    def from_urdf_file(
        cls,
        path: str | Path,
        fingertip_frames: Sequence[str],
        fingertip_radius: float,
        **kwargs: object,
    ) -> Hand:
        """Load a hand from a URDF file; mesh paths resolve relative to its folder."""
        path = Path(path)
        if not path.is_file():
            raise ModelError(f"URDF file not found: {str(path)!r}")
        text = path.read_text()
        kwargs.setdefault("name", path.stem)
        kwargs.setdefault("package_dirs", [str(path.parent)])
        return cls(text, fingertip_frames, fingertip_radius, **kwargs)  # type: ignore[arg-type]

    @classmethod
    def builtin(cls, name: str = "paper") -> Hand:
        """Return a builtin hand: ``"paper"`` (4 x 3 DOF) or ``"allegro"``.

        Raises:
            InvalidInputError: unknown name.
            DependencyError: ``allegro`` without the ``allegro`` extra installed.
        """
        if name == "paper":
            text = resources.files("dexplan").joinpath("data/hands/paper_hand.urdf").read_text()
            return cls(text, PAPER_HAND_TIPS, PAPER_HAND_TIP_RADIUS, name="paper")
        if name == "allegro":
            return _allegro_hand()
        raise InvalidInputError(f"hand.builtin must be one of {list(BUILTIN_HANDS)}, got {name!r}")

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
        self, finger: int, p_target_world: FloatArray, q_hand: FloatArray
    ) -> FloatArray | None:
        """:meth:`finger_ik` for inner loops: no input checks, None on failure.

        Closed-form fingers skip the FK confirmation (the solver was checked
        against FK when the hand was loaded); others run :meth:`finger_ik`.

        Args:
            finger: finger index.
            p_target_world: (3,) fingertip-centre target, world frame.
            q_hand: (nq,) configuration whose finger values break branch ties.

        Returns:
            ``q_finger: (m,)`` within limits, or None.
        """
        analytic = self._analytic_ik[finger]
        if analytic is not None:
            return analytic.solve(p_target_world, q_hand[self.finger_q_index[finger]])
        res = self.finger_ik(finger, p_target_world, q_hand)
        return res.q_finger if res.success else None

    def has_closed_form_ik(self, finger: int) -> bool:
        """True when ``finger`` is solved in closed form (see :meth:`finger_ik`)."""
        return self._analytic_ik[finger] is not None

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
            Closed-form fingers are solved vectorized; others call
            :meth:`finger_ik` per target.
        """
        targets = np.asarray(p_targets_world, dtype=float).reshape(-1, 3)
        analytic = self._analytic_ik[finger]
        if analytic is not None:
            return analytic.solve_batch(targets)
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
        paper hand) are solved in closed form first (checked against
        Pinocchio's FK when the hand is loaded); others, and targets the closed
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


def _allegro_hand() -> Hand:
    """The Allegro right hand from ``example-robot-data`` (``allegro`` extra)."""
    try:
        import example_robot_data as erd
    except ImportError as exc:
        raise DependencyError(
            "hand 'allegro' needs example-robot-data: pip install 'dexplan[allegro]'"
        ) from exc
    models_dir = Path(erd.getModelPath("allegro_hand_description/urdf/allegro_right_hand.urdf"))
    urdf = models_dir / "allegro_hand_description" / "urdf" / "allegro_right_hand.urdf"
    tips = ("link_3.0_tip", "link_7.0_tip", "link_11.0_tip", "link_15.0_tip")
    return Hand.from_urdf_file(urdf, tips, 0.012, name="allegro", package_dirs=[str(models_dir)])
