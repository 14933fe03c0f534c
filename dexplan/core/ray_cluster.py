"""Joining a Ray cluster from ``--ray ADDRESS``: every form Ray accepts, or a one-line fix.

The forms (those of ``ray.init(address=...)``):

- ``local``: start a private cluster in this process (``ray.init()``);
- ``auto``: the cluster started on this machine with ``ray start --head``;
- ``HOST:PORT``: a cluster's GCS address (``ray start --head`` prints it;
  port 6379 by default), on this machine or another;
- ``ray://HOST:PORT``: a Ray Client server (port 10001; needs ``ray[client]``).

Token authentication: ``ray start --head`` turns it on when this machine
has a token (``~/.ray/auth_token``, made by any ``ray.init()`` cluster or
``ray get-auth-token --generate``). Ray sends the token for ``auto`` only;
with an explicit address it sends none and retries for some 20 s of
``InvalidAuthToken`` warnings. :func:`import_ray` turns token mode on whenever
a token is available (a cluster without authentication ignores it);
:func:`join_ray` checks the address first, keeps
Ray's native retry warnings off the terminal, and names the fix when the
cluster still refuses.
"""

from __future__ import annotations

import contextlib
import importlib
import logging
import os
import re
import socket
import sys
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path
from types import ModuleType
from typing import Any

from dexplan.core.errors import DependencyError, InvalidInputError, one_line
from dexplan.core.native_output import captured_stderr

__all__ = [
    "RAY_INSTALL",
    "RayAddress",
    "RayAddressKind",
    "check_listening",
    "import_ray",
    "join_ray",
    "parse_ray_address",
    "ray_token_available",
]

RAY_INSTALL = "pip install 'dexplan[ray]' (or pip install ray)"
"""How to install Ray."""

_FORMS = "local, auto, HOST:PORT (the GCS address ray start prints) or ray://HOST:PORT"
_HOSTPORT = re.compile(r"^(?P<host>[A-Za-z0-9_.\-]+|\[[0-9A-Fa-f:]+\]):(?P<port>[0-9]{1,5})$")


class RayAddressKind(StrEnum):
    """The forms of a ``--ray`` address."""

    LOCAL = "local"
    """Start a private cluster in this process."""
    AUTO = "auto"
    """The cluster ``ray start --head`` started on this machine."""
    GCS = "gcs"
    """``HOST:PORT``: a cluster's GCS address."""
    CLIENT = "client"
    """``ray://HOST:PORT``: a Ray Client server."""


@dataclass(frozen=True)
class RayAddress:
    """A checked ``--ray`` address.

    Attributes:
        text: the address as given (stripped).
        kind: its form.
        host, port: of a ``GCS`` or ``CLIENT`` address ("" and 0 otherwise).
    """

    text: str
    kind: RayAddressKind
    host: str = ""
    port: int = 0


def parse_ray_address(text: str, option: str = "--ray") -> RayAddress:
    """Check a ``--ray`` address's form.

    Raises:
        InvalidInputError: not one of the forms Ray accepts, with them listed
            (a dashboard ``http://`` address is named as such).
    """
    t = text.strip()
    if t in ("local", "auto"):
        return RayAddress(t, RayAddressKind(t))
    if t.startswith(("http://", "https://")):
        raise InvalidInputError(
            f"{option} {text!r}: that is the dashboard (jobs) address; give the cluster's "
            f"GCS address instead (HOST:6379, which ray start --head prints), or {_FORMS}"
        )
    client = t.startswith("ray://")
    m = _HOSTPORT.match(t[6:] if client else t)
    if m is None or not 0 < int(m["port"]) < 65536:
        raise InvalidInputError(f"{option} must be {_FORMS}; got {text!r}")
    host = m["host"].strip("[]")
    kind = RayAddressKind.CLIENT if client else RayAddressKind.GCS
    return RayAddress(t, kind, host, int(m["port"]))


def ray_token_available() -> bool:
    """True when Ray would find an authentication token on this machine.

    Where Ray looks: ``RAY_AUTH_TOKEN``, the file ``RAY_AUTH_TOKEN_PATH``
    names, else ``~/.ray/auth_token``.
    """
    if os.environ.get("RAY_AUTH_TOKEN", "").strip():
        return True
    path = os.environ.get("RAY_AUTH_TOKEN_PATH") or str(Path.home() / ".ray" / "auth_token")
    try:
        return bool(Path(path).read_text().strip())
    except OSError:
        return False


