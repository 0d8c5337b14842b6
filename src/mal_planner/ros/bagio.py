"""Shared rosbag2 helpers (rosbags): topic types, bag writing/reading, (de)serialization for both backends.

Bags are real rosbag2 bags: a directory with ``metadata.yaml`` (what ``ros2 bag record`` makes), or a single
``.mcap``/``.db3`` storage file (which rosbags and ``ros2 bag play`` also read). Message definitions of our
``mal_msgs`` types go into the bag from the :func:`mal_msgs_py.typestore`.
"""

from __future__ import annotations

import shutil
import signal
import sys
import tempfile
import threading
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from rosbags.rosbag2 import Writer

import mal_msgs_py
from mal_planner.ros.bag_common import (
    LATCHED_TYPES,
    STATE_TYPE,
    STORAGES,
    SUFFIX,
    TOPIC_TYPES,
    BagError,
    MsgTypes,
    add_topic,
    bag_qos,
    qos_for_type,
    topic_type,
)
from mal_planner.ros.bag_recording import RecordingBagWriter
from mal_planner.ros.bag_recovery import recover_bag

__all__ = [
    "LATCHED_TYPES", "STATE_TYPE", "STORAGES", "TOPIC_TYPES", "BagError", "MsgTypes", "RecordingBagWriter",
    "add_topic", "bag_qos", "open_reader", "open_writer", "qos_for_type", "recover_bag", "serialize",
    "stop_event", "to_backend", "topic_type", "write_bag",
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
    if single and path.suffix != SUFFIX.get(storage):
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
            shutil.move(str(bagdir / (bagdir.name + SUFFIX[storage])), str(path))
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
    """An opened rosbags ``AnyReader`` for a rosbag2 directory or ``.mcap``/``.db3`` file; BagError otherwise.

    A bag whose recorder was killed is recovered first (:func:`recover_bag`)."""
    from rosbags.highlevel import AnyReader

    path = Path(path)
    if not path.exists():
        raise BagError(f"cannot read bag {path}: no such file or directory")
    if path.is_dir():
        recover_bag(path)
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
