"""ROS 2 bags of a trajectory document: one self-contained MCAP file (``rosbags``).

:func:`write_bag` writes a ``dexplan-trajectory/1`` document
(:func:`~dexplan.execution.export.trajectory_document`) as a ROS 2 bag in the
MCAP storage format, the format ``ros2 bag play`` and Foxglove open directly:

- ``/joint_trajectory``, ``trajectory_msgs/msg/JointTrajectory``: one message, the plan;
- ``/joint_states``, ``sensor_msgs/msg/JointState``: one per sample;
- ``/object_pose``, ``geometry_msgs/msg/PoseStamped``: one per sample;
- ``/tf``, ``tf2_msgs/msg/TFMessage``: one per sample;
- ``/grip_force/finger_<i>``, ``geometry_msgs/msg/WrenchStamped``: one per
  sample at which finger ``i`` touches the object.

Stamps are the samples' ``time_from_start`` counted from time 0 (the bag is
the same bytes for the same plan). Frames: ``world`` (the plan's world, the
palm frame), ``object`` (the object's pose in ``world``) and ``contact_<i>``
(finger ``i``'s contact point on the object, axes of ``object``); a grip
force is published in its contact frame while the finger touches the object,
its torque the soft-contact torsional moment about the normal.

``rosbags`` (extra ``ros``) is pure Python: no ROS installation is needed to
write or read a bag. Only this module imports it.
"""

from __future__ import annotations

import importlib
import os
import shutil
import tempfile
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dexplan.core.errors import DependencyError, InvalidInputError

__all__ = [
    "BAG_SUFFIX",
    "CONTACT_FRAME",
    "OBJECT_FRAME",
    "WORLD_FRAME",
    "BagMessage",
    "bag_topics",
    "read_bag",
    "require_rosbags",
    "stamp_seconds",
    "write_bag",
]

BAG_SUFFIX = ".mcap"
"""The suffix of a bag file (``-o traj.mcap``)."""

WORLD_FRAME = "world"
"""TF frame of the plan's world (the palm frame of the builtin hands)."""

OBJECT_FRAME = "object"
"""TF frame of the object."""

CONTACT_FRAME = "contact_{}"
"""TF frame of finger ``i``'s contact point (``CONTACT_FRAME.format(i)``)."""

_TRAJECTORY = ("/joint_trajectory", "trajectory_msgs/msg/JointTrajectory")
_JOINT_STATES = ("/joint_states", "sensor_msgs/msg/JointState")
_OBJECT_POSE = ("/object_pose", "geometry_msgs/msg/PoseStamped")
_TF = ("/tf", "tf2_msgs/msg/TFMessage")
_WRENCH = "geometry_msgs/msg/WrenchStamped"
_PIP = "pip install 'dexplan[ros]' (or: pip install rosbags)"


@dataclass(frozen=True)
class BagMessage:
    """One message of a bag read back by :func:`read_bag`.

    Attributes:
        topic: its topic.
        msgtype: its ROS 2 type (``sensor_msgs/msg/JointState``).
        timestamp_ns: its log time (ns since the trajectory's start).
        message: the deserialized message (``rosbags`` message dataclass).
    """

    topic: str
    msgtype: str
    timestamp_ns: int
    message: Any


def _rosbags(module: str) -> Any:
    """Import a ``rosbags`` module, or say how to install it."""
    try:
        return importlib.import_module(f"rosbags.{module}")
    except ImportError as exc:
        raise DependencyError(f"ROS 2 bags need rosbags: {_PIP}") from exc


def require_rosbags() -> None:
    """Check, before any work, that bags can be written.

    Raises:
        DependencyError: ``rosbags`` is not installed (extra ``ros``).
    """
    _rosbags("rosbag2")


def _typestore() -> Any:
    """The ROS 2 Humble message definitions (the types above are the same in later distros)."""
    typesys = _rosbags("typesys")
    return typesys.get_typestore(typesys.Stores.ROS2_HUMBLE)


def bag_topics(doc: Mapping[str, Any]) -> list[tuple[str, str]]:
    """The ``(topic, type)`` pairs a bag of ``doc`` has, in the order they are added."""
    n = len(doc["fingertip_frames"])
    fingers = [(f"/grip_force/finger_{i}", _WRENCH) for i in range(n)]
    return [_TRAJECTORY, _JOINT_STATES, _OBJECT_POSE, _TF, *fingers]


