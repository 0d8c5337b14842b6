"""Shared rosbag2 helpers (rosbags): topic types, bag writing/reading, (de)serialization for both backends.

Bags are real rosbag2 bags: a directory with ``metadata.yaml`` (what ``ros2 bag record`` makes), or a single
``.mcap``/``.db3`` storage file (which rosbags and ``ros2 bag play`` also read). Message definitions of our
``mal_msgs`` types go into the bag from the :func:`mal_msgs_py.typestore`.
"""

from __future__ import annotations

import fnmatch
import os
import shutil
import signal
import sys
import tempfile
import threading
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import yaml
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import StoragePlugin, Writer

import mal_msgs_py
from mal_planner.ros.transport import QOS_DEFAULT, QOS_LATCHED, QoSProfile

STATE_TYPE = "mal_msgs/msg/AircraftState"

#: Topic name patterns (relative, fnmatch) -> message type; first match wins.
TOPIC_TYPES: tuple[tuple[str, str], ...] = (
    ("aircraft/*/state", STATE_TYPE),
    ("aircraft/*/path", "nav_msgs/msg/Path"),
    ("radar/tracks", STATE_TYPE),
    ("landing_plan", "mal_msgs/msg/LandingPlan"),
    ("planner/markers", "visualization_msgs/msg/MarkerArray"),
    ("diagnostics", "diagnostic_msgs/msg/DiagnosticArray"),
    ("airspace/no_fly_zones", "mal_msgs/msg/NoFlyZone"),
)
#: Types published latched (TRANSIENT_LOCAL) by our nodes; subscribe to them with QOS_LATCHED.
LATCHED_TYPES = frozenset({"nav_msgs/msg/Path", "mal_msgs/msg/LandingPlan", "visualization_msgs/msg/MarkerArray"})
STORAGES = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}
_SUFFIX = {"mcap": ".mcap", "sqlite3": ".db3"}


class MsgTypes:
    """``node.types`` stand-in without a node: the ``mal_msgs_py`` classes (for writing bags directly)."""

    @staticmethod
    def msg(name: str) -> type:
        return mal_msgs_py.get_type(name)


class BagError(Exception):
    """A bag that cannot be written or read (the message names the file)."""


def topic_type(topic: str) -> str | None:
    """Message type of one of our topics (absolute or relative name, any namespace), or None."""
    name = topic.strip("/")
    for pattern, msgtype in TOPIC_TYPES:
        if fnmatch.fnmatchcase(name, pattern) or fnmatch.fnmatchcase(name, "*/" + pattern):
            return msgtype
    return None


def qos_for_type(msgtype: str) -> QoSProfile:
    """QoS our nodes use for a topic of this type (latched for plans, paths and markers)."""
    return QOS_LATCHED if msgtype in LATCHED_TYPES else QOS_DEFAULT


def bag_qos(profile: QoSProfile) -> list[Qos]:
    """rosbags ``offered_qos_profiles`` entry for one of our QoS profiles."""
    zero = QosTime(0, 0)
    return [
        Qos(
            QosHistory.KEEP_ALL if profile.keep_all else QosHistory.KEEP_LAST,
            profile.depth,
            QosReliability.RELIABLE if profile.reliable else QosReliability.BEST_EFFORT,
            QosDurability.TRANSIENT_LOCAL if profile.transient_local else QosDurability.VOLATILE,
            zero,
            zero,
            QosLiveliness.AUTOMATIC,
            zero,
            False,
        )
    ]


def open_writer(path: str | Path, storage: str = "mcap") -> Writer:
    """An opened rosbag2 writer (bag directory ``path``, format version 9); BagError if it cannot be made."""
    path = Path(path)
    if storage not in STORAGES:
        raise BagError(f"unknown storage {storage!r} (expected mcap or sqlite3)")
    if path.exists():
        raise BagError(f"{path} exists already, not overwriting")
    try:
        writer = Writer(path, version=Writer.VERSION_LATEST, storage_plugin=STORAGES[storage])
        writer.open()
    except Exception as exc:
        raise BagError(f"cannot create bag {path}: {exc}") from None
    return writer


def add_topic(writer: Writer, topic: str, msgtype: str, qos: QoSProfile | None = None) -> Any:
    """Add a connection with the type's definition from our typestore; returns the rosbags Connection."""
    return writer.add_connection(
        topic, msgtype, typestore=mal_msgs_py.typestore(), offered_qos_profiles=bag_qos(qos or qos_for_type(msgtype))
    )


