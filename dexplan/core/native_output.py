"""Capture what native libraries write on the process's stderr (file descriptor 2).

urdfdom (through console_bridge), Pinocchio and mesh loaders print warnings and
errors straight to the C stderr, bypassing :data:`sys.stderr`, so Python cannot
catch them with ``contextlib.redirect_stderr``. :func:`captured_stderr`
redirects file descriptor 2 itself into a temporary file for the duration of a
``with`` block and hands the text back, so the caller can turn what matters into
one clean dexplan error (or drop it).

While a capture is active, everything written to fd 2 by any thread goes into
it, Python's own ``sys.stderr`` included: keep the blocks short (one native
call) and never log from inside them. Captures are serialised by a process-wide
re-entrant lock; a nested capture in the same thread gets the inner text only.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys
import tempfile
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

_LOCK = threading.RLock()
_STDERR_FD = 2

_LIBC_FFLUSH: Callable[[ctypes.c_void_p | None], int] | None
try:  # flushes C stdio buffers (stderr is unbuffered by default, but be safe)
    _LIBC_FFLUSH = ctypes.CDLL(None).fflush
except (OSError, AttributeError):  # pragma: no cover - non-POSIX platforms
    _LIBC_FFLUSH = None


@dataclass
class CapturedText:
    """Text written to fd 2 inside a :func:`captured_stderr` block.

    Attributes:
        text: everything captured (decoded as UTF-8, undecodable bytes
            replaced); empty until the block has exited.
    """

    text: str = field(default="")

    @property
    def lines(self) -> list[str]:
        """The non-blank captured lines, stripped."""
        return [ln.strip() for ln in self.text.splitlines() if ln.strip()]

    def first_line(self, limit: int = 200) -> str:
        """The first non-blank captured line, cleaned for an error message.

        console_bridge's ``Error:`` / ``Warning:`` prefixes are removed and
        runs of whitespace collapsed; the result is cut to ``limit``
        characters. Empty when nothing was captured.
        """
        for line in self.lines:
            for prefix in ("Error:", "Warning:", "Info:", "Debug:"):
                if line.startswith(prefix):
                    line = line[len(prefix) :]
                    break
            line = " ".join(line.split())
            if line:
                return line if len(line) <= limit else line[: limit - 3] + "..."
        return ""


def _flush_all() -> None:
    with contextlib.suppress(Exception):
        sys.stderr.flush()
    if _LIBC_FFLUSH is not None:
        with contextlib.suppress(Exception):
            _LIBC_FFLUSH(None)


@contextlib.contextmanager
def captured_stderr() -> Iterator[CapturedText]:
    """Redirect file descriptor 2 into a buffer for the duration of the block.

    Yields:
        A :class:`CapturedText` whose ``text`` is filled in when the block
        exits (also when it raises). fd 2 is restored in every case. When fd 2
        cannot be duplicated (closed), nothing is captured and the block runs
        unchanged.

    Example:
        >>> with captured_stderr() as err:
        ...     model = pin.buildModelFromXML(text)  # doctest: +SKIP
        >>> err.first_line()  # doctest: +SKIP
        'Could not parse collision element for Link [l1]'
    """
    out = CapturedText()
    with _LOCK:
        _flush_all()
        try:
            saved = os.dup(_STDERR_FD)
        except OSError:
            yield out
            return
        try:
            with tempfile.TemporaryFile(mode="w+b") as buf:
                os.dup2(buf.fileno(), _STDERR_FD)
                try:
                    yield out
                finally:
                    _flush_all()
                    os.dup2(saved, _STDERR_FD)
                    buf.seek(0)
                    out.text = buf.read().decode("utf-8", errors="replace")
        finally:
            os.close(saved)
