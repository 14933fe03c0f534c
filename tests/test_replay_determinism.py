"""The same plan gives the same replay report: twice in one process, and in a fresh process."""

import copy
import hashlib
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dexplan.planfile import read_plan, write_plan

pytest.importorskip("mujoco")

from dexplan.execution.replay.simulation import replay_loops

#: Run in a fresh interpreter: the report of the plan file given, and its digest.
_FRESH = """
import sys
from pathlib import Path
from dexplan.execution.replay.simulation import replay_loops
from dexplan.planfile import read_plan
sys.path.insert(0, sys.argv[2])
from test_replay_determinism import fingerprint
path = Path(sys.argv[1])
print(fingerprint(replay_loops(read_plan(path), base_dir=path.parent)))
"""


def fingerprint(report) -> str:
    """The report's text and a digest of every recorded sample (bit for bit)."""
    h = hashlib.sha256()
    for r in report.results:
        for a in (r.t, r.sim_pose, r.sim_q, r.position_error, r.angle_error):
            h.update(np.ascontiguousarray(a, dtype=float).tobytes())
    return report.summary() + "\n" + h.hexdigest()


@pytest.fixture(scope="module")
def piece(tmp_path_factory, paper_plan) -> Path:
    """paper_sphere seed 1 cut to its first two segments, a hand-over between them (cheap:
    the whole plan replays likewise)."""
    folder = tmp_path_factory.mktemp("determinism")
    doc = read_plan(paper_plan(1, folder))
    d = copy.deepcopy(doc)
    d["segments"] = d["segments"][:2]
    last = d["segments"][-1]["waypoints"][-1]
    d["goal"] = dict(d["goal"], object_pose_xyzquat=last["object_pose_xyzquat"])
    path = folder / "piece.json"
    write_plan(path, d)
    return path


def test_same_report_twice_in_one_process_and_in_a_fresh_one(piece: Path) -> None:
    doc = read_plan(piece)
    first = fingerprint(replay_loops(doc, base_dir=piece.parent))
    assert "hand-overs" in first
    again = fingerprint(replay_loops(doc, base_dir=piece.parent))
    assert again == first
    fresh = subprocess.run(
        [sys.executable, "-c", _FRESH, str(piece), str(Path(__file__).parent)],
        capture_output=True,
        text=True,
        check=True,
    )
    assert fresh.stdout.strip() == first.strip()
