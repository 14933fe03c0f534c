"""Friction cones, contact wrenches and a force-closure quality with provable bounds.

Modules: :mod:`.cones` (contact models, their linearizations and wrenches),
:mod:`.force_closure` (the quality ``Q`` and its solver), :mod:`.subgrasps`
(per-subset data, the exact screen and the certified pair bounds),
:mod:`.least_distance` (the pair programs, exact and OSQP), :mod:`.batch`
(many grasps at once), :mod:`.halfspace` (a cheap necessary condition);
apart from force closure, :mod:`.grip_forces` (the contact forces that hold
the object at one configuration, and the planner's hold check) and
:mod:`.grip_program` (their constraint rows, LP and QP).

Everything here is expressed in the **object frame**: contact points ``p_c`` (metres)
and *inward* unit normals ``n_c`` (pointing into the object), one row per contact.

Friction model
--------------
Point contact with Coulomb friction ``mu``, the cone linearized by ``E = edges`` unit
edge directions ``u_ce = cos(a) n_c + sin(a) (cos(t_e) t1_c + sin(t_e) t2_c)`` with
``tan(a) = mu`` and ``t_e = 2 pi e / E``. The tangent basis ``(t1_c, t2_c)`` is a
deterministic function of ``n_c`` alone (Duff et al. 2017, "Building an orthonormal
basis, revisited"), never of the world frame, so a grasp expressed in the object
frame gives the same pyramid wherever the object is in the world (a basis tied to
the world frame would make the force-closure verdict of a grasp depend on the
object's orientation).

The edge wrenches are ``w_ce = [u_ce, (p_c x u_ce) / L]`` with the torque scale ``L``
(the object's characteristic length; by default the largest ``|p_c|``, or 1 if all
points are at the origin). ``W`` is the ``(k E, 6)`` matrix of these rows.

Quality
-------
Let ``G = [G_1 ... G_k]`` with ``G_c = [I_3; [p_c]_x / L]`` (6 x 3) map the stacked
contact forces ``f = (f_1, ..., f_k)`` to the scaled wrench ``G f``, and ``K_c`` be the
pyramid spanned by the edges of contact ``c``. For a wrench ``d`` define the minimum
Euclidean force needed to produce it::

    phi(d) = min { |f|_2 : G f = d, f_c in K_c for every c }   (+inf if infeasible)

and, over the 12 signed unit axes ``d_j = +-e_i`` of the scaled wrench space::

    Q = min_j 1 / phi(d_j)          (0 when some phi(d_j) is infinite).

``Q > 0`` iff the grasp is force closure (FC) with the linearized cones.

Bounds relative to Ferrari-Canny. Let ``H = conv({0} U {w_ce})``,
``eps = max{r : B(0, r) in H}`` the (L1, ``sum lambda <= 1``) Ferrari-Canny epsilon
of the unit edge wrenches, ``gamma(d) = min{sum lambda : W^T lambda = d, lambda >= 0}``
the gauge of ``H``, and ``q = min_j 1 / gamma(d_j)`` the 12-direction LP quality
(one linear program per direction). With ``k`` contacts::

    eps <= q <= Q <= sqrt(k (1 + mu^2)) q <= sqrt(6 k (1 + mu^2)) eps.

Proof. (i) ``eps <= q <= sqrt(6) eps``: ``B(0, eps)`` in ``H`` gives ``eps d_j`` in ``H``,
so ``1/gamma(d_j) >= eps``; conversely ``H`` is convex and contains ``q d_j`` for all
12 ``j``, hence the cross-polytope of radius ``q``, hence the ball of radius
``q / sqrt(6)``. (ii) Every edge has ``n_c . u_ce = cos(a)``, so any representation
``f_c = sum_e lambda_ce u_ce`` has ``sum_e lambda_ce = n_c . f_c / cos(a)``: ``gamma(d) =
min{sum_c n_c . f_c / cos(a) : G f = d, f_c in K_c}``. The pyramid lies inside the
circular cone of half-angle ``a``, so ``cos(a) |f_c| <= n_c . f_c <= |f_c|`` on it. For
any feasible ``f``: ``|f|_2 <= sum_c |f_c| <= sum_c n_c . f_c / cos(a)``, so
``phi <= gamma``; and ``|f|_2 >= sum_c |f_c| / sqrt(k) >= sum_c n_c . f_c / sqrt(k)
>= cos(a) gamma / sqrt(k)``, so ``phi >= gamma / sqrt(k (1 + mu^2))``. Taking ``1/.``
and the minimum over ``j`` gives ``q <= Q <= sqrt(k (1 + mu^2)) q``. (iii) Adding a
contact adds variables (its force may be zero), so every ``phi(d_j)`` can only
decrease: ``Q`` is monotone under adding contacts (with ``L`` fixed).

Computation
-----------
If ``G`` has full rank 6, ``f = G^+ d + f_int`` with ``f_int`` in the null space of ``G``
(internal forces) and ``G^+ d`` orthogonal to it, so ``phi(d)^2 = |G^+ d|^2 + |z*|^2``
with ``z* = argmin{|z| : B z <= b(d)}``, ``B = A Pi`` (``A`` the block-diagonal outward
facet normals of the pyramids, ``Pi = I - G^+ G`` the projector onto the internal
forces, rows scaled to unit length) and ``b(d) = -A G^+ d``: a least-distance program,
strongly convex (``P = I``), one per (grasp, direction) "pair". The optimum lies in the
range of ``Pi``, so no null-space basis is needed. Per call:

1. Screens, exact sign. Fewer than 3 contacts (7 if ``mu = 0``) or ``rank G < 6``:
   0. Else FC iff some internal force is strictly inside every pyramid, i.e. iff
   ``B z < 0`` has a solution. The candidate ``Pi n`` (every finger pushing along its
   normal, made internal) settles most FC grasps; otherwise the least-distance
   program ``min |z| s.t. B z <= -1``, solved exactly by Lawson-Hanson NNLS, is
   feasible iff the grasp is FC. Either way ``z0`` with ``B z0 <= -1`` is kept.
2. Certified bounds for every pair, vectorized over the subgrasps and the 12
   directions: the relaxation to the most violated halfspace gives ``|z*| >= lo``
   (exact when one constraint is active); the points ``theta z1 + c z0``
   (``z1`` the relaxed optimum, ``theta`` on a 5-point grid, ``c`` the smallest
   feasible) are feasible and give ``|z*| <= hi``. With ``margin``, ``theta = 0``
   alone is tried first; most validity decisions end here.
3. Best-first branch and bound over the pairs: the pair with the smallest certified
   lower bound on its quality is solved, until that bound reaches the best solved
   value (typically 1-4 of the 48 pairs of a 4-contact ``min_subgrasp_quality``).
   ``solver="osqp"`` (default): one cached OSQP problem per ``(rows, n)`` shape, i.e.
   per (contact count, edges), ``P = I``, ``A = B`` with a dense pattern; per pair only
   ``Ax`` (skipped when the subgrasp has not changed) and ``u`` are updated, warm start
   from the feasible point, polish on, ``max_iter = 400``. A pair OSQP leaves
   unsolved (ADMM needs a median of ~170 iterations here and thousands near
   degenerate active sets) is solved exactly by Lawson-Hanson. ``solver="nnls"``
   solves every pair exactly by Lawson-Hanson (the least-distance dual is an NNLS),
   about 3x faster than the OSQP path here. Results are clamped to the certified bounds.

Accuracy: the sign never depends on OSQP or on a tolerance other than the screens'
(``RANK_TOL``, ``MAX_INTERIOR_NORM``); values are exact to ~1e-9 (NNLS, or OSQP with
successful polish) or to OSQP's ``eps`` (1e-7 relative) otherwise.

Measured speed and the comparison with a qhull reference: docs/force_closure.md and
``python scripts/bench_grasp.py``.

Soft contacts
-------------
With ``contact_model="soft"`` a contact also transmits a torsional moment
``tau_c n_c``, ``|tau_c| <= torsion f_n`` (linearized: :mod:`dexplan.model.grasp.cones`).
Its variables are ``x_c = (f_c, sigma_c)``, ``sigma_c = tau_c / L``,
``G_c = [I_3, 0; [p_c]_x / L, n_c]`` (6 x 4), the cone ``K_c`` is the bipyramid of
the ``E`` edges ``(u_ce, 0)`` and ``(n_c, +-t)``, ``t = torsion / L``, and
``phi(d) = min{|x|_2 : G x = d, x_c in K_c}``. Everything above carries over with
``r = 4`` force coordinates per contact (pairs are solved by Lawson-Hanson: OSQP
left those of 2-contact soft subgrasps unsolved at ``max_iter``); the bounds become::

    eps / sqrt(1 + t^2) <= q / sqrt(1 + t^2) <= Q <= sqrt(k (1 + mu^2)) q
                                                 <= sqrt(6 k (1 + mu^2)) eps.

Proof. (i) is unchanged (it only uses the convexity of ``H``). (ii) Every
generator has ``n_c . f = cos(a)`` (edges) or ``1`` (torsional), so any
representation has ``n_c . f_c >= cos(a) sum lambda_c``, hence
``gamma(d) <= sum_c n_c . f_c / cos(a) <= sqrt(1 + mu^2) sum_c |x_c| <=
sqrt(k (1 + mu^2)) |x|_2`` for the optimal ``x`` of ``phi``; and the generators have
norm ``1`` or ``sqrt(1 + t^2)``, so ``phi(d) <= sum_c |x_c| <= sqrt(1 + t^2)
gamma(d)``. Since the point cone is the soft cone's face ``sigma = 0`` with the
same norm there, ``Q(soft) >= Q(point)`` for the same grasp. (iii) holds as is.
Two soft contacts can be force closure (the torque about the line through them
comes from the torsional moments), one never: ``min_contacts``.

The exact sets (the round Coulomb cone, the elliptic soft-finger set
``|f_t|^2 / mu^2 + tau^2 / torsion^2 <= f_n^2``) are judged by
:func:`exact_force_closure` between dense inscribed and circumscribed polytopes.
"""

