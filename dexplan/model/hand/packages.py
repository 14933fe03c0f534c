"""``package://`` mesh URIs resolved as ROS does, and the hashes that pin the meshes.

A URDF from a ROS description package names its meshes
``package://<package>/<path>``. Pinocchio resolves such a URI against a list
of folders: the first ``<folder>/<package>/<path>`` that exists. dexplan hands
it, in this order (:func:`search_dirs`):

1. the folders the caller gives (the URDF's own folder; ``[hand]
   package_dirs`` of a scenario; a plan file's folder);
2. ``ROS_PACKAGE_PATH`` (``--package-dir`` of ``dexplan verify``, ``show``,
   ``export`` and ``replay`` is prepended to it, :func:`package_search_path`):
   each entry, the folder holding it (an entry may be a package itself) and
   the folders holding the packages found below it (``package.xml``, two
   levels deep, as ROS crawls a workspace);
3. the ``share`` folders of installed description wheels: example-robot-data's
   (``cmeel.prefix/share``, where every cmeel-packaged description installs),
   and the folder holding each installed Python package of
   :data:`PYTHON_DESCRIPTION_PACKAGES` (``package://gymnasium_robotics/...``
   names a file of the gymnasium-robotics wheel, the Shadow hand's MJCF).

A plan file keeps the URDF's URIs exactly as given, so it does not depend on
the folders of the machine that made it, and records the SHA-256 of every
collision mesh by URI (:func:`mesh_sha256`); ``dexplan verify`` elsewhere
resolves the URIs its own way and refuses a mesh whose bytes differ.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib.util
import os
import xml.etree.ElementTree as ET
from collections.abc import Iterator, Mapping, Sequence
from importlib import metadata
from pathlib import Path

__all__ = [
    "ROS_PACKAGE_PATH",
    "collision_mesh_uris",
    "mesh_mismatches",
    "mesh_sha256",
    "package_search_path",
    "package_uri",
    "resolve_mesh",
    "search_dirs",
    "wheel_share_dirs",
]

#: The environment variable ROS reads its package folders from.
ROS_PACKAGE_PATH = "ROS_PACKAGE_PATH"
_PACKAGE = "package://"
#: Python packages whose installed files ``package://<name>/...`` URIs may name.
PYTHON_DESCRIPTION_PACKAGES: tuple[str, ...] = ("gymnasium_robotics",)


def python_package_dirs() -> dict[str, Path]:
    """Installed folder of each package of :data:`PYTHON_DESCRIPTION_PACKAGES`.

    Found with :func:`importlib.util.find_spec`, which does not import the package.
    """
    out = {}
    for name in PYTHON_DESCRIPTION_PACKAGES:
        try:
            spec = importlib.util.find_spec(name)
        except (ImportError, ValueError):
            spec = None
        locations = list(spec.submodule_search_locations or []) if spec is not None else []
        if locations and Path(locations[0]).is_dir():
            out[name] = Path(locations[0])
    return out


def package_uri(path: Path) -> str | None:
    """``package://<name>/<path>`` for a file inside a :func:`python_package_dirs` folder."""
    resolved = path.resolve()
    for name, folder in python_package_dirs().items():
        try:
            rel = resolved.relative_to(folder.resolve())
        except ValueError:
            continue
        return f"{_PACKAGE}{name}/{rel.as_posix()}"
    return None


def wheel_share_dirs() -> list[Path]:
    """``share`` folders of installed description wheels (example-robot-data's)."""
    try:
        dist = metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        return []
    share = Path(str(dist.locate_file("cmeel.prefix/share")))
    return [share] if share.is_dir() else []


def _ros_dirs(value: str) -> list[Path]:
    """Folders one ``ROS_PACKAGE_PATH`` value contributes (see the module docstring)."""
    out: list[Path] = []
    for entry in value.split(os.pathsep):
        if not entry:
            continue
        root = Path(entry).expanduser()
        out += [root, root.parent]
        if root.is_dir():
            # sorted: the same folders in the same order on every run
            for pattern in ("*/package.xml", "*/*/package.xml"):
                out += [p.parent.parent for p in sorted(root.glob(pattern))]
    return out


