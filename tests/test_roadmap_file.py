"""Malformed roadmap files (``--load-roadmap F``, :meth:`Roadmap.load`).

Every malformed file raises :class:`RoadmapFileError` (a ``PlanFileError``)
naming the array or field, on one line, before any large allocation; through
the CLI that is exit 2 with one ``dexplan: error:`` line.
"""

from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

import numpy as np
import pytest
from cli_contract import MAX_LINE, assert_bad_input, run_cli
from hypothesis import given, settings
from hypothesis import strategies as st

from dexplan.core.errors import PlanFileError, RoadmapFileError
from dexplan.planning.roadmap.file import MAX_ROADMAP_VERTICES, ROADMAP_FORMAT, read_roadmap_arrays
from dexplan.planning.roadmap.graph import Roadmap

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "paper_sphere.toml"
WIDTH = 19  # 7 pose + 12 joints of the paper hand
EMPTY = np.zeros((0, 2), dtype=np.int64)


def _vertices(n: int = 6, width: int = WIDTH) -> np.ndarray:
    rng = np.random.default_rng(0)
    v = rng.normal(size=(n, width))
    v[:, 3:7] /= np.linalg.norm(v[:, 3:7], axis=1, keepdims=True)
    return v


def _meta(**over: object) -> str:
    meta: dict[str, object] = {"format": ROADMAP_FORMAT, "planner": "PRM", "scenario_key": "k"}
    meta.update(over)
    return json.dumps({k: v for k, v in meta.items() if v is not None})


def _arrays(**over: object) -> dict[str, object]:
    """The arrays of a valid roadmap; ``over`` replaces (or with None drops) some."""
    arrays: dict[str, object] = {
        "vertices": _vertices(),
        "edges": np.array([[0, 1], [1, 2], [3, 4]], dtype=np.int64),
        "links": np.array([[2, 3]], dtype=np.int64),
        "meta": np.array(_meta()),
    }
    arrays.update(over)
    return {k: v for k, v in arrays.items() if v is not None}


def _write(path: Path, **over: object) -> Path:
    with open(path, "wb") as fh:
        np.savez(fh, **_arrays(**over))
    return path


def _npy_bytes(header: dict, body: bytes = b"") -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, header)
    return buf.getvalue() + body


def _assert_clean(path: Path, *names: str) -> str:
    with pytest.raises(RoadmapFileError) as info:
        Roadmap.load(path)
    assert isinstance(info.value, PlanFileError)
    msg = str(info.value)
    assert "\n" not in msg and len(msg) <= MAX_LINE, msg
    for name in names:
        assert name in msg, (name, msg)
    return msg


def test_valid_roadmap_round_trip(tmp_path: Path) -> None:
    rm = Roadmap(_vertices(), np.array([[0, 1]]), np.zeros((0, 2), dtype=np.int64), "PRM", "k")
    rm.save(tmp_path / "rm.npz")
    back = Roadmap.load(tmp_path / "rm.npz", "k", ambient_dim=WIDTH)
    np.testing.assert_array_equal(back.vertices, rm.vertices)
    assert back.edges.tolist() == [[0, 1]] and back.links.shape == (0, 2)
    assert back.edges.dtype == np.int64 and back.planner == "PRM"
    assert [p.name for p in tmp_path.iterdir()] == ["rm.npz"]  # no temporary file left
    _write(tmp_path / "w.npz")
    assert Roadmap.load(tmp_path / "w.npz").n_vertices == 6