class SplitBagWriter:
    """A rosbag2 bag written as a sequence of closed storage files, like ``ros2 bag record --max-bag-duration``.

    Each file is closed (indexed, footer written) after ``split_s`` seconds with messages, moved into the bag
    directory and ``metadata.yaml`` is rewritten (atomically) to list it: a SIGKILL loses at most the messages of
    the open file, the bag left behind is readable by rosbags and ``ros2 bag info``. The open file is written in
    the hidden ``.open`` folder of the bag (an unfinished MCAP there is what a kill leaves).
    """

    def __init__(self, path: str | Path, storage: str = "mcap", split_s: float = 1.0) -> None:
        self.path = Path(path)
        if storage not in STORAGES:
            raise BagError(f"unknown storage {storage!r} (expected mcap or sqlite3)")
        if not split_s > 0:
            raise BagError(f"split interval must be > 0 s, got {split_s!r}")
        if self.path.exists():
            raise BagError(f"{self.path} exists already, not overwriting")
        try:
            self.path.mkdir(parents=True)
        except OSError as exc:
            raise BagError(f"cannot create bag {self.path}: {exc.strerror}") from None
        self.storage, self.split_s = storage, split_s
        self._staging = self.path / ".open"
        self._topics: list[tuple[str, str, QoSProfile | None]] = []
        self._conns: list[Any] = []
        self._files: list[dict[str, Any]] = []  # metadata of the closed files, in order
        self._lock = threading.Lock()
        self._writer: Writer | None = None
        self._open_file()

    def _open_file(self) -> None:
        name = f"{self.path.name}_{len(self._files)}"
        shutil.rmtree(self._staging, ignore_errors=True)
        self._staging.mkdir()
        try:
            self._writer = Writer(self._staging / name, version=Writer.VERSION_LATEST,
                                  storage_plugin=STORAGES[self.storage])
            self._writer.open()
        except Exception as exc:
            raise BagError(f"cannot create bag {self.path}: {exc}") from None
        self._conns = [add_topic(self._writer, *topic) for topic in self._topics]
        self._count = 0
        self._opened = time.monotonic()

    def add_topic(self, topic: str, msgtype: str, qos: QoSProfile | None = None) -> int:
        """Add a connection (in this and every following file); returns its key for :meth:`write`."""
        with self._lock:
            assert self._writer is not None
            self._topics.append((topic, msgtype, qos))
            self._conns.append(add_topic(self._writer, topic, msgtype, qos))
            return len(self._topics) - 1

    def write(self, key: int, timestamp_ns: int, data: bytes) -> None:
        with self._lock:
            assert self._writer is not None
            self._writer.write(self._conns[key], timestamp_ns, data)
            self._count += 1
        self.maybe_split()

    def maybe_split(self) -> None:
        """Close the open file if it has messages and is ``split_s`` old (call it periodically)."""
        with self._lock:
            if self._writer is not None and self._count and time.monotonic() - self._opened >= self.split_s:
                self._close_file()
                self._open_file()

    def _close_file(self) -> None:
        assert self._writer is not None
        folder = self._writer.path
        self._writer.close()
        self._writer = None
        info = yaml.safe_load((folder / "metadata.yaml").read_text(encoding="utf-8"))["rosbag2_bagfile_information"]
        for rel in info["relative_file_paths"]:
            os.replace(folder / rel, self.path / rel)
        self._files.append(info)
        self._write_metadata()
        shutil.rmtree(self._staging, ignore_errors=True)

    def _write_metadata(self) -> None:
        """``metadata.yaml`` of all closed files (counts and times summed over them)."""
        files = self._files
        merged = dict(files[0])
        with_msgs = [f for f in files if f["message_count"]] or files[:1]
        start = min(f["starting_time"]["nanoseconds_since_epoch"] for f in with_msgs)
        end = max(f["starting_time"]["nanoseconds_since_epoch"] + f["duration"]["nanoseconds"] for f in with_msgs)
        counts: dict[str, int] = {}
        for f in files:
            for t in f["topics_with_message_count"]:
                name = t["topic_metadata"]["name"]
                counts[name] = counts.get(name, 0) + int(t["message_count"])
        merged |= {
            "relative_file_paths": [p for f in files for p in f["relative_file_paths"]],
            "files": [e for f in files for e in f["files"]],
            "message_count": sum(int(f["message_count"]) for f in files),
            "starting_time": {"nanoseconds_since_epoch": start},
            "duration": {"nanoseconds": end - start},
            "topics_with_message_count": [dict(t, message_count=counts[t["topic_metadata"]["name"]])
                                          for t in files[0]["topics_with_message_count"]],
        }
        tmp = self.path / "metadata.yaml.tmp"
        with tmp.open("w", encoding="utf-8") as fh:
            yaml.safe_dump({"rosbag2_bagfile_information": merged}, fh, default_flow_style=False, sort_keys=False)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, self.path / "metadata.yaml")

    def close(self) -> None:
        """Close the open file (an empty one only when it is the bag's first) and remove ``.open``."""
        with self._lock:
            if self._writer is None:
                return
            if self._count or not self._files:
                self._close_file()
            else:
                self._writer.close()
                self._writer = None
            shutil.rmtree(self._staging, ignore_errors=True)

    @property
    def files(self) -> int:
        """Closed storage files so far."""
        return len(self._files)


