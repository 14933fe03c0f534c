"""Atomic file output: a reader never sees a half-written plan, roadmap or recording.

Output goes to a temporary file in the destination folder, which is renamed
over the destination only once it is complete; on any error the temporary file
is removed and the destination is left as it was.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

from dexplan.core.errors import DexplanError, InvalidInputError


@contextlib.contextmanager
def atomic_output(path: str | Path, what: str = "output") -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it to ``path`` on success.

    Args:
        path: destination file.
        what: what is written, for the error message.

    Raises:
        InvalidInputError: the destination folder does not exist.
    """
    path = Path(path)
    folder = path.resolve().parent
    if not folder.is_dir():
        raise InvalidInputError(f"{what} folder does not exist: {str(folder)!r}")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; give the usual permissions
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    finally:
        Path(tmp).unlink(missing_ok=True)


def check_output_path(path: str | Path, what: str) -> Path:
    """Check, before any work, that ``path`` can be written; return it.

    A run that plans for minutes and then cannot write its result (or leaves
    one output without the other) is worse than one that refuses at once.

    Args:
        path: the file to be written.
        what: the option or output it is, for the message (``-o``, ``--rrd``).

    Raises:
        InvalidInputError: the folder is missing or not writable, or ``path``
            is a folder.
    """
    path = Path(path)
    if str(path) == "":
        raise InvalidInputError(f"{what}: empty file name")
    folder = path.resolve().parent
    if not folder.is_dir():
        raise InvalidInputError(f"{what}: folder does not exist: {str(folder)!r}")
    if path.is_dir():
        raise InvalidInputError(f"{what}: is a folder, not a file: {str(path)!r}")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise InvalidInputError(f"{what}: folder is not writable: {str(folder)!r}")
    return path


def file_sha256(path: str | Path) -> str:
    """SHA-256 hex digest of a file's bytes: the one file identity of dexplan.

    Meshes in plan files, URDFs and meshes in benchmark scenario hashes and
    plans in trajectory files are identified by it.

    Raises:
        OSError: the file cannot be read.
    """
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def read_input_file(path: str | Path, what: str, error: type[DexplanError]) -> bytes:
    """The bytes of an input file (a URDF, a mesh), or a one-line ``error``.

    Args:
        path: the file.
        what: what it is, for the message (``"URDF"``, ``"mesh"``).
        error: the exception raised (a :class:`~dexplan.core.errors.DexplanError`).

    Raises:
        error: ``"<what> file not found: '<path>'"`` or
            ``"cannot read <what> file '<path>': <reason>"``.
    """
    p = Path(path)
    if not p.is_file():
        raise error(f"{what} file not found: {str(p)!r}")
    try:
        return p.read_bytes()
    except OSError as exc:
        raise error(f"cannot read {what} file {str(p)!r}: {exc.strerror or exc}") from exc