def test_save_is_atomic(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "rm.npz"
    Roadmap(_vertices(), np.zeros((0, 2)), np.zeros((0, 2)), "PRM", "k").save(path)
    before = path.read_bytes()

    def boom(*_a: object, **_k: object) -> None:
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez_compressed", boom)
    with pytest.raises(OSError, match="disk full"):
        Roadmap(_vertices(3), np.zeros((0, 2)), np.zeros((0, 2)), "PRM", "k").save(path)
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["rm.npz"]


def test_truncated_npz(tmp_path: Path) -> None:
    good = _write(tmp_path / "good.npz").read_bytes()
    path = tmp_path / "t.npz"
    path.write_bytes(good[: len(good) // 2])
    _assert_clean(path, "t.npz", "not a complete .npz")


def test_empty_file(tmp_path: Path) -> None:
    path = tmp_path / "e.npz"
    path.write_bytes(b"")
    _assert_clean(path, "e.npz", "not a roadmap")


def test_plain_npy(tmp_path: Path) -> None:
    path = tmp_path / "v.npy"
    np.save(path, _vertices())
    _assert_clean(path, "v.npy", "not a complete .npz")


def test_meta_is_a_json_list(tmp_path: Path) -> None:
    _assert_clean(_write(tmp_path / "m.npz", meta=np.array("[1, 2]")), "meta", "[1, 2]")


@pytest.mark.parametrize("width", [3, 7, 300])
def test_vertices_of_the_wrong_width(tmp_path: Path, width: int) -> None:
    path = _write(tmp_path / "w.npz", vertices=np.zeros((4, width)))
    _assert_clean(path, "vertices", f"got {width}")


def test_vertices_width_of_another_hand(tmp_path: Path) -> None:
    path = _write(tmp_path / "w.npz", vertices=_vertices(6, WIDTH + 1))
    Roadmap.load(path)  # a plausible width on its own
    with pytest.raises(RoadmapFileError, match=r"vertices have 20 columns.* 19 \(7 \+ nq\)"):
        Roadmap.load(path, ambient_dim=WIDTH)


def test_header_claiming_1e9_rows(tmp_path: Path) -> None:
    """Read from the .npy header before any data: no 150 GB allocation, no MemoryError."""
    path = tmp_path / "h.npz"
    with zipfile.ZipFile(path, "w") as zf:
        header = {"descr": "<f8", "fortran_order": False, "shape": (10**9, WIDTH)}
        zf.writestr("vertices.npy", _npy_bytes(header, b"\0" * 4096))
        for name, arr in _arrays().items():
            if name != "vertices":
                buf = io.BytesIO()
                np.save(buf, arr)
                zf.writestr(f"{name}.npy", buf.getvalue())
    msg = _assert_clean(path, "vertices", "1000000000 rows", str(MAX_ROADMAP_VERTICES))
    assert "at most" in msg


def test_header_claiming_more_rows_than_the_member_holds(tmp_path: Path) -> None:
    path = tmp_path / "s.npz"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        header = {"descr": "<f8", "fortran_order": False, "shape": (10**6, WIDTH)}
        zf.writestr("vertices.npy", _npy_bytes(header, _vertices(3).tobytes()))
        for name, arr in _arrays().items():
            if name != "vertices":
                buf = io.BytesIO()
                np.save(buf, arr)
                zf.writestr(f"{name}.npy", buf.getvalue())
    _assert_clean(path, "vertices: the header claims shape (1000000, 19)", "holds")


def test_a_million_zero_vertices(tmp_path: Path) -> None:
    """Zero quaternions (a ZeroDivisionError in quat_angle once linked) are rejected."""
    path = tmp_path / "z.npz"
    with open(path, "wb") as fh:
        arrays = _arrays(vertices=np.zeros((10**6, WIDTH)), edges=np.zeros((0, 2), np.int64))
        np.savez_compressed(fh, **{**arrays, "links": np.zeros((0, 2), np.int64)})
    _assert_clean(path, "vertices[0]", "quaternion", "norm 0")


@pytest.mark.parametrize(
    ("edges", "name", "needle"),
    [
        (np.array([[0, 6]]), "edges", "edges[0] = [0, 6]"),
        (np.array([[0, 1], [-1, 2]]), "edges", "edges[1] = [-1, 2]"),
        (np.array([[0, 1], [2, 2**40]]), "links", "links[1]"),
    ],
)
def test_indices_out_of_range(tmp_path: Path, edges: np.ndarray, name: str, needle: str) -> None:
    _assert_clean(_write(tmp_path / "i.npz", **{name: edges}), needle, "6 vertices")


def test_nan_in_vertices(tmp_path: Path) -> None:
    v = _vertices()
    v[4, 9] = np.nan
    _assert_clean(_write(tmp_path / "n.npz", vertices=v), "vertices[4]", "not finite")


def test_wrong_format_tag(tmp_path: Path) -> None:
    path = _write(tmp_path / "f.npz", meta=np.array(_meta(format="dexplan-roadmap/2")))
    _assert_clean(path, "meta.format", "'dexplan-roadmap/2'", ROADMAP_FORMAT)


@pytest.mark.parametrize(
    ("over", "needles"),
    [
        ({"edges": np.array([[0.0, 1.5]])}, ["edges", "integer"]),
        ({"edges": np.arange(4)}, ["edges", "(4,)"]),
        ({"vertices": np.zeros((4, WIDTH), dtype=np.int64)}, ["vertices", "float"]),
        ({"vertices": _vertices().ravel()}, ["vertices", "2-D"]),
        ({"vertices": np.array([{"a": 1}], dtype=object)}, ["vertices", "|O"]),
        ({"links": None}, ["'links' is missing"]),
        ({"extra": np.zeros(3)}, ["unknown array", "extra.npy"]),
        ({"meta": np.array("{not json")}, ["meta is not JSON"]),
        ({"meta": np.array("[" * 100_000)}, ["meta is not JSON"]),
        ({"meta": np.array(b"{}")}, ["meta must be one JSON string"]),
        ({"meta": np.array(_meta(planner=None))}, ["meta.planner"]),
        ({"meta": np.array(_meta(planner=3))}, ["meta.planner", "got 3"]),
        ({"meta": np.array(_meta(scenario_key="x\ny"))}, ["meta.scenario_key", "'x\\ny'"]),
        ({"meta": np.array(_meta(plnner="PRM"))}, ["meta.plnner", "did you mean 'planner'"]),
    ],
)
def test_malformed_arrays_and_meta(tmp_path: Path, over: dict, needles: list[str]) -> None:
    _assert_clean(_write(tmp_path / "x.npz", **over), *needles)


def test_other_models_and_missing_file(tmp_path: Path) -> None:
    path = _write(tmp_path / "k.npz")
    with pytest.raises(RoadmapFileError, match="built for other models"):
        Roadmap.load(path, "other")
    with pytest.raises(RoadmapFileError, match="roadmap file not found"):
        Roadmap.load(tmp_path / "nope.npz")
    with pytest.raises(RoadmapFileError, match="not found"):
        Roadmap.load(tmp_path)  # a folder


def test_read_roadmap_arrays_returns_checked_arrays(tmp_path: Path) -> None:
    v, e, links, meta = read_roadmap_arrays(_write(tmp_path / "a.npz"))
    assert v.dtype == np.float64 and e.dtype == np.int64 and links.shape == (1, 2)
    assert meta["scenario_key"] == "k"


# ------------------------------------------------------------------ property tests
def _valid_bytes(tmp_path: Path) -> bytes:
    path = tmp_path / "valid.npz"
    Roadmap(_vertices(), np.array([[0, 1], [4, 5]]), np.array([[1, 2]]), "PRM", "k").save(path)
    return path.read_bytes()


BAD_META = st.one_of(
    st.just("[]"),
    st.just("3"),
    st.just('"dexplan-roadmap/1"'),
    st.text(max_size=30).filter(lambda t: not t.strip().startswith("{")),
    st.sampled_from(
        [
            _meta(format=None),
            _meta(format="dexplan-roadmap/0"),
            _meta(format=1),
            _meta(planner=None),
            _meta(planner=""),
            _meta(planner=["PRM"]),
            _meta(scenario_key=None),
            _meta(scenario_key=12),
            _meta(scenario_key="k" * 65),
            _meta(extra=1),
        ]
    ),
)


@st.composite
def malformed_roadmap(draw: st.DrawFn, valid: bytes) -> tuple[bytes | dict, str]:
    """(file bytes or arrays for np.savez, a string the error must contain)."""
    kind = draw(
        st.sampled_from(["bytes", "truncate", "vertices", "quat", "nonfinite", "edges", "meta"])
    )
    if kind == "bytes":
        data = draw(st.binary(max_size=512))
        return data, "not a roadmap"
    if kind == "truncate":
        return valid[: draw(st.integers(0, len(valid) - 1))], "not a "
    n = draw(st.integers(1, 12))
    v = _vertices(n)
    if kind == "vertices":
        bad = draw(
            st.sampled_from(
                [
                    np.zeros((n, draw(st.integers(0, 7)))),
                    np.zeros((n, 264)),
                    np.zeros(n),
                    np.zeros((n, WIDTH, 1)),
                    v.astype(np.int32),
                    v.astype(np.complex128),
                    v.astype(bool),
                    v.astype(str),
                ]
            )
        )
        return _arrays(vertices=bad, edges=EMPTY, links=EMPTY), "vertices"
    if kind == "quat":
        row = draw(st.integers(0, n - 1))
        v[row, 3:7] *= draw(st.sampled_from([0.0, 0.5, 1.01, 2.0, -3.0, 1e300]))
        return _arrays(vertices=v, edges=EMPTY, links=EMPTY), "quaternion"
    if kind == "nonfinite":
        v[draw(st.integers(0, n - 1)), draw(st.integers(0, WIDTH - 1))] = draw(
            st.sampled_from([np.nan, np.inf, -np.inf])
        )
        return _arrays(vertices=v, edges=EMPTY, links=EMPTY), "not finite"
    if kind == "edges":
        name = draw(st.sampled_from(["edges", "links"]))
        good = np.zeros((draw(st.integers(0, 5)), 2), dtype=np.int64)
        bad = draw(
            st.sampled_from(
                [
                    np.array([[0, n]]),
                    np.array([[n + 5, 0]]),
                    np.array([[-1, 0]]),
                    np.array([[0, 2**62]]),
                    np.zeros((2, 3), dtype=np.int64),
                    np.zeros(3, dtype=np.int64),
                    np.zeros((2, 2)),
                    np.array([["a", "b"]]),
                ]
            )
        )
        if bad.ndim == 2 and bad.shape[1] == 2 and bad.dtype.kind == "i":
            bad = np.vstack([good, bad])
        other = "links" if name == "edges" else "edges"
        return _arrays(vertices=v, **{name: bad, other: np.zeros((0, 2), np.int64)}), name
    return _arrays(vertices=v, meta=np.array(draw(BAD_META))), "meta"


def _check_malformed(tmp_path: Path, case: tuple[bytes | dict, str]) -> None:
    content, needle = case
    path = tmp_path / "bad.npz"
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        with open(path, "wb") as fh:
            np.savez(fh, **content)
    _assert_clean(path, needle)


@given(data=st.data())
def test_malformed_roadmaps_raise_clean_errors(tmp_path: Path, data: st.DataObject) -> None:
    _check_malformed(tmp_path, data.draw(malformed_roadmap(_valid_bytes(tmp_path))))


@pytest.mark.slow
@settings(max_examples=2000)
@given(data=st.data())
def test_malformed_roadmaps_raise_clean_errors_thorough(
    tmp_path: Path, data: st.DataObject
) -> None:
    _check_malformed(tmp_path, data.draw(malformed_roadmap(_valid_bytes(tmp_path))))


# ------------------------------------------------------------------------ CLI
@pytest.mark.parametrize(
    ("make", "needles"),
    [
        (lambda p: p.write_bytes(b""), ["bad.npz", "not a roadmap"]),
        (lambda p: _write(p, meta=np.array("[]")), ["meta"]),
        (lambda p: _write(p, vertices=np.zeros((4, 5))), ["vertices", "5 columns"]),
    ],
)
def test_cli_load_roadmap_bad_input(capfd, tmp_path: Path, make, needles: list[str]) -> None:
    bad = tmp_path / "bad.npz"
    make(bad)
    out = tmp_path / "p.json"
    code, _, err = run_cli(capfd, "plan", str(PAPER), "--load-roadmap", str(bad), "-o", str(out))
    assert_bad_input(code, err, names=needles, outputs=[out])


def test_cli_roadmap_of_another_hand_width(capfd, tmp_path: Path) -> None:
    """Right scenario key, wrong vertex width: exit 2 naming the vertices, one line.

    ``dexplan plan`` passes ``ambient_dim`` to :meth:`Roadmap.load`, so the
    width is refused before any progress line.
    """
    from dexplan.model.scenario import load_scenario
    from dexplan.planning.context import build_context
    from dexplan.planning.roadmap.graph import scenario_key

    key = scenario_key(build_context(load_scenario(PAPER)))
    bad = tmp_path / "wide.npz"
    Roadmap(_vertices(3, WIDTH + 1), EMPTY, EMPTY, "PRM", key).save(bad)
    out = tmp_path / "p.json"
    code, _, err = run_cli(capfd, "plan", str(PAPER), "--load-roadmap", str(bad), "-o", str(out))
    assert_bad_input(code, err, names=["vertices have 20 columns"], outputs=[out])
