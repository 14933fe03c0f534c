"""Recordings from files, and the native Rerun viewer (``dexplan show``)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping
from pathlib import Path
from typing import IO, Any

from dexplan.core.errors import DependencyError, DexplanError, PlanFileError
from dexplan.planfile import read_plan
from dexplan.planning.roadmap.graph import Roadmap
from dexplan.viz.plan_recording import record_plan
from dexplan.viz.roadmap_recording import record_roadmap
from dexplan.viz.session import require_rerun

_NO_DISPLAY = (
    "cannot open the Rerun viewer: no display (DISPLAY/WAYLAND_DISPLAY unset); "
    "write the recording to a file instead (dexplan show PLAN --save out.rrd) and "
    "open it with `rerun out.rrd` on a machine with a display, or serve it to a "
    "browser with `rerun --serve-web out.rrd`"
)


def write_recording(
    source: str | Path | Mapping[str, Any],
    path: str | Path,
    *,
    roadmap: Roadmap | str | Path | None = None,
    plan: Mapping[str, Any] | str | Path | None = None,
    base_dir: str | Path | None = None,
) -> Path:
    """Write a recording of a plan or a roadmap, chosen by what ``source`` is.

    Args:
        source: a plan document, a plan ``.json`` file, or a roadmap ``.npz``
            file (recognised by its suffix).
        path: output ``.rrd`` file.
        roadmap: for a plan, the roadmap (object or ``.npz`` file) to add.
        plan: for a roadmap file, a plan (document or ``.json`` file) whose
            hand, object and obstacles are drawn with it, each node's
            configuration on the ``roadmap_node`` timeline.
        base_dir: folder relative mesh paths resolve against (default: the
            plan file's folder, or the working directory for a document).

    Returns:
        ``path`` as a :class:`~pathlib.Path`.

    Raises:
        DependencyError: rerun-sdk missing.
        PlanFileError: unreadable plan or roadmap file.

    """
    require_rerun()
    path = Path(path)

    def load_doc(item: Mapping[str, Any] | str | Path) -> tuple[Mapping[str, Any], Path]:
        if isinstance(item, Mapping):
            return item, Path(base_dir or ".")
        return read_plan(item, base_dir), Path(base_dir or Path(item).resolve().parent)

    if not isinstance(source, Mapping) and Path(source).suffix == ".npz":
        scene, folder = load_doc(plan) if plan is not None else (None, Path(base_dir or "."))
        record_roadmap(Roadmap.load(source), path, scene=scene, base_dir=folder)
        return path
    doc, folder = load_doc(source)
    rm = Roadmap.load(roadmap) if isinstance(roadmap, str | Path) else roadmap
    record_plan(doc, path, roadmap=rm, base_dir=folder)
    return path


def _has_display() -> bool:
    if sys.platform.startswith("linux"):
        return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    return True


def viewer_command() -> list[str]:
    """The command that starts the Rerun viewer (``rerun``, else ``python -m rerun``)."""
    exe = shutil.which("rerun")
    if exe is not None:
        return [exe]
    return [sys.executable, "-m", "rerun"]


def show(
    source: str | Path | Mapping[str, Any],
    *,
    roadmap: Roadmap | str | Path | None = None,
    plan: Mapping[str, Any] | str | Path | None = None,
    base_dir: str | Path | None = None,
    wait_s: float = 1.5,
) -> Path:
    """Open a plan, roadmap or recording in the native Rerun viewer.

    A plan (document or ``.json``) or roadmap (``.npz``) is first recorded to
    a temporary ``.rrd`` (kept, so it can be reopened); an ``.rrd`` is opened
    as is. The viewer runs detached; this returns once it has started.

    Args:
        source: plan document, or a ``.json``, ``.npz`` or ``.rrd`` file.
        roadmap: roadmap to add to a plan's recording.
        plan: for a roadmap file, the plan whose models are drawn with it.
        base_dir: folder relative mesh paths resolve against.
        wait_s: seconds to watch the viewer for an immediate failure.

    Returns:
        The path of the ``.rrd`` opened.

    Raises:
        DependencyError: rerun-sdk missing, or no display to open a window on
            (headless machine: write the file with :func:`write_recording`
            and open it elsewhere, or serve it with ``rerun --serve-web``).
        DexplanError: the viewer exited at once (its message is included).
        PlanFileError: the file does not exist or cannot be read.

    """
    require_rerun()
    if isinstance(source, str | Path) and not Path(source).is_file():
        raise PlanFileError(f"file not found: {str(source)!r}")
    if not _has_display():
        raise DependencyError(_NO_DISPLAY)
    if isinstance(source, str | Path) and Path(source).suffix == ".rrd":
        rrd = Path(source)
    else:
        fd, tmp = tempfile.mkstemp(prefix="dexplan-", suffix=".rrd")
        os.close(fd)
        rrd = write_recording(source, tmp, roadmap=roadmap, plan=plan, base_dir=base_dir)
    _start_viewer(rrd, wait_s)
    return rrd


def _start_viewer(rrd: Path, wait_s: float) -> None:
    """Start the viewer on ``rrd``, detached, and watch it for ``wait_s`` seconds.

    Raises:
        DependencyError: the viewer cannot be started.
        DexplanError: the viewer exited at once (its last stderr lines are included).
    """
    cmd = [*viewer_command(), str(rrd)]
    log = tempfile.TemporaryFile()  # noqa: SIM115 - the viewer's stderr, read back on failure
    try:
        proc = subprocess.Popen(
            cmd,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=log,
            start_new_session=True,
        )
    except OSError as exc:
        log.close()
        raise DependencyError(f"cannot start the Rerun viewer ({cmd[0]}): {exc}") from exc
    try:
        _watch(proc, log, rrd, time.monotonic() + max(0.0, wait_s))
    finally:
        log.close()


def _watch(proc: subprocess.Popen[bytes], log: IO[bytes], rrd: Path, deadline: float) -> None:
    """Raise DexplanError if the viewer exits before ``deadline`` (monotonic seconds)."""
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            log.seek(0)
            err = log.read().decode(errors="replace")
            tail = "\n".join(err.strip().splitlines()[-5:])
            raise DexplanError(
                f"the Rerun viewer exited at once (code {proc.returncode}) on {rrd}: {tail}"
            )
        time.sleep(0.05)
