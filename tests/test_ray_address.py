"""``--ray ADDRESS``: every form Ray accepts is understood, anything else is a one-line fix.

No Ray cluster is started here (slow, and racy on shared CI machines); joining
one is covered by test_bench's Ray backend test where Ray is installed.
"""

from __future__ import annotations

import os
import socket
import sys
import types

import pytest
from cli_contract import assert_bad_input, run_cli

from dexplan.core.errors import InvalidInputError
from dexplan.core.ray_cluster import (
    RayAddressKind,
    import_ray,
    join_ray,
    parse_ray_address,
    ray_token_available,
)


@pytest.mark.parametrize(
    ("text", "kind", "host", "port"),
    [
        ("local", RayAddressKind.LOCAL, "", 0),
        ("auto", RayAddressKind.AUTO, "", 0),
        ("127.0.0.1:6379", RayAddressKind.GCS, "127.0.0.1", 6379),
        ("head-node.cluster:6380", RayAddressKind.GCS, "head-node.cluster", 6380),
        ("[::1]:6379", RayAddressKind.GCS, "::1", 6379),
        ("ray://10.0.0.5:10001", RayAddressKind.CLIENT, "10.0.0.5", 10001),
    ],
)
def test_address_forms(text, kind, host, port) -> None:
    a = parse_ray_address(f" {text} ")
    assert (a.kind, a.host, a.port) == (kind, host, port)


@pytest.mark.parametrize(
    ("text", "names"),
    [
        ("127.0.0.1", ["must be local, auto, HOST:PORT", "'127.0.0.1'"]),
        ("host:99999", ["must be local, auto"]),
        ("http://127.0.0.1:8265", ["dashboard", "GCS address"]),
        ("", ["must be local"]),
    ],
)
def test_bad_forms_name_the_accepted_ones(text, names) -> None:
    with pytest.raises(InvalidInputError) as exc:
        parse_ray_address(text)
    for name in names:
        assert name in str(exc.value)


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]  # closed again when the block ends


def test_nothing_listening_fails_at_once_with_the_fix(monkeypatch) -> None:
    fake = types.ModuleType("ray")
    fake.is_initialized = lambda: False  # type: ignore[attr-defined]
    fake.init = lambda **kw: pytest.fail("ray.init must not be tried")  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "ray", fake)
    port = _closed_port()
    with pytest.raises(InvalidInputError, match=f"ray start --head --port {port}"):
        join_ray(f"127.0.0.1:{port}")


def test_token_mode_follows_the_token(tmp_path, monkeypatch) -> None:
    """Ray sends its token for ``auto`` only; dexplan sends it for every address."""
    fake = types.ModuleType("ray")
    monkeypatch.setitem(sys.modules, "ray", fake)
    monkeypatch.delenv("RAY_AUTH_MODE", raising=False)
    monkeypatch.delenv("RAY_AUTH_TOKEN", raising=False)
    monkeypatch.setenv("RAY_AUTH_TOKEN_PATH", str(tmp_path / "none"))
    assert not ray_token_available()
    import_ray()
    assert "RAY_AUTH_MODE" not in os.environ
    (tmp_path / "token").write_text("abc123\n")
    monkeypatch.setenv("RAY_AUTH_TOKEN_PATH", str(tmp_path / "token"))
    assert ray_token_available()
    assert import_ray() is fake
    assert os.environ["RAY_AUTH_MODE"] == "token"
    monkeypatch.setenv("RAY_AUTH_MODE", "disabled")  # the user's choice is kept
    import_ray()
    assert os.environ["RAY_AUTH_MODE"] == "disabled"


def test_no_local_cluster_names_the_fix(monkeypatch) -> None:
    fake = types.ModuleType("ray")
    fake.is_initialized = lambda: False  # type: ignore[attr-defined]

    def refuse(**kw):
        raise ConnectionError("Failed to connect to Ray cluster at 192.0.2.2:6390")

    fake.init = refuse  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "ray", fake)
    monkeypatch.setattr(
        "dexplan.core.ray_cluster.check_listening", lambda addr, option="--ray": None
    )
    with pytest.raises(InvalidInputError) as exc:
        join_ray("auto")
    assert "no Ray cluster runs on this machine" in str(exc.value)
    assert "ray start --head" in str(exc.value)


def test_cli_bad_address_is_one_line(capfd, tmp_path) -> None:
    out = tmp_path / "rm.npz"
    code, _, err = run_cli(
        capfd, "roadmap", "build", "--nodes", "5", "--ray", "127.0.0.1", "-o", out
    )
    assert_bad_input(code, err, names=["--ray", "HOST:PORT"], outputs=[out])