def _ns(seconds: float) -> int:
    """Seconds as integer nanoseconds (rounded: 0.01 s is 10_000_000 ns exactly)."""
    return round(seconds * 1e9)


class _Messages:
    """The messages of one trajectory document, built with a typestore's classes."""

    def __init__(self, doc: Mapping[str, Any], store: Any) -> None:
        self.doc = doc
        self.types = store.types
        self.joints = list(doc["joint_names"])

    def _msg(self, msgtype: str, /, **fields: Any) -> Any:
        return self.types[msgtype](**fields)

    def stamp(self, ns: int) -> Any:
        return self._msg("builtin_interfaces/msg/Time", sec=ns // 10**9, nanosec=ns % 10**9)

    def header(self, ns: int, frame: str) -> Any:
        return self._msg("std_msgs/msg/Header", stamp=self.stamp(ns), frame_id=frame)

    def vector(self, v: Sequence[float]) -> Any:
        return self._msg("geometry_msgs/msg/Vector3", x=v[0], y=v[1], z=v[2])

    def quaternion(self, q: Sequence[float]) -> Any:
        return self._msg("geometry_msgs/msg/Quaternion", x=q[0], y=q[1], z=q[2], w=q[3])

    def transform(self, ns: int, parent: str, child: str, xyzquat: Sequence[float]) -> Any:
        tr = self._msg(
            "geometry_msgs/msg/Transform",
            translation=self.vector(xyzquat[:3]),
            rotation=self.quaternion(xyzquat[3:]),
        )
        return self._msg(
            "geometry_msgs/msg/TransformStamped",
            header=self.header(ns, parent),
            child_frame_id=child,
            transform=tr,
        )

    def trajectory(self) -> Any:
        """The whole plan as one ``JointTrajectory`` (effort: the joint torques)."""
        points = []
        for p in self.doc["points"]:
            ns = _ns(p["time_from_start"])
            points.append(
                self._msg(
                    "trajectory_msgs/msg/JointTrajectoryPoint",
                    positions=np.asarray(p["positions"], dtype=np.float64),
                    velocities=np.asarray(p["velocities"], dtype=np.float64),
                    accelerations=np.asarray(p["accelerations"], dtype=np.float64),
                    effort=np.asarray(p["joint_torques"], dtype=np.float64),
                    time_from_start=self._msg(
                        "builtin_interfaces/msg/Duration", sec=ns // 10**9, nanosec=ns % 10**9
                    ),
                )
            )
        return self._msg(
            "trajectory_msgs/msg/JointTrajectory",
            header=self.header(0, WORLD_FRAME),
            joint_names=self.joints,
            points=points,
        )

    def sample(self, p: Mapping[str, Any]) -> Iterator[tuple[str, Any]]:
        """The ``(topic, message)`` pairs of one sample."""
        ns = _ns(p["time_from_start"])
        yield (
            _JOINT_STATES[0],
            self._msg(
                "sensor_msgs/msg/JointState",
                header=self.header(ns, ""),
                name=self.joints,
                position=np.asarray(p["positions"], dtype=np.float64),
                velocity=np.asarray(p["velocities"], dtype=np.float64),
                effort=np.asarray(p["joint_torques"], dtype=np.float64),
            ),
        )
        pose = p["object_pose_xyzquat"]
        point = self._msg("geometry_msgs/msg/Point", x=pose[0], y=pose[1], z=pose[2])
        yield (
            _OBJECT_POSE[0],
            self._msg(
                "geometry_msgs/msg/PoseStamped",
                header=self.header(ns, WORLD_FRAME),
                pose=self._msg(
                    "geometry_msgs/msg/Pose", position=point, orientation=self.quaternion(pose[3:])
                ),
            ),
        )
        transforms = [self.transform(ns, WORLD_FRAME, OBJECT_FRAME, pose)]
        for i, (c, f) in enumerate(zip(p["contacts"], p["grip_forces"], strict=True)):
            if c is None or f is None:  # a free finger: no contact frame, no force
                continue
            frame = CONTACT_FRAME.format(i)
            transforms.append(self.transform(ns, OBJECT_FRAME, frame, [*c, 0.0, 0.0, 0.0, 1.0]))
            yield f"/grip_force/finger_{i}", self._wrench(ns, frame, f, p, i)
        yield _TF[0], self._msg("tf2_msgs/msg/TFMessage", transforms=transforms)

    def _wrench(
        self, ns: int, frame: str, force: Sequence[float], p: Mapping[str, Any], i: int
    ) -> Any:
        """Finger ``i``'s grip force at its contact; torque: the torsional moment (normal)."""
        tm, n = p["torsional_moments"][i], p["contact_normals"][i]
        torque = [0.0] * 3 if tm is None or n is None else [tm * v for v in n]
        wrench = self._msg(
            "geometry_msgs/msg/Wrench", force=self.vector(force), torque=self.vector(torque)
        )
        return self._msg(
            "geometry_msgs/msg/WrenchStamped", header=self.header(ns, frame), wrench=wrench
        )


def write_bag(path: str | Path, doc: Mapping[str, Any]) -> dict[str, int]:
    """Write a trajectory document as a ROS 2 MCAP bag; the message count of each topic.

    The bag is written in a temporary folder next to ``path`` and its MCAP
    file renamed to ``path`` when complete: an error or Ctrl-C leaves no
    partial file. The MCAP file carries the message definitions and the
    rosbag2 metadata, so it plays without the ``metadata.yaml`` of a bag folder.

    Raises:
        InvalidInputError: ``path`` does not end in ``.mcap`` or its folder is missing.
        DependencyError: ``rosbags`` is not installed (extra ``ros``).
        OSError: the file cannot be written.
    """
    path = Path(path)
    if path.suffix.lower() != BAG_SUFFIX:
        raise InvalidInputError(f"-o: a ROS 2 bag must end in .mcap, got {str(path)!r}")
    folder = path.resolve().parent
    if not folder.is_dir():
        raise InvalidInputError(f"bag folder does not exist: {str(folder)!r}")
    rosbag2 = _rosbags("rosbag2")
    store = _typestore()
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder))
    try:
        bag = tmp / "bag"
        counts = _write(rosbag2.Writer(bag, version=9, storage_plugin=rosbag2.StoragePlugin.MCAP),
                        doc, store)  # fmt: skip
        mcap = bag / "bag.mcap"
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(mcap, 0o666 & ~umask)
        os.replace(mcap, path)
        return counts
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _write(writer: Any, doc: Mapping[str, Any], store: Any) -> dict[str, int]:
    """Write every message of ``doc`` with an unopened ``rosbags`` writer."""
    build = _Messages(doc, store)
    counts = dict.fromkeys((t for t, _ in bag_topics(doc)), 0)
    with writer:
        conns = {
            topic: writer.add_connection(topic, msgtype, typestore=store)
            for topic, msgtype in bag_topics(doc)
        }

        def put(topic: str, ns: int, msg: Any) -> None:
            writer.write(conns[topic], ns, store.serialize_cdr(msg, msg.__msgtype__))
            counts[topic] += 1

        put(_TRAJECTORY[0], 0, build.trajectory())
        for p in doc["points"]:
            ns = _ns(p["time_from_start"])
            for topic, msg in build.sample(p):
                put(topic, ns, msg)
    return counts


def read_bag(path: str | Path) -> list[BagMessage]:
    """Every message of a single-file ROS 2 MCAP bag, in log-time order.

    Raises:
        DependencyError: ``rosbags`` is not installed (extra ``ros``).
        InvalidInputError: the file is not a ROS 2 MCAP bag.
    """
    mcap = _rosbags("rosbag2.storage_mcap")
    errors = _rosbags("rosbag2.errors")
    store = _typestore()
    reader = mcap.McapReader(Path(path))
    try:
        reader.open()
    except (errors.ReaderError, OSError, ValueError) as exc:
        raise InvalidInputError(f"{str(path)!r} is not a ROS 2 MCAP bag: {exc}") from exc
    try:
        return [
            BagMessage(c.topic, c.msgtype, t, store.deserialize_cdr(data, c.msgtype))
            for c, t, data in reader.messages(reader.connections)
        ]
    finally:
        reader.close()


def stamp_seconds(stamp: Any) -> float:
    """A ``builtin_interfaces`` time or duration in seconds."""
    return int(stamp.sec) + int(stamp.nanosec) * 1e-9
