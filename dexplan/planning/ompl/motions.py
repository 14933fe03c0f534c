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
geodesics, :mod:`dexplan.planning.geodesic_motion`).

:class:`FallbackMotions` is then the space information's motion validator: an
``ob.MotionValidator`` subclass whose ``checkMotion(s1, s2)`` asks the space's
own validator (a ``ConstrainedMotionValidator``, kept from
``si.getMotionValidator()``) and then the fallback. The states of every motion
the fallback joined are recorded, so the densification of a path through that
edge follows them (:meth:`FallbackMotions.states`); an edge met without a
record (a roadmap built in another process, or loaded) is joined again, the
fallback being deterministic.

Binding facts (ompl 2.0.1 wheel, measured, docs/meshes.md): the wheel calls a
Python ``ob.MotionValidator`` given to ``si.setMotionValidator`` (PRM's
``growRoadmap`` 145 times in 3 s on the egg, single-threaded); it does not
call Python overrides of the state space's ``interpolate``, so the dense
states of a fallback motion come from the record, not from OMPL. The
3-argument ``checkMotion(s1, s2, last_valid)`` (the tree planners') stays the
space's own: only the PRM family, which calls the 2-argument one, is given a
fallback.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
from ompl import base as ob

from dexplan.exceptions import PlannerError
from dexplan.typing import FloatArray

if TYPE_CHECKING:
    from dexplan.planning.ompl.callbacks import ErrorSink
    from dexplan.planning.ompl.spaces import ConstraintSpec, Frame

__all__ = ["FallbackMotions", "MotionFallback"]

MotionFallback = Callable[[FloatArray, FloatArray, float], Any]
"""``fallback(x_a (n,), x_b (n,), deadline) -> (K, n) ambient states | None``."""

END_TOLERANCE = 1e-9
"""Largest planning-coordinate gap between a fallback motion's ends and its states."""


class FallbackMotions(ob.MotionValidator):
    """The space's motion validator, then a fallback motion; joined motions recorded.

    Args:
        si: the space information (its current validator becomes the first one
            asked; install this one with ``si.setMotionValidator``).
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
        share: during a solve, the fallback is not called while the time it
            took exceeds this fraction of the solve's time so far (it
            costs tens of milliseconds a call and rarely joins what OMPL's
            motion does not: its cost stays bounded).

    Attributes:
        attempts: fallback calls made.
        joined: fallback calls that joined their states.
        skipped: calls left out for the time share.
    """

    def __init__(
        self,
        si: Any,
        fallback: MotionFallback,
        spec: ConstraintSpec,
        frame: Frame,
        sink: ErrorSink,
        *,
        merges_only: bool,
        share: float = 0.25,
    ) -> None:
        super().__init__(si)
        self._si = si
        self._original = si.getMotionValidator()
        self._fallback = fallback
        self._spec = spec
        self._frame = frame
        self._sink = sink
        self._merges_only = merges_only
        self._lo = frame.to_y(spec.lower)
        self._up = frame.to_y(spec.upper)
        self._record: dict[tuple[bytes, bytes], FloatArray] = {}
        self._parent: dict[bytes, bytes] = {}
        self._share = share
        self.attempts = 0
        self.joined = 0
        self.skipped = 0
        self._deadline = math.inf
        self._started: float | None = None
        self._spent = 0.0

    def start(self, seconds: float) -> None:
        """A solve of ``seconds`` starts: no fallback past its end, its time share counted."""
        now = time.perf_counter()
        self._deadline = now + seconds
        self._started = now
        self._spent = 0.0

    def stop(self) -> None:
        """The solve ended: the fallback is tried without deadline or share."""
        self._deadline = math.inf
        self._started = None

    # ------------------------------------------------------------ OMPL's calls

    def checkMotion(self, s1: Any, s2: Any, *last_valid: Any) -> bool:  # noqa: N802
        """OMPL's motion check: the space's own motion, else the fallback's."""
        if last_valid:  # the tree planners' form: the space's own motion only
            return bool(self._original.checkMotion(s1, s2, *last_valid))
        if self._sink.error is not None:
            return False
        try:
            if self._original.checkMotion(s1, s2):
                read = self._frame.read
                self._union(read(s1).tobytes(), read(s2).tobytes())
                return True
            read = self._frame.read
            return self._check_fallback(read(s1), read(s2))
        except Exception as exc:  # must not unwind through C++: recorded, re-raised
            self._sink.record(exc)
            return False

    # ------------------------------------------------------------ Python side

    def check(self, ya: FloatArray, yb: FloatArray) -> bool:
        """Whether ``ya -> yb`` (planning ``(n,)``) is a valid motion, either kind."""
        if self._original_ok(ya, yb):
            self._union(ya.tobytes(), yb.tobytes())
            return True
        return self._check_fallback(ya, yb)

    def _check_fallback(self, ya: FloatArray, yb: FloatArray) -> bool:
        """Whether the fallback joins ``ya -> yb`` (recorded, or joined now)."""
        ka, kb = ya.tobytes(), yb.tobytes()
        if self._recorded(ka, kb) is not None:
            self._union(ka, kb)
            return True
        if self._merges_only and self._find(ka) == self._find(kb):
            return False
        return self._join(ya, yb) is not None

    def states(self, ya: FloatArray, yb: FloatArray) -> FloatArray | None:
        """The fallback's planning-coordinate ``(K, n)`` states of ``ya -> yb``, or None.

        None when the space's own motion is valid (OMPL's interpolation then
        densifies the edge) or when neither motion joins the states. Recorded
        motions are returned as recorded (reversed for ``yb -> ya``).
        """
        recorded = self._recorded(ya.tobytes(), yb.tobytes())
        if recorded is not None:
            return recorded
        if self._original_ok(ya, yb):
            return None
        return self._join(ya, yb)

    def recorded(self, ya: FloatArray, yb: FloatArray) -> FloatArray | None:
        """The recorded fallback states of ``ya -> yb`` (planning), or None (no call)."""
        return self._recorded(ya.tobytes(), yb.tobytes())

    @property
    def record_size(self) -> int:
        """Motions the fallback joined and this validator keeps."""
        return len(self._record)

    # ------------------------------------------------------------ helpers

    def _original_ok(self, ya: FloatArray, yb: FloatArray) -> bool:
        si = self._si
        a, b = si.allocState(), si.allocState()
        a.copy(ya.tolist())
        b.copy(yb.tolist())
        return bool(self._original.checkMotion(a, b))

    def _recorded(self, ka: bytes, kb: bytes) -> FloatArray | None:
        got = self._record.get((ka, kb))
        if got is not None:
            return got
        back = self._record.get((kb, ka))
        return None if back is None else back[::-1]

    def _join(self, ya: FloatArray, yb: FloatArray) -> FloatArray | None:
        """Call the fallback; check, record and return its planning states, or None."""
        now = time.perf_counter()
        if now >= self._deadline:
            return None
        if self._started is not None and self._spent > self._share * (now - self._started):
            self.skipped += 1
            return None
        self.attempts += 1
        frame = self._frame
        try:
            got = self._fallback(frame.to_x(ya), frame.to_x(yb), self._deadline)
        finally:
            self._spent += time.perf_counter() - now
        if got is None:
            return None
        xs = np.asarray(got, dtype=np.float64)
        n = frame.n
        if xs.ndim != 2 or xs.shape[1] != n or xs.shape[0] < 2 or not np.all(np.isfinite(xs)):
            raise PlannerError(
                f"a motion fallback returned shape {xs.shape} (need (K >= 2, {n})) or non-finite"
            )
        ys = np.array(frame.to_y(xs), dtype=np.float64)
        ends = max(float(np.max(np.abs(ys[0] - ya))), float(np.max(np.abs(ys[-1] - yb))))
        if ends > END_TOLERANCE:
            raise PlannerError(
                f"a motion fallback's states do not start and end at its two states "
                f"(gap {ends:.3g} > {END_TOLERANCE:g})"
            )
        if not self._on_manifold(xs, ys):
            return None
        ys[0], ys[-1] = ya, yb  # exactly the roadmap's states
        self._record[(ya.tobytes(), yb.tobytes())] = ys
        self._union(ya.tobytes(), yb.tobytes())
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
