"""Ctrl-C for the command line: a flag that survives libraries which swallow it.

Some libraries catch ``BaseException`` around their own imports (trimesh
does), which swallows the ``KeyboardInterrupt`` raised there; a native
module's initialisation may abort when one surfaces inside it. So SIGINT
always sets a flag, and raises only while a command runs and the interrupted
code is not inside an ``import``; the flag is acted on at the next progress
event or before any output (:func:`check`).
"""

from __future__ import annotations

import signal
import threading
from types import FrameType

__all__ = ["check", "install", "is_interrupted", "running"]

_interrupted = False
_running = False


def _on_sigint(signum: int, frame: FrameType | None) -> None:
    global _interrupted
    _interrupted = True
    if _running and not _importing(frame):
        raise KeyboardInterrupt


def _importing(frame: FrameType | None) -> bool:
    """True when the interrupted code runs inside an ``import``."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
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
