"""The torque-ratio program of one contact set, solved by HiGHS along a sequence.

A hold's torque ratio (:mod:`dexplan.model.grasp.holds`) is the largest of
its contact sets' ratios, each set's the optimum of a small linear program:
``min t`` over the set's contact forces ``x`` and ``t >= 0`` such that
``lo <= A x <= hi`` (balance, normal forces, cones) and
``|T x| <= t effort`` (the limited joints' torques). The sets share nothing
but ``t`` in a program of all of them together, so its optimum is the
largest of theirs; solved one by one, each program is a dozen variables and
about sixty rows.

Consecutive programs of one question differ little (a transfer's
waypoints; a hold and its shifted contacts), so each starts from the
previous one's optimal basis, and the simplex then needs few iterations. The
value is the program's optimum whatever the start: the optimum ``t`` is
unique, the start only changes the path to it. A :class:`RatioLP` serves one
question (its starts come from that question alone), so the same question
gives the same answer in any process.

HiGHS is reached through SciPy's own build of it (the solver behind
``scipy.optimize.milp``): its Python module is private to SciPy, so it is
imported under a guard and checked on a known program; without it each
program goes to ``milp``, with the same optimum.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.optimize import Bounds, LinearConstraint, milp

from dexplan.core.typing import FloatArray

__all__ = ["RatioLP"]


def _highs_core() -> Any:
    """SciPy's HiGHS module when it is there and answers a known program, else None."""
    try:
        from scipy.optimize._highspy import _core  # private to SciPy: guarded

        h = _new_highs(_core)
        h.passModel(*_program(_core, np.array([[1.0, -1.0]]), np.array([0.5]), np.array([0.5])))
        h.run()
        ok = h.getModelStatus() == _core.HighsModelStatus.kOptimal
        if ok and abs(h.getSolution().col_value[-1] - 0.0) < 1e-12:
            return _core
    except Exception:  # any failure: the public milp
        pass
    return None


def _new_highs(core: Any) -> Any:
    """A silent HiGHS instance without presolve (the programs are tiny)."""
    h = core._Highs()
    h.setOptionValue("output_flag", False)
    h.setOptionValue("presolve", "off")
    return h


def _program(core: Any, M: FloatArray, lo: FloatArray, hi: FloatArray) -> tuple[Any, ...]:
    """``passModel``'s arguments: ``min t`` s.t. ``lo <= M [x; t] <= hi``, ``x`` free, ``t >= 0``.

    The arrays go to HiGHS as they are (a ``HighsLp``'s fields would be
    copied element by element); those that depend only on the shape are made
    once per shape.

    Args:
        core: SciPy's HiGHS module.
        M: (rows, m + 1) dense rows over ``(x, t)``.
        lo: (rows,) lower bounds (``-inf`` for none).
        hi: (rows,) upper bounds (``inf`` for none).
    """
    rows, cols = M.shape
    fixed = _FIXED.get(M.shape)
    if fixed is None:
        inf = core.kHighsInf
        fixed = _FIXED[M.shape] = (
            np.r_[np.zeros(cols - 1), 1.0],  # cost: t
            np.r_[np.full(cols - 1, -inf), 0.0],  # x free, t >= 0
            np.full(cols, inf),
            np.arange(0, rows * cols + 1, cols, dtype=np.int32),  # dense rows
            np.tile(np.arange(cols, dtype=np.int32), rows),
            np.zeros(cols, dtype=np.int32),  # continuous
        )
    cost, col_lo, col_hi, start, index, integrality = fixed
    return (
        cols,
        rows,
        rows * cols,
        int(core.MatrixFormat.kRowwise),
        int(core.ObjSense.kMinimize),
        0.0,
        cost,
        col_lo,
        col_hi,
        np.maximum(lo, -core.kHighsInf),
        np.minimum(hi, core.kHighsInf),
        start,
        index,
        np.ascontiguousarray(M, dtype=float).ravel(),
        integrality,
    )


#: :func:`_program`'s arrays that depend only on the shape, by shape.
_FIXED: dict[tuple[int, int], tuple[FloatArray, ...]] = {}

_CORE = _highs_core()


class RatioLP:
    """The ratio programs of one question, each warm-started from the previous one's basis.

    Make one per question (a hold, the waypoints of a transfer): the starts
    then come from that question alone.
    """

    def __init__(self) -> None:
        self._highs = None if _CORE is None else _new_highs(_CORE)
        self._basis: dict[tuple[int, int], Any] = {}

    def ratio(
        self, A: FloatArray, lo: FloatArray, hi: FloatArray, T: FloatArray, effort: FloatArray
    ) -> float:
        """The least ``t`` of one contact set; ``inf`` when it cannot hold at all.

        Args:
            A: (rows, m) the set's balance, normal-force and cone rows.
            lo: (rows,) their lower bounds (``-inf`` for none).
            hi: (rows,) their upper bounds (``inf`` for none).
            T: (ne, m) the limited joints' torques per unit of the forces (N m).
            effort: (ne,) those joints' effort limits (N m); with none the
                program only decides feasibility and the ratio is 0.
        """
        ne = len(effort)
        t_col = np.concatenate([np.zeros(A.shape[0]), -effort, -effort])[:, None]
        M = np.hstack([np.vstack([A, T, -T]) if ne else A, t_col])
        lo_all = np.concatenate([lo, np.full(2 * ne, -np.inf)])
        hi_all = np.concatenate([hi, np.zeros(2 * ne)])
        if self._highs is None:
            return _milp_ratio(M, lo_all, hi_all)
        h = self._highs
        h.passModel(*_program(_CORE, M, lo_all, hi_all))
        basis = self._basis.get(M.shape)
        if basis is not None:
            h.setBasis(basis)
        h.run()
        if h.getModelStatus() != _CORE.HighsModelStatus.kOptimal:
            return math.inf
        self._basis[M.shape] = h.getBasis()
        return float(h.getSolution().col_value[-1])


def _milp_ratio(M: FloatArray, lo: FloatArray, hi: FloatArray) -> float:
    """:meth:`RatioLP.ratio`'s program by ``scipy.optimize.milp`` (no warm start)."""
    m = M.shape[1] - 1
    lp = milp(
        np.r_[np.zeros(m), 1.0],
        constraints=LinearConstraint(M, lo, hi),
        bounds=Bounds(np.r_[np.full(m, -np.inf), 0.0], np.full(m + 1, np.inf)),
        options={"presolve": False},
    )
    if lp.status != 0 or lp.x is None:
        return math.inf
    return float(lp.x[-1])