def search_dirs(given: Sequence[str | Path] = ()) -> tuple[str, ...]:
    """The folders ``package://`` URIs and relative mesh paths are searched in, in order.

    Args:
        given: the caller's folders, searched first.

    Returns:
        ``given``, then ``ROS_PACKAGE_PATH``'s folders, then the wheels'
        ``share`` folders and Python package folders' parents, each once.
    """
    dirs = [Path(d) for d in given]
    dirs += _ros_dirs(os.environ.get(ROS_PACKAGE_PATH, ""))
    dirs += wheel_share_dirs()
    dirs += [folder.parent for folder in python_package_dirs().values()]
    return tuple(dict.fromkeys(str(d) for d in dirs))


@contextlib.contextmanager
def package_search_path(dirs: Sequence[str | Path]) -> Iterator[None]:
    """``dirs`` prepended to ``ROS_PACKAGE_PATH`` for the duration (restored after).

    What ``--package-dir`` does: every hand built inside, whichever command
    builds it, searches those folders too.
    """
    old = os.environ.get(ROS_PACKAGE_PATH)
    parts = [str(Path(d).expanduser().resolve()) for d in dirs]
    os.environ[ROS_PACKAGE_PATH] = os.pathsep.join(parts + ([old] if old else []))
    try:
        yield
    finally:
        if old is None:
            os.environ.pop(ROS_PACKAGE_PATH, None)
        else:
            os.environ[ROS_PACKAGE_PATH] = old


def resolve_mesh(uri: str, dirs: Sequence[str | Path]) -> Path | None:
    """The file a URDF mesh ``filename`` names, as Pinocchio finds it, or None.

    ``package://<package>/<path>`` and relative paths: the first
    ``<dir>/<package>/<path>`` (``<dir>/<path>``) that is a file; ``file://``
    and absolute paths: the path itself.
    """
    if uri.startswith("file://"):
        uri = uri[len("file://") :]
    rel = uri[len(_PACKAGE) :] if uri.startswith(_PACKAGE) else uri
    if os.path.isabs(rel):
        return Path(rel) if Path(rel).is_file() else None
    for d in dirs:
        path = Path(d) / rel
        if path.is_file():
            return path
    return None


def collision_mesh_uris(urdf_xml: str) -> list[str]:
    """The ``filename`` of every ``<collision>`` mesh of a URDF, in file order, each once."""
    try:
        root = ET.fromstring(urdf_xml)
    except ET.ParseError:
        return []
    uris = [
        m.get("filename", "")
        for col in root.iter("collision")
        for m in col.iter("mesh")
        if m.get("filename")
    ]
    return list(dict.fromkeys(uris))


def mesh_sha256(urdf_xml: str, dirs: Sequence[str | Path]) -> dict[str, str]:
    """SHA-256 (hex) of each collision mesh of a URDF, by URI as the URDF gives it.

    Meshes that do not resolve are left out (the hand does not build without them).
    """
    out: dict[str, str] = {}
    for uri in collision_mesh_uris(urdf_xml):
        path = resolve_mesh(uri, dirs)
        if path is not None:
            out[uri] = hashlib.sha256(path.read_bytes()).hexdigest()
    return out


def mesh_mismatches(
    recorded: Mapping[str, str], found: Mapping[str, str], dirs: Sequence[str | Path]
) -> list[str]:
    """One line per recorded mesh whose file here differs from the one the plan was made with."""
    out = []
    for uri, digest in recorded.items():
        here = found.get(uri)
        if here is not None and here != digest:
            path = resolve_mesh(uri, dirs)
            out.append(
                f"mesh {uri!r} resolves to {str(path)!r} whose SHA-256 {here[:12]}... differs "
                f"from the plan's {digest[:12]}... (give the folder with the plan's meshes "
                "with --package-dir)"
            )
    return out
