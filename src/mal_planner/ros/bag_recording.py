"""Crash-safe recording of a rosbag2 bag: one storage file, or a few split by size or duration.

Like ``ros2 bag record``, the bag directory holds ``<bag>_0.mcap``, ``<bag>_1.mcap``, ... (a new file after
``max_bytes`` or ``max_duration_s``) and ``metadata.yaml``. For crash safety the open file is written in place
and flushed every ``flush_s`` seconds (MCAP: the pending chunk is closed and written; sqlite3: a commit), and
``metadata.yaml`` is rewritten with what is on disk at each flush: a SIGKILL loses at most the last ``flush_s``.
The open file then has no MCAP summary or footer; :func:`mal_planner.ros.bag_recovery.recover_bag` ends it.

Each file is made by a rosbags ``Writer`` in the hidden ``.writing`` folder and hard-linked into the bag as soon
as it is created (sqlite would refuse to go on with a moved file, and keeps its rollback journal there). The
recorder holds an exclusive ``flock`` on the bag directory while it writes, so that a reader never repairs a bag
that is being recorded.
"""

from __future__ import annotations

import fcntl
import os
import shutil
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from rosbags.rosbag2 import Writer
from rosbags.rosbag2.metadata import dump_qos_v9
from rosbags.rosbag2.storage_mcap import McapWriter
from rosbags.rosbag2.storage_sqlite3 import Sqlite3Writer

from mal_planner.ros.bag_common import STORAGES, BagError, add_topic
from mal_planner.ros.transport import QoSProfile

STAGING = ".writing"
"""Hidden folder of the bag where rosbags makes each storage file before it is moved into the bag."""
FLUSH_S = 1.0
MAX_BAG_BYTES = 1 << 30
MAX_BAG_DURATION_S = 600.0


@dataclass
class TopicInfo:
    """One connection of the bag, as ``metadata.yaml`` lists it."""

    name: str
    msgtype: str
    qos: list[Any]
    """rosbags ``Qos`` profiles offered."""
    digest: str
    count: int = 0


@dataclass
class FileInfo:
    """One storage file of the bag: its name, its messages per topic and their time span [ns]."""

    name: str
    counts: dict[str, int] = field(default_factory=dict)
    start_ns: int = 2**63 - 1
    end_ns: int = 0


def bag_metadata(storage: str, topics: list[TopicInfo], files: list[FileInfo]) -> dict[str, Any]:
    """``metadata.yaml`` content (rosbag2 version 9, the keys rosbags' Writer writes) of a bag of ``files``."""
    totals = {t.name: sum(f.counts.get(t.name, 0) for f in files) for t in topics}
    with_msgs = [f for f in files if sum(f.counts.values())]
    start = min((f.start_ns for f in with_msgs), default=0)
    end = max((f.end_ns for f in with_msgs), default=0)
    info = {
        "version": 9,
        "storage_identifier": storage,
        "relative_file_paths": [f.name for f in files],
        "duration": {"nanoseconds": max(0, end - start)},
        "starting_time": {"nanoseconds_since_epoch": start},
        "message_count": sum(totals.values()),
        "topics_with_message_count": [
            {"topic_metadata": {"name": t.name, "type": t.msgtype, "serialization_format": "cdr",
                                "offered_qos_profiles": dump_qos_v9(t.qos), "type_description_hash": t.digest},
             "message_count": totals[t.name]} for t in topics],
        "compression_format": "",
        "compression_mode": "",
        "files": [_file_entry(f) for f in files],
        "custom_data": None,
        "ros_distro": "rosbags",
    }
    return {"rosbag2_bagfile_information": info}


def _file_entry(f: FileInfo) -> dict[str, Any]:
    count = sum(f.counts.values())
    return {"path": f.name, "starting_time": {"nanoseconds_since_epoch": f.start_ns if count else 0},
            "duration": {"nanoseconds": max(0, f.end_ns - f.start_ns)}, "message_count": count}


def write_metadata(bag: Path, metadata: dict[str, Any]) -> None:
    """Replace ``bag/metadata.yaml`` atomically (a reader sees the old or the new one, never half)."""
    tmp = bag / "metadata.yaml.tmp"
    with tmp.open("w", encoding="utf-8") as fh:
        yaml.safe_dump(metadata, fh, default_flow_style=False, sort_keys=False)
    os.replace(tmp, bag / "metadata.yaml")


def lock_bag(bag: Path, blocking: bool) -> int | None:
    """A descriptor holding an exclusive flock on the bag directory, or None when another process holds it."""
    fd = os.open(bag, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | (0 if blocking else fcntl.LOCK_NB))
    except BlockingIOError:
        os.close(fd)
        return None
    return fd


