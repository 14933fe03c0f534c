"""The verifier of plan files: every rule of a ``dexplan-plan/2`` (or ``/1``) document.

:func:`verify_plan` re-checks a plan from the file alone. It rebuilds the
models (Pinocchio hand, object, coal world, force closure) but shares no code
path with the planner, so a planner bug cannot hide itself: every rule is
checked again and each violation names the segment, the waypoint and the rule.

The rules are named once, in :data:`~dexplan.planfile.rules.RULES` (the
table of ``docs/plan_format.md``); the checker has one method per rule family (waypoint
pose and joints, fingertip contacts, collisions, force closure, steps,
transfer, regrasp, continuity, start and goal) and records a violation only
under a name of that table.

The format itself (reading, writing, building) is
:mod:`dexplan.planfile.document`, the models of a document
:mod:`dexplan.planfile.models`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dexplan.core.errors import DexplanError, PlanFileError, one_line
from dexplan.core.pose import inverse_transform_points, length, quat_angle
from dexplan.core.segments import Segment, Waypoint
from dexplan.core.typing import FloatArray
from dexplan.model.collision import CollisionReport
from dexplan.model.grasp import ForceClosure, Solver, exact_force_closure_batch
from dexplan.model.grasp.holds import HoldChecker
from dexplan.model.grasp.rolling import ContactMotion
from dexplan.model.objects.fingertip import TIP_DISTANCE_TOL, fingertip_contact
from dexplan.planfile.document import segments_from_dicts
from dexplan.planfile.models import PlanModels, cached_plan_hand, models_from_document
from dexplan.planfile.report import VerifyReport, Violation
from dexplan.planfile.rules import (
    CONTACT_DRIFT_TOL,
    FC_PASS,
    GOAL_ANGLE_TOL,
    GOAL_POSITION_TOL,
    MAX_STEP_M,
    MAX_STEP_RAD,
    NO_SLIP_ABS,
    NO_SLIP_REL,
    PENETRATION_TOL,
    RULES,
    STILL_TOL,
)
from dexplan.planfile.schema import validate_plan
from dexplan.planfile.tip_contacts import contact_path_lengths, tip_sides

__all__ = [
    "RULES",
    "TIP_DISTANCE_TOL",
    "VerifyReport",
    "Violation",
    "fingertip_contact",
    "verify_plan",
]


# ---------------------------------------------------------------- checking
#: The verifier's own force-closure solver: every pair it solves, exactly
#: (Lawson-Hanson), so a plan's weakest hold does not depend on what the
#: process solved before (an OSQP solution moves with its warm state, to its
#: tolerance of 1e-7).
_EXACT = ForceClosure(solver=Solver.NNLS)


@dataclass(frozen=True)
class _Reading:
    """A waypoint's contacts, read against its pose (:meth:`_Checker.read`).

    Attributes:
        rows: per finger in contact, ``(finger, fingertip distance error,
            contact distance to the surface, stated-to-fingertip gap)`` (m).
        fingers: the fingers in contact, in order.
        P: (k, 3) their contact points, object frame.
        N: (k, 3) their inward normals, object frame.
    """

    rows: list[tuple[int, float, float, float]]
    fingers: tuple[int, ...]
    P: FloatArray
    N: FloatArray


class _Checker:
    """Checks every rule against the models of one plan, one method per rule family."""

    def __init__(self, m: PlanModels) -> None:
        self.hand, self.obj, self.world = m.hand, m.obj, m.world
        self.mu, self.edges = m.mu, m.friction_edges
        self.contact_model, self.torsion = m.contact_model, m.torsion
        self.rolling = m.contact_motion == ContactMotion.ROLLING
        self.n = self.hand.n_fingers
        self.violations: list[Violation] = []
        self._fc_memo: dict[tuple[bytes, bool], str] = {}
        self.holds = HoldChecker(
            self.hand,
            self.obj,
            self.mu,
            self.edges,
            self.contact_model,
            self.torsion,
            m.forces,
            shift_m=m.hold_shift,
        )
        self.weakest_hold: float | None = None
        self.worst_torque_ratio: float | None = None
        self._surface_memo: dict[bytes, tuple[float, tuple[FloatArray, FloatArray]]] = {}
        self._tips: tuple[Segment, list[list[FloatArray]]] | None = None
        self._collision_memo: dict[bytes, CollisionReport] = {}

    def add(self, seg: int, wp: int, rule: str, message: str) -> None:
        """Record a violation of ``rule`` (a name of :data:`RULES`)."""
        if rule not in RULES:
            raise ValueError(f"unknown verification rule {rule!r}")
        self.violations.append(Violation(seg, wp, rule, message))

    # -- per segment ---------------------------------------------------------
    def segment(self, si: int, seg: Segment, previous: Segment | None) -> None:
        """Every rule of one segment: its waypoints, steps, kind and continuity."""
        transfer = seg.kind == "transfer"
        reads = [self.read(w) for w in seg.waypoints]
        self._judge(reads, subgrasps=transfer)
        for wi, (w, rd) in enumerate(zip(seg.waypoints, reads, strict=True)):
            self.waypoint(si, wi, w, rd, subgrasps=transfer)
        self.holds_of(si, seg, reads)
        self.steps(si, seg)
        if seg.kind == "transfer":
            self.transfer(si, seg)
        else:
            self.regrasp(si, seg)
        if previous is not None:
            self.continuity(si, previous, seg)

    # -- per waypoint --------------------------------------------------------
    def waypoint(
        self, si: int, wi: int, w: Waypoint, rd: _Reading | None, *, subgrasps: bool
    ) -> None:
        """Every rule of one waypoint (``subgrasps``: of a transfer; ``rd``: its reading)."""
        if not self.pose_and_joints(si, wi, w) or rd is None:
            return
        self.contacts(si, wi, rd)
        self.collisions(si, wi, w)
        self.force_closure(si, wi, rd, subgrasps=subgrasps)

    def pose_and_joints(self, si: int, wi: int, w: Waypoint) -> bool:
        """``object_pose`` and ``joint_limits``; False when the pose is unusable."""
        hand = self.hand
        pose, q = w.object_pose_xyzquat, w.q  # sizes and finiteness: validate_plan
        if abs(length(pose[3:]) - 1.0) > 1e-6:
            self.add(si, wi, "object_pose", "quaternion is not unit length")
            return False
        if not hand.within_limits(q, 1e-9):
            bad = [
                hand.joint_names[j]
                for j in np.flatnonzero((q < hand.lower - 1e-9) | (q > hand.upper + 1e-9))
            ]
            self.add(si, wi, "joint_limits", f"joints outside limits: {bad}")
        return True

    def read(self, w: Waypoint) -> _Reading | None:
        """A waypoint's contacts read against its pose; None when the pose is unusable.

        Every rule on the contacts (fingertip contacts, force closure, the
        holds' quality) reads them once, here: the fingertip sphere pushes
        where :func:`fingertip_contact` says.
        """
        if abs(length(w.object_pose_xyzquat[3:]) - 1.0) > 1e-6:
            return None  # pose_and_joints reports it
        obj, r = self.obj, self.hand.fingertip_radius
        tips = inverse_transform_points(w.object_pose_xyzquat, self.hand.fingertip_positions(w.q))
        rows, fingers, pts, nrm = [], [], [], []
        for i, c in enumerate(w.contacts):
            if c is None:
                continue
            d_tip = float(obj.signed_distance(tips[i])) - r
            d_c, stated = self._surface(c)
            p_s, n_s, gap = fingertip_contact(obj, c, tips[i], r, stated)
            rows.append((i, d_tip, d_c, gap))
            fingers.append(i)
            pts.append(np.asarray(p_s).reshape(3))
            nrm.append(-np.asarray(n_s).reshape(3))
        shape = (len(pts), 3)
        return _Reading(
            rows, tuple(fingers), np.array(pts).reshape(shape), np.array(nrm).reshape(shape)
        )

    def contacts(self, si: int, wi: int, rd: _Reading) -> None:
        """The fingertip-contact rules of a waypoint's reading."""
        for i, d_tip, d_c, gap in rd.rows:
            if abs(d_tip) > TIP_DISTANCE_TOL:
                msg = f"finger {i}: fingertip is {d_tip * 1e3:+.2f} mm from the surface"
                self.add(si, wi, "fingertip_distance", msg)
            if abs(d_c) > TIP_DISTANCE_TOL:
                msg = f"finger {i}: contact is {d_c * 1e3:+.2f} mm off the surface"
                self.add(si, wi, "contact_on_surface", msg)
            if gap > TIP_DISTANCE_TOL:
                msg = f"finger {i}: stated contact is {gap * 1e3:.2f} mm from the fingertip's"
                self.add(si, wi, "contact_matches_fingertip", msg)

    def _surface(self, c: FloatArray) -> tuple[float, tuple[FloatArray, FloatArray]]:
        """Signed distance and closest surface point of a stated contact, by exact value.

        A contact is held over a whole transfer: its surface figures are
        computed once (the same numbers give the same answers).
        """
        key = np.asarray(c, dtype=float).tobytes()
        out = self._surface_memo.get(key)
        if out is None:
            p_s, n_s = self.obj.closest_point(c)
            out = self._surface_memo[key] = (float(self.obj.signed_distance(c)), (p_s, n_s))
        return out

    def collisions(self, si: int, wi: int, w: Waypoint) -> None:
        """``collision`` and ``penetration``."""
        mask = w.contact_mask()
        key = w.q.tobytes() + w.object_pose_xyzquat.tobytes() + bytes(mask)
        rep = self._collision_memo.get(key)
        if rep is None:  # a regrasp's still hand, a segment's shared end: the same answer
            rep = self.world.check(w.q, w.object_pose_xyzquat, mask, first_only=True)
            self._collision_memo[key] = rep
        if rep.pair is not None:
            self.add(si, wi, "collision", f"{rep.pair[0]} touches {rep.pair[1]}")
        if rep.max_penetration > PENETRATION_TOL:
            msg = f"a fingertip sinks {rep.max_penetration * 1e3:.2f} mm into the object"
            self.add(si, wi, "penetration", msg)

    def force_closure(self, si: int, wi: int, rd: _Reading, *, subgrasps: bool) -> None:
        """``force_closure`` and (``subgrasps``) ``subgrasp_force_closure``."""
        k = len(rd.fingers)
        if k < 2:
            self.add(si, wi, "force_closure", f"only {k} finger(s) hold the object")
            return
        key = rd.P.tobytes() + rd.N.tobytes()
        fc = self._fc_memo[key, False]
        if fc not in FC_PASS:
            self.add(si, wi, "force_closure", f"holding grasp is {self._fc_text(fc)}")
        elif subgrasps and (sub := self._fc_memo[key, True]) not in FC_PASS:
            msg = f"some {k - 1}-finger subgrasp is {self._fc_text(sub)}"
            self.add(si, wi, "subgrasp_force_closure", msg)

    def _judge(self, reads: Sequence[_Reading | None], *, subgrasps: bool) -> None:
        """The force-closure verdicts of a segment's waypoints, into ``_fc_memo``.

        The rules are signs, judged under the plan's contact model against the
        exact sets (round Coulomb cone, elliptic soft-finger set): the file's
        own linearization, then dense inner and outer polytopes. The same
        contacts give the same answer, so answers are kept by exact contact
        values (along a regrasp the holding contacts repeat); the others are
        judged together, the waypoints of one contact count at once.
        """
        todo: dict[tuple[int, bool], dict[bytes, _Reading]] = {}
        for rd in reads:
            if rd is None or len(rd.fingers) < 2:
                continue
            key = rd.P.tobytes() + rd.N.tobytes()
            for sub in (False, True) if subgrasps else (False,):
                if (key, sub) not in self._fc_memo:
                    todo.setdefault((len(rd.fingers), sub), {})[key] = rd
        for (_, sub), group in todo.items():
            verdicts = exact_force_closure_batch(
                np.array([rd.P for rd in group.values()]),
                np.array([rd.N for rd in group.values()]),
                self.mu,
                edges=self.edges,
                torque_scale=self.obj.characteristic_length,
                subgrasps=sub,
                contact_model=self.contact_model,
                torsion=self.torsion,
            )
            for key, verdict in zip(group, verdicts, strict=True):
                self._fc_memo[key, sub] = str(verdict)

    def _fc_text(self, verdict: str) -> str:
        if self.contact_model == "soft":
            where = f"soft contacts, mu {self.mu:g}, torsion {self.torsion:g} m"
        else:
            where = f"point contacts, mu {self.mu:g}"
        if verdict == "undecided":
            return (
                f"not provably force closure ({where}): within the gap between the "
                "dense inner and outer polytopes of the exact contact sets"
            )
        return f"not force closure ({where})"

    def holds_of(self, si: int, seg: Segment, reads: Sequence[_Reading | None]) -> None:
        """``holds`` of one segment, and the figures of its holds kept.

        A regrasp's hold (the n-1 holding fingers; they and the object stay
        still) is checked with every contact moved ``hold_shift``. A
        transfer's waypoints, where every finger holds, are checked at their
        stated contacts (:meth:`HoldChecker.stated_ratios`). The plan's
        own linearization is used: its edges lie on the round cone, so a hold
        of it is a hold of the round cone.
        """
        wps = [
            (wi, w, rd)
            for wi, (w, rd) in enumerate(zip(seg.waypoints, reads, strict=True))
            if rd is not None and len(rd.fingers) >= 2  # else force_closure reports it
        ]
        if seg.kind == "transfer":
            holds = [(w.q, w.object_pose_xyzquat, list(w.contacts)) for _, w, _ in wps]
            stated = self.holds.stated_ratios(holds, [rd.N for _, _, rd in wps])
            ratios = [(wi, rd, r) for (wi, _, rd), r in zip(wps, stated, strict=True)]
            free = None
        else:
            free = seg.finger
            inner = [(wi, w, rd) for wi, w, rd in wps if 0 < wi < len(seg.waypoints) - 1]
            ratios = [
                (wi, rd, self.holds.ratio(w.q, w.object_pose_xyzquat, self._held(w, free)))
                for wi, w, rd in inner
                if sum(c is not None for c in self._held(w, free)) >= 2
            ]
        for wi, _, ratio in ratios:
            self._keep_hold(si, wi, free, ratio)
        self._weakest([rd for _, rd, _ in ratios], free)

    @staticmethod
    def _held(w: Waypoint, free: int | None) -> list[Any]:
        return [None if i == free else c for i, c in enumerate(w.contacts)]

    def _keep_hold(self, si: int, wi: int, free: int | None, ratio: float) -> None:
        """Record a hold's torque ratio and its violation, if any."""
        worst = self.worst_torque_ratio
        self.worst_torque_ratio = ratio if worst is None else max(worst, ratio)
        if not ratio <= 1.0:
            need = "cannot balance it at all" if ratio == math.inf else f"need {ratio:.2f} x"
            moved = f", contacts moved {self.holds.shift_m * 1e3:g} mm" if free is not None else ""
            msg = (
                f"the holding contacts {need} the joints' effort limits for the object's "
                f"weight ({self.holds.forces.mass:g} kg{moved})"
            )
            self.add(si, wi, "holds", msg)

    def _weakest(self, reads: Sequence[_Reading], free: int | None) -> None:
        """Fold a segment's holds into the weakest hold's force-closure quality.

        A transfer's hold is every contact, judged by its weakest (n-1)-finger
        subgrasp; a regrasp's is the fingers but ``free``, judged whole. Only
        the least quality is reported, so the holds are bounded together and
        only the pairs that can still be below the least value found are
        solved (:meth:`ForceClosure.weakest_quality`).
        """
        groups: dict[int, dict[bytes, tuple[FloatArray, FloatArray]]] = {}
        for rd in reads:
            keep = [j for j, i in enumerate(rd.fingers) if i != free]
            P, N = rd.P[keep], rd.N[keep]
            groups.setdefault(len(keep), {})[P.tobytes() + N.tobytes()] = (P, N)
        for grasps in groups.values():
            q = _EXACT.weakest_quality(
                np.array([P for P, _ in grasps.values()]),
                np.array([N for _, N in grasps.values()]),
                self.mu,
                edges=self.edges,
                torque_scale=self.obj.characteristic_length,
                subgrasps=free is None,
                contact_model=self.contact_model,
                torsion=self.torsion,
                cap=math.inf if self.weakest_hold is None else self.weakest_hold,
            )
            self.weakest_hold = float(q)

    # -- steps, transfer, regrasp, continuity --------------------------------
    def steps(self, si: int, seg: Segment) -> None:
        """``step``: object and joint change between consecutive waypoints."""
        for wi in range(1, len(seg.waypoints)):
            a, b = seg.waypoints[wi - 1], seg.waypoints[wi]
            dp = length(b.object_pose_xyzquat[:3] - a.object_pose_xyzquat[:3])
            da = quat_angle(a.object_pose_xyzquat[3:], b.object_pose_xyzquat[3:])
            dq = float(np.max(np.abs(b.q - a.q))) if a.q.size else 0.0
            if dp > MAX_STEP_M + 1e-12:
                self.add(
                    si, wi, "step", f"object moves {dp * 1e3:.2f} mm from the previous waypoint"
                )
            if da > MAX_STEP_RAD + 1e-12:
                self.add(si, wi, "step", f"object turns {da:.4f} rad from the previous waypoint")
            if dq > MAX_STEP_RAD + 1e-12:
                self.add(si, wi, "step", f"a joint moves {dq:.4f} rad from the previous waypoint")

    def transfer(self, si: int, seg: Segment) -> None:
        """``transfer_contacts``, and ``transfer_contact_drift`` or ``transfer_no_slip``."""
        first = seg.waypoints[0]
        if any(w.contact_mask() != first.contact_mask() for w in seg.waypoints):
            for wi, w in enumerate(seg.waypoints):
                if w.contact_mask() != first.contact_mask():
                    self.add(si, wi, "transfer_contacts", "the set of contact fingers changes")
            return
        if self.rolling:
            self.no_slip(si, seg)
            return
        for wi, w in enumerate(seg.waypoints):
            for i, (c, c0) in enumerate(zip(w.contacts, first.contacts, strict=True)):
                if c is None:
                    continue
                drift = float(np.linalg.norm(np.asarray(c) - np.asarray(c0)))
                if drift > CONTACT_DRIFT_TOL:
                    msg = f"finger {i}: contact drifts {drift * 1e3:.2f} mm in the object frame"
                    self.add(si, wi, "transfer_contact_drift", msg)

    def no_slip(self, si: int, seg: Segment) -> None:
        """``transfer_no_slip``: per finger, equal path lengths on the tip and on the object."""
        for i, on_tip, on_obj in contact_path_lengths(self.hand, seg, self.tip_sides(seg)):
            if abs(on_tip - on_obj) > NO_SLIP_REL * on_obj + NO_SLIP_ABS:
                msg = (
                    f"finger {i}: the contact travels {on_tip * 1e3:.2f} mm on the fingertip "
                    f"but {on_obj * 1e3:.2f} mm on the object (it slips)"
                )
                self.add(si, len(seg.waypoints) - 1, "transfer_no_slip", msg)

    def tip_sides(self, seg: Segment) -> list[list[FloatArray]]:
        """Each waypoint's contacts in their tip frames (:func:`tip_sides`), read once a segment.

        The tip-contact rule and a rolling transfer's no-slip rule both read them.
        """
        if self._tips is None or self._tips[0] is not seg:
            self._tips = (seg, [tip_sides(self.hand, w) for w in seg.waypoints])
        return self._tips[1]

    def tip_contact(self, si: int, seg: Segment, stated: Sequence[Sequence[Any]]) -> None:
        """``tip_contact``: the file's ``tip_contacts`` of a segment against the pose's."""
        r = self.hand.fingertip_radius
        for wi, (row, sides) in enumerate(zip(stated, self.tip_sides(seg), strict=True)):
            for i, (t, t_pose) in enumerate(zip(row, sides, strict=True)):
                if t is None:
                    continue
                t = np.asarray(t, dtype=float)
                gap = length(t - t_pose)
                off = abs(length(t) - r)
                if gap > TIP_DISTANCE_TOL or off > TIP_DISTANCE_TOL:
                    msg = (
                        f"finger {i}: tip contact is {gap * 1e3:.2f} mm from the contact's "
                        f"place on the tip and {off * 1e3:.2f} mm off the tip sphere"
                    )
                    self.add(si, wi, "tip_contact", msg)

    def regrasp(self, si: int, seg: Segment) -> None:
        """The ``regrasp_*`` rules of a regrasp of finger ``seg.finger``."""
        assert seg.finger is not None, "validate_plan: a regrasp names its finger"
        f = int(seg.finger)  # in [0, n): validate_plan
        wps = seg.waypoints
        if len(wps) < 3:
            self.add(si, -1, "regrasp_interior", "a regrasp needs at least one interior waypoint")
        for wi, w in enumerate(wps):
            self._regrasp_still(si, wi, w, wps[0], f)
            if 0 < wi < len(wps) - 1:
                self._regrasp_free(si, wi, w, f)
        for wi in (0, len(wps) - 1):
            if wps[wi].contacts[f] is None:
                self.add(si, wi, "regrasp_endpoints", f"finger {f} must be in contact here")

    def _regrasp_still(self, si: int, wi: int, w: Waypoint, first: Waypoint, f: int) -> None:
        """``regrasp_object_still`` and ``regrasp_one_finger`` (finger ``f`` moves)."""
        others = np.ones(self.hand.nq, dtype=bool)
        others[self.hand.finger_q_index[f]] = False
        dpose = float(np.max(np.abs(w.object_pose_xyzquat - first.object_pose_xyzquat)))
        if dpose > STILL_TOL:
            self.add(si, wi, "regrasp_object_still", f"the object moves ({dpose:.3g})")
        moved = np.flatnonzero(np.abs(w.q - first.q)[others] > STILL_TOL)
        if len(moved):
            names = [self.hand.joint_names[j] for j in np.flatnonzero(others)[moved]]
            self.add(si, wi, "regrasp_one_finger", f"joints of other fingers move: {names}")
        for i in range(self.n):
            if i == f:
                continue
            c, c0 = w.contacts[i], first.contacts[i]
            if (c is None) != (c0 is None) or (
                c is not None and np.linalg.norm(np.asarray(c) - np.asarray(c0)) > STILL_TOL
            ):
                self.add(si, wi, "regrasp_one_finger", f"finger {i}'s contact changes")

    def _regrasp_free(self, si: int, wi: int, w: Waypoint, f: int) -> None:
        """``regrasp_free_finger`` and ``regrasp_clearance`` at an interior waypoint."""
        if w.contacts[f] is not None:
            msg = f"finger {f} must be free (contact null) at interior waypoints"
            self.add(si, wi, "regrasp_free_finger", msg)
            return
        d = self.world.finger_object_distance(w.q, w.object_pose_xyzquat, f)
        if d <= 0.0:
            msg = f"free finger {f} touches the object ({d * 1e3:.3f} mm)"
            self.add(si, wi, "regrasp_clearance", msg)

    def continuity(self, si: int, previous: Segment, seg: Segment) -> None:
        """``continuity``: segment ``si`` starts where ``previous`` ends."""
        a, b = previous.waypoints[-1], seg.waypoints[0]
        same = np.allclose(a.q, b.q, rtol=0.0, atol=STILL_TOL) and np.allclose(
            a.object_pose_xyzquat, b.object_pose_xyzquat, rtol=0.0, atol=STILL_TOL
        )
        if not same:
            self.add(si, 0, "continuity", "does not start where the previous segment ends")

    # -- start and goal (finite, tolerances > 0: validate_plan) --------------
    def start(self, start: Mapping[str, Any], segments: Sequence[Segment]) -> None:
        """``start``: the first waypoint is the plan's start."""
        w0 = segments[0].waypoints[0]
        sp = np.asarray(start["object_pose_xyzquat"], dtype=float)
        if not np.allclose(sp, w0.object_pose_xyzquat, rtol=0.0, atol=1e-9):
            self.add(0, 0, "start", "first waypoint is not the start object pose")
        if start.get("q") is not None:
            sq = np.asarray(start["q"], dtype=float)
            if not np.allclose(sq, w0.q, rtol=0.0, atol=1e-9):
                self.add(0, 0, "start", "first waypoint is not the start configuration")

    def goal(self, goal: Mapping[str, Any], segments: Sequence[Segment]) -> None:
        """``goal``: the last waypoint is in the goal region."""
        wl = segments[-1].waypoints[-1]
        gp = np.asarray(goal["object_pose_xyzquat"], dtype=float)
        dp = float(np.linalg.norm(wl.object_pose_xyzquat[:3] - gp[:3]))
        da = quat_angle(wl.object_pose_xyzquat[3:], gp[3:])
        last = (len(segments) - 1, len(segments[-1].waypoints) - 1)
        if not dp <= float(goal.get("position_tol", GOAL_POSITION_TOL)) + 1e-12:
            self.add(*last, "goal", f"object ends {dp * 1e3:.2f} mm from the goal position")
        if not da <= float(goal.get("angle_tol", GOAL_ANGLE_TOL)) + 1e-12:
            msg = f"object ends {math.degrees(da):.2f} deg from the goal orientation"
            self.add(*last, "goal", msg)


def verify_plan(
    doc: Mapping[str, Any], base_dir: str | Path = ".", package_dirs: Sequence[str | Path] = ()
) -> VerifyReport:
    """Check every rule of a ``dexplan-plan/2`` (or ``/1``) document.

    Args:
        doc: the parsed plan (see :func:`dexplan.planfile.document.read_plan`).
        base_dir: folder that relative mesh paths resolve against.
        package_dirs: folders the hand's ``package://`` mesh URIs resolve
            against first (:func:`~dexplan.model.hand.packages.search_dirs`).

    Returns:
        A :class:`VerifyReport` listing every violation.

    Raises:
        PlanFileError: the document is malformed (:func:`validate_plan`: the
            message names the field) or its models cannot be rebuilt (the URDF
            text, a mesh file).
    """
    validate_plan(doc, base_dir)
    try:
        hand = cached_plan_hand(doc["hand"], package_dirs)
        chk = _Checker(models_from_document(doc, Path(base_dir), hand=hand))
    except PlanFileError:
        raise
    except DexplanError as exc:  # a mesh file that changed since validation, coal
        raise PlanFileError(f"cannot rebuild the plan's models: {one_line(str(exc), 200)}") from exc
    segments = segments_from_dicts(doc["segments"])
    if not segments:
        chk.add(-1, -1, "segments", "the plan has no segments")
    for si, seg in enumerate(segments):
        chk.segment(si, seg, segments[si - 1] if si > 0 else None)
        if doc["format"] != "dexplan-plan/1":
            chk.tip_contact(si, seg, [w["tip_contacts"] for w in doc["segments"][si]["waypoints"]])
    if segments:
        chk.start(doc["start"], segments)
        chk.goal(doc["goal"], segments)
    total = sum(len(s.waypoints) for s in segments)
    return VerifyReport(
        tuple(chk.violations),
        total,
        len(segments),
        weakest_hold=chk.weakest_hold,
        worst_torque_ratio=chk.worst_torque_ratio,
    )
