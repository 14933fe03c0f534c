"""Motions between two states: OMPL's discrete geodesic, or a caller's fallback.

OMPL joins two states of a constrained space by its discrete geodesic (the
projected interpolation, :meth:`PathGeometric.interpolate`). A caller may add a
second motion, tried when that one is invalid::

    fallback(x_a, x_b, deadline) -> (K, n) states | None

``x_a, x_b: (n,)`` ambient states; the answer holds ambient states from
``x_a`` to ``x_b`` (both included, K >= 2), each valid, or None when the
fallback cannot join them; ``deadline`` is the running solve's end
(``time.perf_counter()``; ``math.inf`` outside a solve). dexplan's planning
layer passes the paper's section VI motion on meshes (contacts along surface
geodesics, :mod:`dexplan.planning.local.geodesic_motion`).

:class:`FallbackMotions` holds the fallback, the record of the motions it
joined and the bookkeeping that bounds its cost. Installed as the space
information's motion validator (an ``ob.MotionValidator`` subclass given to
``si.setMotionValidator``), its ``checkMotion(s1, s2)`` asks the space's own
validator (a ``ConstrainedMotionValidator``, kept from
``si.getMotionValidator()``) and then the fallback. Paths through an edge
the fallback joined are densified along its recorded states
(:meth:`FallbackMotions.states`); an edge met without a record (a roadmap
built in another process, or loaded) is joined again, the fallback being a
function of its two states.

Binding facts (ompl 2.0.1 wheel, nanobind): the
wheel calls a Python ``ob.MotionValidator`` given to ``si.setMotionValidator``
(PRM's ``growRoadmap`` 145 times in 3 s on the egg, single-threaded); its
trampoline answers the 3-argument ``checkMotion(s1, s2, last_valid)`` with
the 2-argument Python method and leaves ``last_valid`` unset, so planners
that read it (RRT, RRTConnect, the KPIECE family) must not get a fallback;
the PRM family calls the 2-argument form only. The wheel does not call
Python overrides of the state space's ``interpolate``, so the dense states
of a fallback motion come from the record, not from OMPL. The validator
keeps no reference to the space information: the C++ side owns the Python
object (a cycle through C++ would never be collected).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from ompl import base as ob

from dexplan.core.errors import PlannerError
from dexplan.core.typing import FloatArray
from dexplan.planning.ompl.error_sink import ErrorSink
from dexplan.planning.ompl.spaces import ConstraintSpec, Frame

__all__ = ["FallbackMotions", "MotionFallback"]

MotionFallback = Callable[[FloatArray, FloatArray, float], Any]
"""``fallback(x_a (n,), x_b (n,), deadline) -> (K, n) ambient states | None``."""

END_TOLERANCE = 1e-9
"""Largest planning-coordinate gap between a fallback motion's ends and its states."""

KEY_DECIMALS = 10
"""States are recorded by their planning coordinates rounded to this many
decimals: a roadmap vertex read back through ambient coordinates
(``y * inv * scale``) differs from OMPL's own by a few ulps."""


def state_key(y: FloatArray) -> bytes:
    """The record's key of a planning-coordinate state."""
    return np.round(y, KEY_DECIMALS).tobytes()


