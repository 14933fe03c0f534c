"""Ctrl-C in the middle of a run: exit 130, "interrupted", no output file, no traceback.

The interrupt is a real SIGINT sent to this process at a chosen moment of a
real run (inside a library call that swallows it, as the file of an output
is about to appear, while a Rerun stream is being built), not a flag set
before the run starts.
"""

from __future__ import annotations

import gc
import json
import os
import signal
import sys
import types
from collections.abc import Callable
from pathlib import Path

import pytest
from cli_contract import run_cli

import dexplan.core.files as files
from dexplan.cli import interrupt
from dexplan.cli.main import EXIT_INTERRUPTED
from dexplan.planfile import read_plan


@pytest.fixture(autouse=True)
def _no_interrupt_left(monkeypatch):
    """Each test starts without a noted interrupt, and leaves none behind."""
    monkeypatch.setattr(interrupt, "_interrupted", False)


def _sigint() -> None:
    os.kill(os.getpid(), signal.SIGINT)


def _assert_interrupted(code: int, err: str, folder: Path, outputs: list[str]) -> None:
    assert code == EXIT_INTERRUPTED, err
    assert "interrupted" in err
    assert "Traceback" not in err and "Exception ignored" not in err, err
    left = sorted(p.name for p in folder.iterdir())
    assert not set(outputs) & set(left), left  # no output, not even a finished one
    assert not [n for n in left if n.endswith(".tmp")], left  # no half-written file


def _interrupt_before_replace(monkeypatch, name: str, fired: list[str]) -> None:
    """SIGINT as ``name``'s complete temporary file is about to be renamed onto it."""

    def replace(src, dst):
        if Path(dst).name == name and not fired:
            fired.append(name)
            _sigint()
        os.replace(src, dst)

    proxy = types.SimpleNamespace(**{k: getattr(os, k) for k in dir(os) if not k.startswith("__")})
    proxy.replace = replace
    monkeypatch.setattr(files, "os", proxy)  # every atomic output
    bag = sys.modules.get("dexplan.execution.bag")
    if bag is not None:  # the ROS 2 bag renames its own MCAP file
        monkeypatch.setattr(bag, "os", proxy)


def test_sigint_swallowed_by_a_library_mid_run_still_ends_the_run(monkeypatch, capfd, tmp_path):
    """A KeyboardInterrupt eaten by `except BaseException` in the middle of planning.

    The interrupt arrives inside module 1 (the GSn exploration), in a call that
    swallows it as trimesh does around its imports; the run goes on and must
    stop at its next progress event.
    """
    import dexplan.planning.planner as planner

    real = planner.explore_gsn
    swallowed: list[str] = []

    def swallowing(*args, **kwargs):
        try:
            _sigint()
            raise AssertionError("the SIGINT handler did not raise")
        except BaseException as exc:  # what such a library does: nothing
            swallowed.append(type(exc).__name__)
        return real(*args, **kwargs)

    monkeypatch.setattr(planner, "explore_gsn", swallowing)
    out = tmp_path / "p.json"
    code, _, err = run_cli(capfd, "plan", "--time-limit", "300", "-o", out)
    assert swallowed == ["KeyboardInterrupt"]  # it arrived mid-run and was swallowed
    _assert_interrupted(code, err, tmp_path, ["p.json"])


STAGES: dict[str, tuple[list[str], str, list[str]]] = {
    # stage: (command after `dexplan`, the file interrupted, every output)
    "plan file": (["plan", "-q", "-o", "p.json"], "p.json", ["p.json"]),
    "recording": (
        ["plan", "-q", "-o", "p.json", "--rrd", "p.rrd"],
        "p.rrd",
        ["p.json", "p.rrd"],
    ),
    "roadmap": (
        ["plan", "-q", "-o", "p.json", "--save-roadmap", "rm.npz"],
        "rm.npz",
        ["p.json", "rm.npz"],
    ),
}


@pytest.mark.parametrize("stage", list(STAGES))
def test_interrupt_as_an_output_appears(stage, monkeypatch, capfd, tmp_path):
    if stage == "recording":
        pytest.importorskip("rerun")
    args, name, outputs = STAGES[stage]
    fired: list[str] = []
    _interrupt_before_replace(monkeypatch, name, fired)
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli(capfd, *args, "--time-limit", "300")
    assert fired == [name]
    _assert_interrupted(code, err, tmp_path, outputs)


@pytest.mark.parametrize("name", ["traj.json", "traj.mcap"])
def test_interrupt_as_the_trajectory_appears(name, paper_plan, monkeypatch, capfd, tmp_path):
    if name.endswith(".mcap"):
        pytest.importorskip("rosbags")
        import dexplan.execution.bag  # noqa: F401 - loaded, so that its rename is watched
    doc = read_plan(paper_plan(1, tmp_path))
    doc["segments"] = doc["segments"][:1]  # the first segment: a plan, cheaper to time
    plan_file = tmp_path / "first_segment.json"
    plan_file.write_text(json.dumps(doc))
    fired: list[str] = []
    _interrupt_before_replace(monkeypatch, name, fired)
    code, _, err = run_cli(capfd, "export", plan_file, "-o", tmp_path / name)
    assert fired == [name]
    _assert_interrupted(code, err, tmp_path, [name])
    assert plan_file.exists()  # the input is not an output


def test_interrupt_while_the_rerun_stream_is_built(monkeypatch, capfd, tmp_path):
    """Inside ``rerun.RecordingStream.__init__``: the stream is finished, then the run ends.

    Cut short there, the stream had no native handle and its ``__del__``
    printed a traceback; the interrupt is now acted on once rerun returns.
    """
    recording_stream = pytest.importorskip("rerun.recording_stream")
    bindings = recording_stream.bindings
    real: Callable[..., object] = bindings.new_recording
    fired: list[bool] = []

    def new_recording(*args, **kwargs):
        native = real(*args, **kwargs)
        if not fired:
            fired.append(True)
            _sigint()
        return native

    monkeypatch.setattr(bindings, "new_recording", new_recording)
    # what Python prints as "Exception ignored in ... Traceback" (pytest would hide it)
    unraisable: list[str] = []
    monkeypatch.setattr(sys, "unraisablehook", lambda u: unraisable.append(repr(u.exc_value)))
    monkeypatch.chdir(tmp_path)
    args = ["plan", "-q", "-o", "p.json", "--rrd", "p.rrd", "--time-limit", "300"]
    code, _, err = run_cli(capfd, *args)
    assert fired == [True]
    gc.collect()
    assert unraisable == []
    _assert_interrupted(code, err, tmp_path, ["p.json", "p.rrd"])
