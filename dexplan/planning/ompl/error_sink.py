"""The error sink: the first exception a Python callback raised during an OMPL solve.

Exceptions must not unwind through OMPL's C++ frames (or its threads): the
callbacks (:mod:`~dexplan.planning.ompl.callbacks`), the constraint and the
projection (:mod:`~dexplan.planning.ompl.spaces`) record them here, answer
"invalid" and terminate the running solve; the caller re-raises the kept one
as a :class:`~dexplan.core.errors.PlannerError`. It is its own module because
both the callbacks and the spaces report to it.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from dexplan.core.errors import PlannerError

__all__ = ["ErrorSink"]


class ErrorSink:
    """First exception raised by a Python callback during a solve.

    Exceptions must not unwind through OMPL's C++ frames (or its threads): callbacks
    record them here, answer "invalid", and terminate the running solve.
    """

    __slots__ = ("error", "ptc")

    def __init__(self) -> None:
        self.error: BaseException | None = None
        self.ptc: Any = None

    def record(self, exc: BaseException) -> None:
        """Keep ``exc`` (unless one is already kept) and terminate the running solve."""
        if self.error is None:
            self.error = exc
        if self.ptc is not None:
            self.ptc.terminate()

    @contextmanager
    def watching(self, ptc: Any) -> Iterator[Any]:
        """Let callbacks terminate ``ptc`` while the ``with`` block runs.

        Args:
            ptc: the planner termination condition of the running solve.

        Yields:
            ``ptc``.

        """
        self.ptc = ptc
        try:
            yield ptc
        finally:
            self.ptc = None

    def reraise(self, during: str) -> None:
        """Raise the kept exception (then forget it) as a :class:`PlannerError`, if any.

        Args:
            during: what was running, for the message (``planning with PRM``).
        """
        error = self.error
        if error is not None:
            self.error = None
            raise PlannerError(
                f"a callback raised during {during}: {type(error).__name__}: {error}"
            ) from error