from dexplan.model.grasp.batch import exact_force_closure_batch, min_subgrasp_quality_batch
from dexplan.model.grasp.cones import (
    CONTACT_MODELS,
    ELLIPSOID_GRID,
    MAX_FRICTION_EDGES,
    MAX_TORSION,
    MIN_FRICTION_EDGES,
    ContactModel,
    check_contact_model,
    contact_wrenches,
    friction_cone_edges,
    friction_cone_facets,
    min_contacts,
    soft_finger_facets,
    tangent_basis,
)
from dexplan.model.grasp.force_closure import (
    DEFAULT,
    DIRECTIONS,
    MAX_FRICTION_EDGES_DENSE,
    VERDICTS,
    ForceClosure,
    ForceClosureStats,
    Solver,
    Verdict,
    exact_force_closure,
    force_closure_quality,
    is_force_closure,
    min_subgrasp_quality,
    weakest_quality,
)
from dexplan.model.grasp.subgrasps import MAX_INTERIOR_NORM, RANK_TOL

__all__ = [
    "CONTACT_MODELS",
    "DEFAULT",
    "DIRECTIONS",
    "ELLIPSOID_GRID",
    "MAX_FRICTION_EDGES",
    "MAX_FRICTION_EDGES_DENSE",
    "MAX_INTERIOR_NORM",
    "MAX_TORSION",
    "MIN_FRICTION_EDGES",
    "RANK_TOL",
    "VERDICTS",
    "ContactModel",
    "ForceClosure",
    "ForceClosureStats",
    "Solver",
    "Verdict",
    "check_contact_model",
    "contact_wrenches",
    "exact_force_closure",
    "exact_force_closure_batch",
    "force_closure_quality",
    "friction_cone_edges",
    "friction_cone_facets",
    "is_force_closure",
    "min_contacts",
    "min_subgrasp_quality",
    "min_subgrasp_quality_batch",
    "soft_finger_facets",
    "tangent_basis",
    "weakest_quality",
]
