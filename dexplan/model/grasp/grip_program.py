"""The grip-force program: its constraint rows, and the LP and QP that solve it.

Variables ``x_c = (f_c, sigma_c)`` per loaded contact (``sigma_c = tau_c / L``
for soft contacts only), object frame. Constraints ``lo <= A x <= hi``: the
balance of the external wrench, every normal force at least the least
normal force, the cone facets (:mod:`dexplan.model.grasp.cones`) and the
limited joints' torques within their effort limits. :class:`GripForceSolver
<dexplan.model.grasp.grip_forces.GripForceSolver>` builds and solves it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import osqp
import scipy.sparse as sp
from scipy.optimize import linprog

from dexplan.core.typing import FloatArray
from dexplan.model.grasp.cones import friction_cone_facets, soft_finger_facets

__all__ = [
    "BALANCE_TOL",
    "GripProgram",
    "balance_rows",
    "cone_rows",
    "contact_torque_columns",
    "feasible_point",
    "frictionless_rows",
    "grip_program",
    "joint_effort_limits",
    "least_norm",
    "satisfies",
]

#: Largest acceptable balance residual of an OSQP solution (N, N m; relative to the
#: largest force when that exceeds 1 N).
BALANCE_TOL = 1e-6


@dataclass(frozen=True)
class GripProgram:
    """The grip-force problem ``lo <= A x <= hi`` and its row blocks (``m`` variables).

    Attributes:
        A: (rows, m) the stacked rows: ``E``, ``nrm``, ``cone``, then the torque rows.
        lo: (rows,) lower bounds (``-inf`` for none).
        hi: (rows,) upper bounds (``inf`` for none).
        E: (6 + e, m) the balance equalities, then the frictionless ones.
        nrm: (k, m) the normal force of every contact.
        cone: (c, m) the cone facet rows (``cone x <= 0``).
        extra: the frictionless equality rows alone, (m,) each.
    """

    A: FloatArray
    lo: FloatArray
    hi: FloatArray
    E: FloatArray
    nrm: FloatArray
    cone: FloatArray
    extra: list[FloatArray]


def grip_program(
    P: FloatArray,
    N: FloatArray,
    w_ext: FloatArray,
    *,
    mu_eff: float,
    torsion_eff: float | None,
    L: float,
    edges: int,
    min_normal_force: float,
    torque: tuple[FloatArray, FloatArray] | None,
) -> GripProgram:
    """The grip-force problem of ``k`` loaded contacts.

    Args:
        P: (k, 3) contact points, object frame.
        N: (k, 3) inward unit normals, object frame.
        w_ext: (6,) external wrench, object frame (torque about its origin).
        mu_eff: the friction coefficient of the (margin-shrunk) cones.
        torsion_eff: the (margin-shrunk) soft-finger torsion (m), or None for
            point contacts.
        L: the object's characteristic length (m), scaling soft torsion.
        edges: friction-cone edges of the linearization.
        min_normal_force: least normal force per contact (N).
        torque: the joint torque rows ``(T, effort)`` of the limited joints,
            or None for no torque limits.
    """
    soft = torsion_eff is not None
    k = P.shape[0]
    r = 4 if soft else 3
    m = k * r
    cone = cone_rows(N, mu_eff, torsion_eff, L, edges, m)
    G, nrm = balance_rows(P, N, L if soft else None, m)
    extra = frictionless_rows(N, r, m) if mu_eff == 0.0 else []
    E = np.vstack([G, *([np.array(extra)] if extra else [])])
    T, effort = (np.zeros((0, m)), np.zeros(0)) if torque is None else torque
    A = np.vstack([E, nrm, cone, T])
    lo = np.concatenate(
        [
            -w_ext,
            np.zeros(len(extra)),
            np.full(k, min_normal_force),
            np.full(len(cone), -np.inf),
            -effort,
        ]
    )
    hi = np.concatenate(
        [-w_ext, np.zeros(len(extra)), np.full(k, np.inf), np.zeros(len(cone)), effort]
    )
    return GripProgram(A, lo, hi, E, nrm, cone, extra)


def cone_rows(
    N: FloatArray, mu_eff: float, torsion_eff: float | None, L: float, edges: int, m: int
) -> FloatArray:
    """Facet rows ``A x <= 0`` of every contact's shrunk cone over the ``m`` QP variables.

    Args:
        N: (k, 3) inward unit normals, object frame.
        mu_eff: the shrunk friction coefficient ``mu (1 - margin)``.
        torsion_eff: the shrunk soft-finger torsion (m), None for point contacts.
        L: the torque scale of soft contacts (m).
        edges: friction-cone edges of the linearization.
        m: number of QP variables (``k * r``, ``r`` = 4 soft, 3 point).

    Returns:
        (rows, m) the stacked facet rows.
    """
    soft = torsion_eff is not None
    k = N.shape[0]
    r = 4 if soft else 3
    if torsion_eff is not None:
        facets = soft_finger_facets(N, mu_eff, torsion_eff, edges, torque_scale=L)
    else:
        facets = friction_cone_facets(N, mu_eff, edges)
    rows = []
    for c in range(k):
        fc = facets[c]
        if soft and mu_eff == 0.0:  # rows on (f_n, sigma): f_t = 0 by equalities below
            blk = np.zeros((fc.shape[0], m))
            blk[:, c * r : c * r + 3] = fc[:, :1] * N[c][None, :]
            blk[:, c * r + 3] = fc[:, 1]
        else:
            blk = np.zeros((fc.shape[0], m))
            blk[:, c * r : c * r + fc.shape[1]] = fc
        rows.append(blk)
    return np.vstack(rows)


def joint_effort_limits(model: Any) -> FloatArray:
    """The URDF's joint effort (torque) limits, ``(nq,)`` N m; NaN where none is set.

    Args:
        model: the hand's Pinocchio model (``model.effortLimit``, (nv,)).
    """
    e = np.array(model.effortLimit, dtype=float).reshape(-1)
    e[~(np.isfinite(e) & (e > 0))] = np.nan
    return e


def contact_torque_columns(
    J: FloatArray, d: FloatArray, R: FloatArray, n_in: FloatArray, L: float | None
) -> FloatArray:
    """Joint torques per unit of one contact's grip-force variables.

    ``tau = J^T [f_w; d x f_w + tau_n R n]`` with ``f_w = R f`` the force in the
    world frame: the columns map the contact's object-frame variables
    ``(f, sigma)`` (``sigma = tau_n / L``, soft contacts only) to joint torques.

    Args:
        J: (6, nv) the fingertip frame's ``LOCAL_WORLD_ALIGNED`` Jacobian.
        d: (3,) tip centre to contact point, world frame (m).
        R: (3, 3) object orientation (object to world).
        n_in: (3,) inward unit normal, object frame.
        L: the torsion scale of soft contacts, or None for point contacts.

    Returns:
        (nv, 3) for point contacts, (nv, 4) for soft ones.
    """
    S = np.array([[0, -d[2], d[1]], [d[2], 0, -d[0]], [-d[1], d[0], 0]])
    cols = J.T @ np.vstack([R, S @ R])
    if L is None:
        return cols
    return np.hstack([cols, (J.T @ np.concatenate([np.zeros(3), R @ n_in]) * L)[:, None]])


def balance_rows(
    P: FloatArray, N: FloatArray, L: float | None, m: int
) -> tuple[FloatArray, FloatArray]:
    """Balance and normal-force rows of the grip-force QP (object frame).

    Balance: ``sum f_c + F = 0`` and ``sum p_c x f_c + L sigma_c n_c + T = 0``.

    Args:
        P: (k, 3) contact points, object frame.
        N: (k, 3) inward unit normals, object frame.
        L: the torsion scale of soft contacts (variables ``(f_c, sigma_c)``),
            or None for point contacts (variables ``f_c``).
        m: number of QP variables.

    Returns:
        ``(G, nrm)``: (6, m) the wrench of the variables and (k, m) their normal forces.
    """
    k = P.shape[0]
    r = 3 if L is None else 4
    G = np.zeros((6, m))
    nrm = np.zeros((k, m))
    for c in range(k):
        G[:3, c * r : c * r + 3] = np.eye(3)
        px, py, pz = P[c]
        G[3:, c * r : c * r + 3] = np.array([[0, -pz, py], [pz, 0, -px], [-py, px, 0]])
        if L is not None:
            G[3:, c * r + 3] = L * N[c]
        nrm[c, c * r : c * r + 3] = N[c]
    return G, nrm


def frictionless_rows(N: FloatArray, r: int, m: int) -> list[FloatArray]:
    """Equality rows ``t . f_c = 0`` on both tangents of every contact (no friction at all).

    Args:
        N: (k, 3) inward unit normals.
        r: QP variables per contact.
        m: number of QP variables.
    """
    extra = []
    for c in range(N.shape[0]):
        for t in np.linalg.svd(N[c][None, :])[2][1:]:
            row = np.zeros(m)
            row[c * r : c * r + 3] = t
            extra.append(row)
    return extra


def least_norm(A: FloatArray, lo: FloatArray, hi: FloatArray) -> FloatArray | None:
    """The least-norm ``x`` with ``lo <= A x <= hi``; None if there is none.

    Feasibility is decided first by a linear program (HiGHS through SciPy,
    minimising ``max |x_i|``), which is exact where OSQP is not: on badly
    conditioned grasps that need forces many times the object's weight (three
    contacts of small force-closure quality), OSQP stops with "primal
    infeasible inaccurate" on feasible problems. OSQP then minimises ``|x|^2``
    from the LP's point, its infeasibility detection off (the problem is
    known to be feasible); if it has not converged the LP's point is used.

    Args:
        A: (rows, m) the constraint matrix.
        lo: (rows,) lower bounds (``-inf`` for none).
        hi: (rows,) upper bounds (``inf`` for none).
    """
    x_lp = feasible_point(A, lo, hi)
    if x_lp is None:
        return None
    m = A.shape[1]
    prob = osqp.OSQP()
    prob.setup(
        sp.identity(m, format="csc"),
        np.zeros(m),
        sp.csc_matrix(A),
        lo,
        hi,
        verbose=False,
        eps_abs=1e-8,
        eps_rel=1e-8,
        eps_prim_inf=1e-15,
        eps_dual_inf=1e-15,
        max_iter=50000,
        polishing=True,
    )
    prob.warm_start(x=x_lp)
    res = prob.solve(raise_error=False)
    x = res.x
    if x is None or not np.all(np.isfinite(x)) or not satisfies(A, lo, hi, x):
        return x_lp
    return x


def feasible_point(A: FloatArray, lo: FloatArray, hi: FloatArray) -> FloatArray | None:
    """A point with ``lo <= A x <= hi`` of least ``max |x_i|``, or None if there is none.

    A linear program (HiGHS through SciPy): exact where OSQP's infeasibility
    detection is not (see :func:`least_norm`).
    """
    m = A.shape[1]
    up, down = np.isfinite(hi), np.isfinite(lo)
    # variables (x, t): minimise t = max |x_i| (a bounded, small point to start from)
    eye = np.eye(m)
    ones = np.ones((m, 1))
    lp = linprog(
        np.r_[np.zeros(m), 1.0],
        A_ub=np.vstack(
            [
                np.hstack([A[up], np.zeros((int(up.sum()), 1))]),
                np.hstack([-A[down], np.zeros((int(down.sum()), 1))]),
                np.hstack([eye, -ones]),
                np.hstack([-eye, -ones]),
            ]
        ),
        b_ub=np.concatenate([hi[up], -lo[down], np.zeros(2 * m)]),
        bounds=(None, None),
        method="highs",
    )
    if lp.status != 0 or lp.x is None:
        return None
    return np.asarray(lp.x[:m], dtype=float)


def satisfies(A: FloatArray, lo: FloatArray, hi: FloatArray, x: FloatArray) -> bool:
    """``lo <= A x <= hi`` to the balance tolerance, relative to the forces' size."""
    ax = A @ x
    tol = BALANCE_TOL * max(1.0, float(np.max(np.abs(x))))
    return bool(np.all(ax >= lo - tol) and np.all(ax <= hi + tol))
