"""Ctrl-C for the command line: a flag that survives libraries which swallow it.

Some libraries catch ``BaseException`` around their own imports (trimesh
does), which swallows the ``KeyboardInterrupt`` raised there; a native
module's initialisation may abort when one surfaces inside it. So SIGINT
always sets a flag, and raises only while a command runs and the interrupted
code is not inside an ``import`` or a library that breaks when cut short
(Rerun); the flag is acted on at the next progress event or before any output
(:func:`check`).

An interrupted command leaves no output: each file is written atomically, and
the files it had already finished (a plan file before its recording) are
removed (:func:`output`, :func:`discard_outputs`), so that no half set of
results looks like a finished run.
"""

from __future__ import annotations

import signal
import threading
from pathlib import Path
from types import FrameType

__all__ = [
    "check",
    "discard_outputs",
    "forget_outputs",
    "install",
    "is_interrupted",
    "output",
    "running",
]

_interrupted = False
_running = False
#: The running command's output files, each with what was there before it ran
#: (``(inode, mtime_ns, size)``, None for no file).
_outputs: dict[Path, tuple[int, int, int] | None] = {}


#: Libraries whose objects break when an exception cuts their Python code
#: short: a ``rerun.RecordingStream`` interrupted while it is built has no
#: native handle, and its ``__del__`` prints a traceback.
_FRAGILE = ("rerun",)


def _on_sigint(signum: int, frame: FrameType | None) -> None:
    global _interrupted
    _interrupted = True
    if _running and not _deferred(frame):
        raise KeyboardInterrupt


def _deferred(frame: FrameType | None) -> bool:
    """True when the interrupted code runs inside an ``import`` or a fragile library.

    There the interrupt is only noted; :func:`check` acts on it once the
    library has returned (the next progress event, or before any output).
    """
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            return True
        module = str(frame.f_globals.get("__name__", ""))
        if module.split(".")[0] in _FRAGILE:
            return True
        frame = frame.f_back
    return False


def install() -> None:
    """Handle SIGINT with :func:`_on_sigint` (only the main thread may)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, _on_sigint)


def running(flag: bool) -> None:
    """Say whether a command runs: only then does SIGINT raise at once."""
    global _running
    _running = flag


def is_interrupted() -> bool:
    """True once SIGINT has been received, even if its exception was swallowed."""
    return _interrupted


def check() -> None:
    """Raise ``KeyboardInterrupt`` if SIGINT was received.

    Raises:
        KeyboardInterrupt: Ctrl-C was pressed (perhaps inside a library that
            swallowed the exception).
    """
    if _interrupted:
        raise KeyboardInterrupt


def _signature(path: Path) -> tuple[int, int, int] | None:
    try:
        st = path.stat()
    except OSError:
        return None
    return (st.st_ino, st.st_mtime_ns, st.st_size)


def output(path: str | Path) -> Path:
    """Note ``path`` as an output of the running command, before it is written.

    Returns:
        ``path``, as a :class:`~pathlib.Path`.
    """
    p = Path(path)
    _outputs[p.absolute()] = _signature(p)
    return p


def discard_outputs() -> None:
    """Remove every noted output the interrupted command has written; forget them."""
    for path, before in _outputs.items():
        if _signature(path) != before:
            path.unlink(missing_ok=True)
    _outputs.clear()


def forget_outputs() -> None:
    """Forget the noted outputs (a command starts, or has ended)."""
    _outputs.clear()
