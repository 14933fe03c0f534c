"""The force-closure quality ``Q`` and its solver (see :mod:`dexplan.model.grasp`).

The derivation, the bounds and the algorithm are in the package docstring and
docs/force_closure.md; the contact models' cones are in
:mod:`dexplan.model.grasp.cones`.
"""

from __future__ import annotations

import math
from enum import StrEnum
from typing import TypedDict

import numpy as np

from dexplan.core.errors import InvalidInputError
from dexplan.core.typing import FloatArray, as_positive
from dexplan.model.grasp.cones import ContactModel, check_grasp, ellipsoid_facets, min_contacts
from dexplan.model.grasp.least_distance import PairQP
from dexplan.model.grasp.subgrasps import (
    Contacts,
    PairBounds,
    Subsets,
    batch_subsets,
    drop_one,
    scaled_torsion,
    screen_groups,
    stacked_grasps,
)

__all__ = [
    "DEFAULT",
    "DIRECTIONS",
    "ForceClosure",
    "force_closure_quality",
    "is_force_closure",
    "min_subgrasp_quality",
    "weakest_quality",
]

#: The 12 signed unit axes ``+-e_i`` of the scaled wrench space, shape (12, 6).
DIRECTIONS: FloatArray = np.vstack([np.eye(6), -np.eye(6)])


class Solver(StrEnum):
    """How the undecided (grasp, direction) pairs are solved (see :class:`ForceClosure`)."""

    OSQP = "osqp"
    NNLS = "nnls"


class ForceClosureStats(TypedDict):
    """Counters of a :class:`ForceClosure` solver (for benchmarks).

    Attributes:
        evaluations: quality evaluations.
        pairs_solved: (subgrasp, direction) pairs sent to the pair solver.
        osqp_fallbacks: OSQP runs that fell back to Lawson-Hanson.
    """

    evaluations: int
    pairs_solved: int
    osqp_fallbacks: int


class Verdict(StrEnum):
    """Outcomes of :func:`exact_force_closure` (members equal their strings)."""

    FC_LINEAR = "fc_linear"
    FC_DENSE = "fc_dense"
    UNDECIDED = "undecided"
    NOT_FC = "not_fc"


class _Grasp:
    """A checked grasp: the arrays and settings every public method starts from.

    ``pts``/``nrm`` (k, 3) object frame, ``mu``, ``edges``, ``scale`` (the torque
    length L, metres) and ``tau`` (``torsion / L``, None for point contacts).
    """

    __slots__ = ("edges", "k", "model", "mu", "nrm", "pts", "scale", "tau")

    def __init__(
        self,
        points: object,
        normals: object,
        mu: float,
        edges: int,
        torque_scale: float | None,
        contact_model: ContactModel | str,
        torsion: float,
    ):
        self.pts, self.nrm, self.mu, self.edges, self.scale = check_grasp(
            points, normals, mu, edges, torque_scale
        )
        self.tau = scaled_torsion(contact_model, torsion, self.scale)
        self.model = contact_model
        self.k = self.pts.shape[0]

    def too_few(self, subgrasps: bool) -> bool:
        """Whether the grasp (or its subgrasps) has fewer contacts than FC needs."""
        m = self.k - 1 if subgrasps else self.k
        return m < min_contacts(self.mu, self.model)

    def subsets(self, subgrasps: bool) -> np.ndarray:
        """(S, m) contact indices: the grasp itself, or its k (k-1)-subgrasps."""
        return drop_one(self.k) if subgrasps else np.arange(self.k)[None, :]

    def contacts(
        self, mu: float | None = None, edges: int | None = None, rows: FloatArray | None = None
    ) -> Contacts:
        """The per-contact blocks, with the grasp's own ``mu`` and ``edges`` by default."""
        return Contacts(
            self.pts,
            self.nrm,
            self.mu if mu is None else mu,
            self.edges if edges is None else edges,
            self.scale,
            self.tau,
            rows,
        )