def check_listening(addr: RayAddress, option: str = "--ray") -> None:
    """Fail at once (not after Ray's retries) when nothing listens at ``HOST:PORT``.

    Raises:
        InvalidInputError: the connection is refused or times out (5 s).
    """
    try:
        with socket.create_connection((addr.host, addr.port), timeout=5.0):
            pass
    except OSError as exc:
        raise InvalidInputError(
            f"{option} {addr.text!r}: no Ray cluster answers there ({exc.strerror or exc}); "
            f"start one with ray start --head --port {addr.port}, or use {option} local"
        ) from exc


def import_ray(option: str = "--ray") -> ModuleType:
    """The ``ray`` module, in token authentication mode when this machine has a token.

    Ray sends its token for ``auto`` only; a cluster started by
    ``ray start --head`` on a machine with a token wants it for every
    address (a cluster without authentication ignores it). Ray reads
    ``RAY_AUTH_MODE`` when it is imported, so it is set first (unless the
    user set it); a Ray imported earlier has its configuration re-read.

    Raises:
        DependencyError: Ray is not installed.
    """
    imported = "ray" in sys.modules
    if "RAY_AUTH_MODE" not in os.environ and ray_token_available():
        os.environ["RAY_AUTH_MODE"] = "token"
    else:
        imported = False  # nothing changed: nothing to re-read
    try:
        ray = importlib.import_module("ray")
    except ImportError as exc:
        raise DependencyError(f"{option} needs Ray: {RAY_INSTALL}") from exc
    if imported:
        with contextlib.suppress(ImportError, AttributeError):  # what Ray itself calls
            importlib.import_module("ray._raylet").Config.initialize("")
    return ray


def join_ray(
    address: str, *, num_cpus: int | None = None, option: str = "--ray"
) -> tuple[ModuleType, bool]:
    """Start or join the Ray cluster ``address`` names, unless Ray is initialised already.

    Args:
        address: one of the forms in the module docstring.
        num_cpus: CPUs of a ``local`` cluster (None: this machine's).
        option: the option's name, for messages.

    Returns:
        The ``ray`` module, and whether this call initialised Ray (and so must
        shut it down).

    Raises:
        InvalidInputError: a malformed address, nothing listening there, or a
            cluster that refuses to be joined; the message says what to change.
        DependencyError: Ray (or, for ``ray://``, Ray Client) is not installed.
    """
    addr = parse_ray_address(address, option)
    ray = import_ray(option)
    if ray.is_initialized():
        return ray, False
    kwargs: dict[str, Any] = {
        "log_to_driver": False,
        "logging_level": logging.ERROR,
        "configure_logging": True,
    }
    if addr.kind == RayAddressKind.LOCAL:
        kwargs.update(num_cpus=num_cpus or os.cpu_count() or 1, include_dashboard=False)
        try:
            # not captured: the cluster's own processes would inherit the capture
            ray.init(**kwargs)
        except Exception as exc:
            raise InvalidInputError(_join_error(addr, option, exc, "")) from exc
        return ray, True
    kwargs["address"] = addr.text
    if addr.kind != RayAddressKind.AUTO:
        check_listening(addr, option)
    failure: Exception | None = None
    with captured_stderr() as native:  # Ray's native retry warnings, 20 s of them
        try:
            ray.init(**kwargs)
        except Exception as exc:  # no cluster, refused token, version mismatch, ...
            failure = exc
    if failure is not None:
        raise InvalidInputError(_join_error(addr, option, failure, native.text)) from failure
    return ray, True


def _join_error(addr: RayAddress, option: str, exc: Exception, native: str) -> str:
    """One line: why joining failed, and what to change."""
    text = f"{exc} {native}"
    where = f"{option} {addr.text!r}"
    if "InvalidAuthToken" in text or "Unauthenticated" in text:
        return (
            f"{where}: the cluster uses token authentication and refused this machine's "
            "token (or it has none): set RAY_AUTH_TOKEN to what ray get-auth-token prints "
            f"on the head node (or RAY_AUTH_TOKEN_PATH to its file), or run with {option} "
            "auto on the head node"
        )
    if "ray[client]" in text:
        return f"{where}: Ray Client addresses need pip install 'ray[client]'"
    if addr.kind == RayAddressKind.AUTO:
        return (
            f"{where}: no Ray cluster runs on this machine ({one_line(exc, 120)}); "
            f"start one with ray start --head, or use {option} local"
        )
    return f"{where}: cannot start or join a Ray cluster: {one_line(exc, 200)}"
