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

import atexit
import contextlib
import ctypes
import os
import re
import sys
import tempfile
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

_LOCK = threading.RLock()
_STDERR_FD = 2
_EXIT_FILTER = [False]  # installed once per process

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


LEAK_REPORT = re.compile(
    rb"^(nanobind: |\s*- leaked |\s*- \.\.\. skipped remainder|"
    rb"See https://nanobind\.readthedocs\.io/en/latest/refleaks\.html)"
)
"""The lines of nanobind's "leaked instances" report (:func:`hide_leak_report_at_exit`)."""


def hide_leak_report_at_exit() -> None:
    """Keep nanobind's "leaked instances" report off the terminal when Python exits.

    nanobind (the ompl binding) lists the binding objects still alive when
    the interpreter shuts down: states, planners and spaces a script held,
    Python planners that subclass ``ob.Planner`` above all. It is noise to a
    user (the process is ending; nothing leaks), dozens of lines after every
    script, and it is printed after Python's exit handlers, where Python can
    no longer catch it. So at exit (an :mod:`atexit` handler) fd 2 becomes a
    pipe to a forked filter process that passes every line on to the real
    stderr except the report's. Set ``DEXPLAN_SHOW_LEAKS=1`` to see it
    (debugging a binding). Installed once; a no-op without ``os.fork``.
    """
    if _EXIT_FILTER[0] or os.environ.get("DEXPLAN_SHOW_LEAKS") or not hasattr(os, "fork"):
        return
    _EXIT_FILTER[0] = True
    atexit.register(_filter_stderr_from_now)


def _filter_stderr_from_now() -> None:
    """Route fd 2 through a forked filter that drops :data:`LEAK_REPORT` lines."""
    _flush_all()
    try:
        read_end, write_end = os.pipe()
        pid = os.fork()
    except OSError:
        return
    if pid == 0:  # the filter: it ends when the exiting process closes the pipe
        os.close(write_end)
        for fd in (0, 1):  # hold nobody's pipes open longer than needed
            with contextlib.suppress(OSError):
                os.close(fd)
        try:
            _pass_lines(read_end)
        finally:
            os._exit(0)
    os.close(read_end)
    os.dup2(write_end, _STDERR_FD)
    os.close(write_end)


def _pass_lines(read_end: int) -> None:
    """Copy lines from ``read_end`` to fd 2, except nanobind's leak report."""
    pending = b""
    while True:
        chunk = os.read(read_end, 65536)
        if not chunk:
            break
        pending += chunk
        *lines, pending = pending.split(b"\n")
        out = b"".join(line + b"\n" for line in lines if not LEAK_REPORT.match(line))
        if out:
            os.write(_STDERR_FD, out)
    if pending and not LEAK_REPORT.match(pending):
        os.write(_STDERR_FD, pending)