class FallbackMotions(ob.MotionValidator):
    """The space's motion validator, then a fallback motion; joined motions recorded.

    Args:
        si: the space information (its current validator becomes the first one
            asked; install this one with ``si.setMotionValidator``). Not kept.
        alloc_state: ``() -> state`` of the space (for :meth:`states` and
            :meth:`check`, which start from coordinates).
        fallback: see :data:`MotionFallback`.
        spec: the constraint (its function, tolerance and bounds check the
            fallback's states).
        frame: the planning coordinates.
        sink: where a callback's exception is recorded.
        merges_only: try the fallback only between states not yet joined by
            accepted motions (a union-find over the states this validator has
            accepted): during roadmap growth the fallback then only merges
            components, which is what it adds to a roadmap's connectivity.
            Makes an answer depend on the calls before it; turn off where a
            motion check must be a function of its two states.
        calls_per_check: the fallback is called only while its calls so far
            are at most this fraction of the motion checks answered (the
            first call is free): it costs tens of milliseconds a call and
            rarely joins what OMPL's motion does not. Counted in work, not
            time, so a seed still gives one roadmap.

    Attributes:
        checks: motion checks answered (either kind).
        attempts: fallback calls made.
        joined: motions the fallback joined and this validator recorded.
        skipped: fallback calls left out for ``calls_per_check``.
    """

    def __init__(
        self,
        si: Any,
        alloc_state: Callable[[], Any],
        fallback: MotionFallback,
        spec: ConstraintSpec,
        frame: Frame,
        sink: ErrorSink,
        *,
        merges_only: bool,
        calls_per_check: float = 0.1,
    ) -> None:
        super().__init__(si)
        self._original = si.getMotionValidator()
        self._alloc_state = alloc_state
        self._fallback = fallback
        self._spec = spec
        self._frame = frame
        self._sink = sink
        self._merges_only = merges_only
        self._calls_per_check = float(calls_per_check)
        self._lo = frame.to_y(spec.lower)
        self._up = frame.to_y(spec.upper)
        self._record: dict[tuple[bytes, bytes], FloatArray] = {}
        self._parent: dict[bytes, bytes] = {}
        self.checks = 0
        self.attempts = 0
        self.joined = 0
        self.skipped = 0
        self._deadline = math.inf

    def start(self, seconds: float) -> None:
        """A solve of ``seconds`` starts: no fallback past its end."""
        self._deadline = time.perf_counter() + seconds

    def stop(self) -> None:
        """The solve ended: the fallback has no deadline."""
        self._deadline = math.inf

    def clear(self) -> None:
        """Forget the record, the union-find and the counts (the roadmap was cleared)."""
        self._record.clear()
        self._parent.clear()
        self.checks = self.attempts = self.joined = self.skipped = 0

    # ------------------------------------------------------------ OMPL's calls

    def checkMotion(self, s1: Any, s2: Any, *_last_valid: Any) -> bool:  # noqa: N802
        """OMPL's motion check: the space's own motion, else the fallback's.

        (The 3-argument form reaches here too, see the module notes: only the
        PRM family, which never uses it, gets this validator.)
        """
        if self._sink.error is not None:
            return False
        try:
            self.checks += 1
            read = self._frame.read
            if self._original.checkMotion(s1, s2):
                self._union(state_key(read(s1)), state_key(read(s2)))
                return True
            if self._sink.error is not None:  # the validity callback raised
                return False
            return self._check_fallback(read(s1), read(s2))
        except Exception as exc:  # must not unwind through C++: recorded, re-raised
            self._sink.record(exc)
            return False

    # ------------------------------------------------------------ Python side

    def states(self, ya: FloatArray, yb: FloatArray) -> FloatArray | None:
        """The fallback's planning-coordinate ``(K, n)`` states of ``ya -> yb``, or None.

        A recorded motion first (reversed for ``yb -> ya``); else None when
        the space's own motion is valid (OMPL's interpolation then densifies
        the edge); else the fallback's motion, joined now (no budget: a path
        is being densified), or None when it does not join the states.
        """
        recorded = self.recorded(ya, yb)
        if recorded is not None:
            return recorded
        if self._original_ok(ya, yb):
            return None
        return self._join(ya, yb)

    def recorded(self, ya: FloatArray, yb: FloatArray) -> FloatArray | None:
        """The recorded fallback states of ``ya -> yb`` (planning), or None (no call)."""
        ka, kb = state_key(ya), state_key(yb)
        got = self._record.get((ka, kb))
        if got is not None:
            return got
        back = self._record.get((kb, ka))
        return None if back is None else back[::-1]

    # ------------------------------------------------------------ helpers

    def _check_fallback(self, ya: FloatArray, yb: FloatArray) -> bool:
        """Whether the fallback joins ``ya -> yb`` (recorded, or joined now, budget allowing)."""
        ka, kb = state_key(ya), state_key(yb)
        if self.recorded(ya, yb) is not None:
            self._union(ka, kb)
            return True
        if self._merges_only and self._find(ka) == self._find(kb):
            return False
        if self.attempts > self._calls_per_check * self.checks:
            self.skipped += 1
            return False
        return self._join(ya, yb) is not None

    def _original_ok(self, ya: FloatArray, yb: FloatArray) -> bool:
        a, b = self._alloc_state(), self._alloc_state()
        a.copy(ya.tolist())
        b.copy(yb.tolist())
        return bool(self._original.checkMotion(a, b))

    def _join(self, ya: FloatArray, yb: FloatArray) -> FloatArray | None:
        """Call the fallback; check, record and return its planning states, or None."""
        if time.perf_counter() >= self._deadline:
            return None
        self.attempts += 1
        frame = self._frame
        got = self._fallback(frame.to_x(ya), frame.to_x(yb), self._deadline)
        if got is None:
            return None
        xs = np.asarray(got, dtype=np.float64)
        n = frame.n
        if xs.ndim != 2 or xs.shape[1] != n or xs.shape[0] < 2:
            raise PlannerError(f"a motion fallback returned shape {xs.shape}, need (K >= 2, {n})")
        if not np.all(np.isfinite(xs)):
            raise PlannerError("a motion fallback returned non-finite states")
        ys = np.array(frame.to_y(xs), dtype=np.float64)
        ends = max(float(np.max(np.abs(ys[0] - ya))), float(np.max(np.abs(ys[-1] - yb))))
        if ends > END_TOLERANCE:
            raise PlannerError(
                f"a motion fallback's states do not start and end at its two states "
                f"(gap {ends:.3g} > {END_TOLERANCE:g})"
            )
        if not self._on_manifold(xs, ys):
            return None
        ys[0], ys[-1] = ya, yb  # exactly the states asked about
        ka, kb = state_key(ya), state_key(yb)
        self._record[(ka, kb)] = ys
        self._union(ka, kb)
        self.joined += 1
        return ys

    def _on_manifold(self, xs: FloatArray, ys: FloatArray) -> bool:
        """Whether every state is within the bounds and the constraint's tolerance."""
        if np.any(ys < self._lo) or np.any(ys > self._up):
            return False
        fun, tol = self._spec.function, self._spec.tolerance
        return all(float(np.linalg.norm(np.asarray(fun(x), dtype=np.float64))) <= tol for x in xs)

    def _find(self, k: bytes) -> bytes:
        parent = self._parent
        root = k
        while parent.get(root, root) != root:
            root = parent[root]
        while k != root:  # path compression
            parent[k], k = root, parent.get(k, k)
        return root

    def _union(self, ka: bytes, kb: bytes) -> None:
        ra, rb = self._find(ka), self._find(kb)
        if ra != rb:
            self._parent[ra] = rb