class RecordingBagWriter:
    """Writes a bag that survives a SIGKILL of its process (see the module docstring); thread-safe."""

    def __init__(self, path: str | Path, storage: str = "mcap", *, flush_s: float = FLUSH_S,
                 max_bytes: int = MAX_BAG_BYTES, max_duration_s: float = MAX_BAG_DURATION_S) -> None:
        self.path = Path(path)
        if storage not in STORAGES:
            raise BagError(f"unknown storage {storage!r} (expected mcap or sqlite3)")
        for name, value in (("flush period", flush_s), ("maximum size", max_bytes),
                            ("maximum duration", max_duration_s)):
            if not value > 0:
                raise BagError(f"the bag's {name} must be > 0, got {value!r}")
        if self.path.exists():
            raise BagError(f"{self.path} exists already, not overwriting")
        try:
            self.path.mkdir(parents=True)
        except OSError as exc:
            raise BagError(f"cannot create bag {self.path}: {exc.strerror}") from None
        self.storage, self.flush_s = storage, flush_s
        self.max_bytes, self.max_duration_s = max_bytes, max_duration_s
        self._lock_fd = lock_bag(self.path, blocking=True)
        self._lock = threading.Lock()
        self._topics: list[TopicInfo] = []
        self._specs: list[tuple[str, str, QoSProfile | None]] = []
        self._files: list[FileInfo] = []
        self._writer: Writer | None = None
        self._conns: list[Any] = []
        self._open_file()

    # -- files ----------------------------------------------------------------------------------------
    def _open_file(self) -> None:
        name = f"{self.path.name}_{len(self._files)}"
        staging = self.path / STAGING / name
        staging.parent.mkdir(exist_ok=True)
        try:
            writer = Writer(staging, version=Writer.VERSION_LATEST, storage_plugin=STORAGES[self.storage])
            writer.open()
        except Exception as exc:
            raise BagError(f"cannot create bag {self.path}: {exc}") from None
        assert writer.storage is not None
        os.link(writer.storage.path, self.path / writer.storage.path.name)
        self._writer = writer
        self._files.append(FileInfo(writer.storage.path.name))
        self._conns = [add_topic(writer, *spec) for spec in self._specs]
        self._opened = time.monotonic()
        self._flush()

    def _close_file(self) -> None:
        """Finish the open file (MCAP summary and footer; sqlite3 commit) and drop its staging folder."""
        self._snapshot()
        assert self._writer is not None
        staging = self._writer.path
        self._writer.close()
        self._writer = None
        shutil.rmtree(staging, ignore_errors=True)

    def _file_bytes(self) -> int:
        assert self._writer is not None and self._writer.storage is not None
        storage = self._writer.storage
        if isinstance(storage, McapWriter):
            return storage.bio.tell() + storage.chunk.bio.tell()
        return (self.path / self._files[-1].name).stat().st_size

    # -- topics and messages --------------------------------------------------------------------------
    def add_topic(self, topic: str, msgtype: str, qos: QoSProfile | None = None) -> int:
        """Add a connection (in this and every following file); returns its key for :meth:`write`."""
        with self._lock:
            assert self._writer is not None
            conn = add_topic(self._writer, topic, msgtype, qos)
            self._conns.append(conn)
            self._specs.append((topic, msgtype, qos))
            self._topics.append(TopicInfo(topic, msgtype, list(conn.ext.offered_qos_profiles), conn.digest))
            self._write_metadata()
            return len(self._topics) - 1

    def write(self, key: int, timestamp_ns: int, data: bytes) -> None:
        with self._lock:
            assert self._writer is not None
            self._writer.write(self._conns[key], timestamp_ns, data)
            self._unflushed += 1
        self.tick()

    def tick(self) -> None:
        """Flush and split when due (call it periodically, e.g. from the spin loop)."""
        with self._lock:
            if self._writer is None:
                return
            now = time.monotonic()
            if now - self._flushed >= self.flush_s and self._unflushed:
                self._flush()
            if sum(self._writer.counts.values()) and (now - self._opened >= self.max_duration_s
                                                      or self._file_bytes() >= self.max_bytes):
                self._close_file()
                self._write_metadata()
                self._open_file()
                self._write_metadata()

    def _flush(self) -> None:
        """Put every message written so far on disk and list it in ``metadata.yaml``."""
        assert self._writer is not None
        storage = self._writer.storage
        if isinstance(storage, McapWriter):
            if storage.chunk.bio.tell():
                storage.close_chunk()
            storage.bio.flush()
        elif isinstance(storage, Sqlite3Writer):
            storage.conn.commit()
        self._flushed, self._unflushed = time.monotonic(), 0
        self._write_metadata()

    def _snapshot(self) -> None:
        """The open file's counts and time span as written so far."""
        assert self._writer is not None
        current = self._files[-1]
        current.counts = {t.name: self._writer.counts[c.id] for t, c in zip(self._topics, self._conns, strict=True)}
        current.start_ns, current.end_ns = self._writer.min_timestamp, self._writer.max_timestamp

    def _write_metadata(self) -> None:
        if self._writer is not None:
            self._snapshot()
        write_metadata(self.path, bag_metadata(self.storage, self._topics, self._files))

    def close(self) -> None:
        """Finish the open file (an empty one is kept only as the bag's first) and ``metadata.yaml``."""
        with self._lock:
            if self._writer is None:
                return
            self._close_file()
            empty = not sum(self._files[-1].counts.values())
            if empty and len(self._files) > 1:
                (self.path / self._files.pop().name).unlink()
            write_metadata(self.path, bag_metadata(self.storage, self._topics, self._files))
            shutil.rmtree(self.path / STAGING, ignore_errors=True)
            if self._lock_fd is not None:
                os.close(self._lock_fd)
                self._lock_fd = None

    @property
    def files(self) -> list[str]:
        """Names of the bag's storage files so far."""
        return [f.name for f in self._files]