def write_bag(
    path: str | Path,
    topics: Iterable[tuple[str, str]],
    messages: Iterable[tuple[str, int, bytes]],
    storage: str = "mcap",
) -> Path:
    """Write ``(topic, timestamp_ns, cdr)`` messages on ``(topic, msgtype)`` connections to a bag.

    ``path`` ending in ``.mcap``/``.db3`` gives a single storage file (no metadata.yaml), any other path a
    rosbag2 directory.
    """
    path = Path(path)
    single = path.suffix in (".mcap", ".db3")
    if single and path.suffix != _SUFFIX.get(storage):
        raise BagError(f"{path}: suffix does not match storage {storage!r}")
    if single and path.exists():
        raise BagError(f"{path} exists already, not overwriting")
    with tempfile.TemporaryDirectory(dir=path.parent if path.parent.exists() else None) as tmp:
        bagdir = Path(tmp) / path.stem if single else path
        writer = open_writer(bagdir, storage)
        try:
            conns = {topic: add_topic(writer, topic, msgtype) for topic, msgtype in topics}
            for topic, stamp_ns, data in messages:
                writer.write(conns[topic], stamp_ns, data)
        finally:
            writer.close()
        if single:
            shutil.move(str(bagdir / (bagdir.name + _SUFFIX[storage])), str(path))
    return path


def serialize(msg: Any, msgtype: str) -> bytes:
    """CDR bytes (with encapsulation header) of a message of either backend."""
    store = mal_msgs_py.typestore()
    idl = sys.modules.get("cyclonedds.idl")  # never imported here: on rclpy, one Cyclone library is enough
    if idl is not None and isinstance(msg, idl.IdlStruct):  # mal_msgs_py class (built-in Cyclone backend)
        return bytes(store.serialize_cdr(mal_msgs_py.to_rosbags(msg), msgtype))
    if hasattr(type(msg), "__msgtype__"):  # a rosbags message
        return bytes(store.serialize_cdr(msg, msgtype))
    from rclpy.serialization import serialize_message  # an rclpy message

    return bytes(serialize_message(msg))


def to_backend(raw: bytes, msgtype: str, reader: Any, node: Any) -> Any:
    """Deserialize a bag message (``reader``: an open AnyReader) into the node's backend class."""
    if getattr(node, "backend", "cyclone") == "rclpy":
        from rclpy.serialization import deserialize_message

        return deserialize_message(raw, node.types.msg(msgtype))
    return mal_msgs_py.from_rosbags(reader.deserialize(raw, msgtype))


def open_reader(path: str | Path) -> Any:
    """An opened rosbags ``AnyReader`` for a rosbag2 directory or ``.mcap``/``.db3`` file; BagError otherwise."""
    from rosbags.highlevel import AnyReader

    path = Path(path)
    if not path.exists():
        raise BagError(f"cannot read bag {path}: no such file or directory")
    try:
        reader = AnyReader([path], default_typestore=mal_msgs_py.typestore())
        reader.open()
    except Exception as exc:
        detail = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise BagError(f"cannot read bag {path}: {detail}") from None
    return reader


def stop_event() -> threading.Event:
    """An event set by SIGINT/SIGTERM (install from the main thread); lets a spin loop end cleanly."""
    event = threading.Event()

    def handler(signum: int, frame: Any) -> None:
        event.set()

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
    return event