class ForceClosure:
    """Force-closure quality with cached OSQP problems (see the module docstring).

    Not thread-safe: the OSQP problems are mutated by every call. Use one instance per
    thread; the module-level functions are the bound methods of a shared default
    instance, :data:`DEFAULT`.

    Args:
        solver: ``"osqp"`` (default) solves the undecided (grasp, direction) pairs with
            OSQP, falling back to exact NNLS if OSQP does not report solved;
            ``"nnls"`` solves them exactly with Lawson-Hanson.
        eps: OSQP absolute and relative tolerance (on the normalized problem).
        max_iter: OSQP iteration cap per pair.
    """

    def __init__(
        self, *, solver: Solver | str = Solver.OSQP, eps: float = 1e-7, max_iter: int = 400
    ):
        if solver not in ("osqp", "nnls"):
            raise InvalidInputError(f"solver must be 'osqp' or 'nnls', got {solver!r}")
        self.solver: Solver = Solver(solver)
        self.eps = as_positive(eps, "eps")
        if isinstance(max_iter, bool) or not isinstance(max_iter, int) or max_iter < 1:
            raise InvalidInputError(f"max_iter must be a positive integer, got {max_iter!r}")
        self.max_iter = max_iter
        self._qps: dict[tuple[int, int], PairQP] = {}
        self._calls = 0
        #: Counters (for benchmarks).
        self.stats: ForceClosureStats = {"evaluations": 0, "pairs_solved": 0, "osqp_fallbacks": 0}

    # -- public API (the module-level functions are DEFAULT's bound methods) --

    def quality(
        self,
        points: object,
        normals: object,
        mu: float,
        *,
        edges: int = 8,
        torque_scale: float | None = None,
        margin: float | None = None,
        solve: bool = True,
        contact_model: ContactModel | str = ContactModel.POINT,
        torsion: float = 0.0,
    ) -> float:
        """Force-closure quality ``Q`` of a grasp; ``> 0`` iff force closure.

        ``Q = min_j 1 / phi(d_j)`` over the 12 signed unit axes of the scaled wrench
        space, ``phi(d)`` the least Euclidean norm of contact forces in the linearized
        cones producing the wrench ``d``; ``0.0`` if not force closure (never negative).
        Bounds (module docstring): ``eps <= Q <= sqrt(6 k (1 + mu^2)) eps`` for the
        Ferrari-Canny epsilon ``eps`` of the unit edge wrenches (L1 hull), and
        ``q <= Q <= sqrt(k (1 + mu^2)) q`` for the 12-direction LP quality ``q``. Soft
        contacts: ``|x_c|^2 = |f_c|^2 + (tau_c / L)^2`` and the lower bounds divide by
        ``sqrt(1 + (torsion / L)^2)``: ``q / sqrt(1 + t^2) <= Q``.

        Args:
            points: (k, 3) contact points, object frame, metres.
            normals: (k, 3) inward contact normals (into the object), object frame.
            mu: friction coefficient, >= 0 (0: frictionless, the cone is the normal).
            edges: pyramid edges per contact, >= 3.
            torque_scale: length dividing torques (metres), e.g. the object's
                characteristic length; default: the largest ``|points|`` (1 if 0).
            margin: decision threshold (validity checks). When given, the result ``r``
                satisfies ``r > margin`` iff ``Q > margin``; ``r`` is exact only when
                that needs it: otherwise a certified lower bound ``margin < r <= Q``
                or a certified upper bound ``Q <= r <= margin``.
            solve: with ``margin``, False never runs the pair solver: undecided grasps
                return their certified lower bound (a "no" may then be a false
                negative; for cheap conservative filtering of many candidates).
            contact_model: ``"point"`` (Coulomb cone, the paper) or ``"soft"`` (plus
                torsional friction about the normal; :mod:`dexplan.model.grasp.cones`).
            torsion: soft-finger torsion coefficient (m), ``|tau_n| <= torsion f_n``,
                in (0, ``MAX_TORSION``] for soft contacts, 0 for point contacts.

        Returns:
            The quality, in (scaled wrench) per (unit contact force).

        Raises:
            InvalidInputError: bad shapes, non-finite values, zero-length normal,
                ``mu < 0``, ``edges < 3``, ``torque_scale <= 0``, ``margin < 0``.
        """
        grasp = _Grasp(points, normals, mu, edges, torque_scale, contact_model, torsion)
        return self._quality(grasp, False, margin, solve)

    def min_subgrasp_quality(
        self,
        points: object,
        normals: object,
        mu: float,
        *,
        edges: int = 8,
        torque_scale: float | None = None,
        margin: float | None = None,
        solve: bool = True,
        contact_model: ContactModel | str = ContactModel.POINT,
        torsion: float = 0.0,
    ) -> float:
        """Minimum quality over the full grasp and each of its (k-1)-contact subgrasps.

        Monotonicity makes the full grasp redundant: a subgrasp's feasible contact
        forces extended by a zero force at the missing contact are feasible for the
        full grasp (same ``torque_scale``), so every ``phi(d_j)`` of the full grasp is
        at most the subgrasp's, i.e. ``Q(full) >= Q(subgrasp)``; the minimum is over
        the k subgrasps only. A subgrasp that fails the exact screens returns 0.0 at
        once.

        The torque scale of every subgrasp is the full grasp's (default: the largest
        ``|points|`` over all k contacts), so this equals
        ``min(force_closure_quality(subgrasp, torque_scale=L) for each subgrasp)``.

        Args:
            points: (k, 3) contact points, object frame, metres.
            normals: (k, 3) inward contact normals, object frame.
            mu: friction coefficient, >= 0.
            edges: pyramid edges per contact, >= 3.
            torque_scale: torque length (metres); see :func:`force_closure_quality`.
            margin: decision threshold; see :func:`force_closure_quality`.
            solve: with ``margin``, False never runs the pair solver (as above).
            contact_model: ``"point"`` or ``"soft"``.
            torsion: soft-finger torsion coefficient (m); 0 for point contacts.

        Returns:
            The minimum quality (0.0 if some subgrasp is not force closure, or k < 4
            with friction, k < 8 without).

        Raises:
            InvalidInputError: as :func:`force_closure_quality`.
        """
        grasp = _Grasp(points, normals, mu, edges, torque_scale, contact_model, torsion)
        return self._quality(grasp, True, margin, solve)

    def is_force_closure(
        self,
        points: object,
        normals: object,
        mu: float,
        *,
        edges: int = 8,
        torque_scale: float | None = None,
        margin: float = 0.0,
        subgrasps: bool = False,
        contact_model: ContactModel | str = ContactModel.POINT,
        torsion: float = 0.0,
    ) -> bool:
        """Whether the grasp's quality exceeds ``margin`` (exact screens only if 0).

        Args:
            points: (k, 3) contact points, object frame, metres.
            normals: (k, 3) inward contact normals, object frame.
            mu: friction coefficient, >= 0.
            edges: pyramid edges per contact, >= 3.
            torque_scale: torque length (metres); see :func:`force_closure_quality`.
            margin: threshold, >= 0.
            subgrasps: test every (k-1)-contact subgrasp instead of the full grasp (the
                planner's validity rule: any finger can let go and the others still
                hold; with ``margin = 0`` the full grasp is then FC too).
            contact_model: ``"point"`` or ``"soft"``.
            torsion: soft-finger torsion coefficient (m); 0 for point contacts.

        Returns:
            ``Q > margin`` (``min_subgrasp_quality > margin`` with ``subgrasps``).
        """
        grasp = _Grasp(points, normals, mu, edges, torque_scale, contact_model, torsion)
        thr = as_positive(margin, "margin", allow_zero=True)
        if grasp.too_few(subgrasps):
            return False
        con, subsets = grasp.contacts(), grasp.subsets(subgrasps)
        if thr == 0.0:
            return self._screen(Subsets(con, subsets)) is not None
        return self._min_quality(con, subsets, thr, True) > thr

    def exact_set_verdict(
        self,
        points: object,
        normals: object,
        mu: float,
        *,
        edges: int = 8,
        torque_scale: float | None = None,
        subgrasps: bool = False,
        contact_model: ContactModel | str = ContactModel.POINT,
        torsion: float = 0.0,
    ) -> Verdict:
        """Force closure under the exact sets: the round cone, the elliptic soft set.

        The exact sets are the round Coulomb cone (point contacts) and the elliptic
        soft-finger set (soft contacts); they are judged by inner and outer polytopes.

        Every linearization used here is either inscribed in the exact set (a "yes"
        for it is a "yes" for the exact set) or circumscribed about it (a "no" for it
        is a "no"): first the model's own ``edges`` linearization (the planner's),
        then a dense inscribed one (64-edge pyramid; the hull of a 48 x 12
        latitude-longitude grid on the ellipsoid), then the dense circumscribed one
        (64-edge pyramid of ``mu / cos(pi / 64)``; the grid hull scaled by
        ``1 / inradius``).

        Args:
            points: (k, 3) contact points, object frame, metres.
            normals: (k, 3) inward contact normals, object frame.
            mu: friction coefficient, >= 0.
            edges: the model's own pyramid edges, >= 3.
            torque_scale: torque length (metres); see :func:`force_closure_quality`.
            subgrasps: judge every (k-1)-contact subgrasp instead of the grasp.
            contact_model: ``"point"`` or ``"soft"``.
            torsion: soft-finger torsion coefficient (m); 0 for point contacts.

        Returns:
            ``"fc_linear"`` (force closure already for the ``edges`` linearization),
            ``"fc_dense"`` (force closure for the dense inscribed polytope),
            ``"undecided"`` (within the gap between the dense inner and outer
            polytopes: 0.12 % of ``mu`` for point contacts, 1.1 % of the set for soft
            ones) or ``"not_fc"`` (not force closure even for the outer polytope, or
            fewer contacts than :func:`~dexplan.model.grasp.cones.min_contacts`).

        Raises:
            InvalidInputError: as :func:`force_closure_quality`.
        """
        grasp = _Grasp(points, normals, mu, edges, torque_scale, contact_model, torsion)
        if grasp.too_few(subgrasps):
            return Verdict.NOT_FC
        subsets = grasp.subsets(subgrasps)

        def sign(con: Contacts) -> bool:
            return self._screen(Subsets(con, subsets)) is not None

        if sign(grasp.contacts()):
            return Verdict.FC_LINEAR
        if grasp.mu == 0.0:  # both sets are exactly their linearizations
            return Verdict.NOT_FC
        dense = MAX_FRICTION_EDGES_DENSE
        if grasp.tau is None:
            if sign(grasp.contacts(edges=dense)):
                return Verdict.FC_DENSE
            outer = grasp.mu / math.cos(math.pi / dense)
            return (
                Verdict.UNDECIDED if sign(grasp.contacts(mu=outer, edges=dense)) else Verdict.NOT_FC
            )
        inner = ellipsoid_facets(grasp.nrm, grasp.mu, grasp.tau, outer=False)
        if sign(grasp.contacts(rows=inner)):
            return Verdict.FC_DENSE
        outer_rows = ellipsoid_facets(grasp.nrm, grasp.mu, grasp.tau, outer=True)
        return Verdict.UNDECIDED if sign(grasp.contacts(rows=outer_rows)) else Verdict.NOT_FC

    def weakest_quality(
        self,
        points: object,
        normals: object,
        mu: float,
        *,
        edges: int = 8,
        torque_scale: float,
        subgrasps: bool = True,
        contact_model: ContactModel | str = ContactModel.POINT,
        torsion: float = 0.0,
        cap: float = math.inf,
    ) -> float:
        """The least exact quality of B grasps of k contacts, in one branch and bound.

        Equals ``min`` over the grasps of :meth:`min_subgrasp_quality`
        (``subgrasps``) or :meth:`quality`, without a margin: the pairs of
        every grasp are bounded at once, and a pair is solved only while its
        lower bound is below the least value found (a grasp whose every bound
        lies above it needs no solve). A plan's weakest hold is such a minimum
        over its waypoints; ``cap``, the least value already known elsewhere
        (e.g. the plan's earlier segments), prunes the pairs above it too.

        Args:
            points: (B, k, 3) contact points, object frame, metres.
            normals: (B, k, 3) inward contact normals, object frame.
            mu: friction coefficient, >= 0.
            edges: pyramid edges per contact, >= 3.
            torque_scale: torque length (metres), the same for every grasp.
            subgrasps: the minimum over each grasp's (k-1)-subgrasps (False:
                the grasp's own quality).
            contact_model: ``"point"`` or ``"soft"``.
            torsion: soft-finger torsion coefficient (m); 0 for point contacts.
            cap: a value already reached: the result is ``min(cap, least quality)``.

        Returns:
            ``min(cap, least quality)``: 0.0 if some grasp is not force closure,
            ``cap`` for B = 0.

        Raises:
            InvalidInputError: shapes other than (B, k, 3), or as :meth:`quality`.
        """
        pts_b, nrm_b = stacked_grasps(points, normals)
        B, k, _ = pts_b.shape
        if B == 0:
            return cap
        flat = (pts_b.reshape(-1, 3), nrm_b.reshape(-1, 3))
        grasp = _Grasp(*flat, mu, edges, torque_scale, contact_model, torsion)
        if (k - 1 if subgrasps else k) < min_contacts(grasp.mu, grasp.model):
            return 0.0
        # each grasp's subsets, as its scalar call takes them
        subsets, per_grasp = batch_subsets(B, k, subgrasps)
        self._calls += 1
        self.stats["evaluations"] += B
        con = grasp.contacts()
        sub = Subsets(con, subsets)
        z0 = self._screen(sub, per_grasp)
        if z0 is None:
            return 0.0
        pairs = PairBounds(sub, z0)
        # a pair whose first lower bound is above the least upper bound (or the
        # cap) cannot be the least: only the subsets with a pair below it are
        # refined and searched (the margin absorbs the bounds' rounding)
        below = min(cap, float(pairs.q_hi.min())) * (1.0 + 1e-9)
        keep = np.flatnonzero((pairs.first_lower() <= below).any(axis=1))
        if not len(keep):
            return cap
        if len(keep) < len(z0):
            pairs = PairBounds(sub.take(keep), z0[keep])
        pairs.refine()
        use_osqp = self.solver == Solver.OSQP and con.r in (1, 3)  # as _min_quality
        return self._branch_and_bound(pairs, None, use_osqp, cap)

    # -- internals ----------------------------------------------------------

    def _quality(self, grasp: _Grasp, subgrasps: bool, margin: float | None, solve: bool) -> float:
        """The quality of the grasp (or the minimum over its subgrasps)."""
        thr = None if margin is None else as_positive(margin, "margin", allow_zero=True)
        if grasp.too_few(subgrasps):
            return 0.0
        return self._min_quality(grasp.contacts(), grasp.subsets(subgrasps), thr, solve)

    @staticmethod
    def _screen(sub: Subsets, group: int | None = None) -> FloatArray | None:
        """Exact FC screen of every subset: interior points ``bh z0 <= -1``, or None.

        :func:`screen_groups` with the subsets in groups of ``group`` (default:
        all in one group): None as soon as one subset is not force closure. A
        group stops at its first failing subset, so the subsets examined, and
        each one's answer, are those of a screen of its grasp alone.
        """
        z0, ok = screen_groups(sub, len(sub.ok) if group is None else group)
        return z0 if ok.all() else None

    def _min_quality(
        self,
        con: Contacts,
        subsets: np.ndarray,
        margin: float | None,
        solve: bool,
    ) -> float:
        """Minimum quality over ``subsets``: screen, certified bounds, branch and bound.

        Args:
            con: the per-contact blocks.
            subsets: (S, m) contact indices of the subsets.
            margin: decision threshold (see :func:`force_closure_quality`), or None.
            solve: False stops at the certified lower bound (with ``margin``).

        Returns:
            The minimum quality, or a certified bound on the far side of ``margin``.
        """
        self._calls += 1
        self.stats["evaluations"] += 1
        sub = Subsets(con, subsets)
        z0 = self._screen(sub)
        if z0 is None:
            return 0.0
        pairs = PairBounds(sub, z0)
        if margin is not None:
            decided = pairs.first_decision(margin)
            if decided is not None:
                return decided
        pairs.refine()
        if margin is not None:
            worst_lo = float(pairs.q_lo.min())
            if worst_lo > margin or not solve:
                return worst_lo
        # Soft contacts: OSQP leaves the pairs of 2-contact soft subgrasps
        # unsolved at max_iter (about 3 ms each before the exact fallback), so
        # their pairs go to Lawson-Hanson directly.
        use_osqp = self.solver == Solver.OSQP and con.r in (1, 3)
        return self._branch_and_bound(pairs, margin, use_osqp)

    def _branch_and_bound(
        self, pairs: PairBounds, margin: float | None, use_osqp: bool, cap: float = math.inf
    ) -> float:
        """Best-first branch and bound over the pairs.

        Pairs are solved in increasing lower bound until the lower bound reaches the
        best exact value (or, with ``margin``, until the decision is certain);
        ``cap`` is a value already reached (the result is at most it).
        """
        flat_lo = pairs.q_lo.ravel()
        order = np.argsort(flat_lo).tolist()
        bounds = flat_lo.tolist()
        exact_l = pairs.exact.ravel().tolist()
        best = cap
        for idx in order:
            bound = bounds[idx]
            if bound >= best:
                break
            if margin is not None and bound > margin:
                return min(best, bound)  # every remaining pair is above the margin
            if exact_l[idx]:
                val = bound
            else:
                s, j = divmod(idx, 12)
                val = self._solve_pair(pairs, s, j, use_osqp)
            best = min(best, val)
            if margin is not None and best <= margin:
                return best
        return best

    def _solve_pair(self, pairs: PairBounds, s: int, j: int, use_osqp: bool) -> float:
        """The quality of pair ``(s, j)``, clamped to its certified bounds.

        Solved by OSQP when ``use_osqp`` (falling back to Lawson-Hanson), else exactly
        by Lawson-Hanson.
        """
        lo_sj = float(pairs.lo[s, j])
        hi_sj = math.sqrt(pairs.hi2[s, j])
        b = pairs.b[s, j]
        z = (
            self._solve_osqp(pairs.sub, s, b, pairs.feasible_point(s, j), lo_sj)
            if use_osqp
            else None
        )
        if z is None:
            z = pairs.sub.ldp_norm(s, b)
        z = hi_sj if z is None else min(max(z, lo_sj), hi_sj)
        self.stats["pairs_solved"] += 1
        return 1.0 / math.sqrt(float(pairs.a2[s, j]) + z * z)

    def _solve_osqp(
        self, sub: Subsets, s: int, b: FloatArray, zf: FloatArray, lo: float
    ) -> float | None:
        """``min |z| s.t. bh_s z <= b`` by OSQP; None if OSQP does not solve it."""
        bh = sub.bh[s]
        rows, n = bh.shape
        qp = self._qps.get((rows, n))
        if qp is None:
            qp = self._qps[(rows, n)] = PairQP(rows, n, self.eps, self.max_iter)
        scale = lo if lo > 0.0 else 1.0
        y0 = np.zeros(rows)
        y0[int(np.argmin(b))] = 1.0
        x, solved = qp.solve((self._calls, s), bh, b / scale, zf / scale, y0)
        if solved:
            z = x * scale
            if np.max(bh @ z - b) <= 1e-7 * max(1.0, lo):
                return math.sqrt(float(z @ z))
        self.stats["osqp_fallbacks"] += 1
        return None


#: Edges of the dense pyramids that judge point contacts against the round cone.
MAX_FRICTION_EDGES_DENSE = 64


#: The instance behind the module-level functions (e.g. ``DEFAULT.solver = "nnls"``).
DEFAULT = ForceClosure()


#: The module-level functions: :data:`DEFAULT`'s bound methods (one signature and
#: docstring each, on :class:`ForceClosure`).
force_closure_quality = DEFAULT.quality
min_subgrasp_quality = DEFAULT.min_subgrasp_quality
weakest_quality = DEFAULT.weakest_quality
is_force_closure = DEFAULT.is_force_closure
exact_force_closure = DEFAULT.exact_set_verdict


#: Outcomes of :func:`exact_force_closure`.
VERDICTS: tuple[Verdict, ...] = tuple(Verdict)
