"""Recovery of a bag whose recorder was killed, like ``ros2 bag reindex``: the open storage file is ended and
``metadata.yaml`` is rebuilt from what the storage files hold.

A killed :class:`~mal_planner.ros.bag_recording.RecordingBagWriter` leaves its ``.writing`` folder and an MCAP
file without summary and footer, possibly with a record cut short at its end. Recovery cuts the file after
its last whole record and appends a data-end record and a footer without summary (the MCAP specification's
form for a file without one: rosbags and rosbag2's MCAP plugin then scan the data section). A sqlite3 file gets
back its rollback journal, which sqlite left in ``.writing``, so that an interrupted commit is undone.
"""

from __future__ import annotations

import logging
import os
import re
import shutil
import sqlite3
import struct
from pathlib import Path
from typing import Any

import yaml
from rosbags.rosbag2.metadata import parse_qos
from rosbags.rosbag2.storage_mcap import McapReader
from rosbags.rosbag2.storage_sqlite3 import Sqlite3Reader

import mal_msgs_py
from mal_planner.ros.bag_common import SUFFIX, BagError
from mal_planner.ros.bag_recording import STAGING, FileInfo, TopicInfo, bag_metadata, lock_bag, write_metadata

_LOG = logging.getLogger(__name__)
MCAP_MAGIC = b"\x89MCAP0\r\n"
_OP_FOOTER, _OP_DATA_END = 0x02, 0x0F
_RECORD_HEAD = struct.Struct("<BQ")
"""Opcode and body length of an MCAP record."""


def recover_bag(bag: str | Path) -> bool:
    """End the storage files and rebuild ``metadata.yaml`` of a bag left by a killed recorder; True if it was one.

    BagError when a live recorder is still writing the bag (it holds the bag directory's flock).
    """
    bag = Path(bag)
    if not (bag / STAGING).exists():
        return False
    fd = lock_bag(bag, blocking=False)
    if fd is None:
        raise BagError(f"cannot read bag {bag}: it is being recorded")
    try:
        if not (bag / STAGING).exists():  # its recorder closed it meanwhile
            return False
        _restore_journals(bag)
        files = [f for f in _storage_files(bag) if _keep(f)]
        cut = sum(end_mcap_file(f) for f in files if f.suffix == SUFFIX["mcap"])
        storage = "sqlite3" if files and files[0].suffix == SUFFIX["sqlite3"] else "mcap"
        write_metadata(bag, _rebuilt_metadata(bag, storage, files))
        shutil.rmtree(bag / STAGING, ignore_errors=True)
    finally:
        os.close(fd)
    _LOG.warning("recovered bag %s left by a killed recorder (%d file(s), %d bytes of a cut record dropped)",
                 bag, len(files), cut)
    return True


def _storage_files(bag: Path) -> list[Path]:
    """``<bag>_<n>.mcap``/``.db3`` of the bag, in the order of ``n``."""
    pattern = re.compile(re.escape(bag.name) + r"_(\d+)\.(mcap|db3)$")
    found = [(int(m.group(1)), p) for p in bag.iterdir() if (m := pattern.match(p.name))]
    return [p for _, p in sorted(found)]


def _restore_journals(bag: Path) -> None:
    """Put sqlite's rollback journals next to their files and let sqlite undo the interrupted transaction."""
    for journal in (bag / STAGING).glob("*/*.db3-journal"):
        restored = bag / journal.name
        os.replace(journal, restored)
        db = sqlite3.connect(bag / journal.name.removesuffix("-journal"))
        try:
            db.execute("SELECT count(*) FROM sqlite_master").fetchall()  # a read rolls a hot journal back
        finally:
            db.close()
        restored.unlink(missing_ok=True)  # still there: not hot (nothing of it had reached the file)


def _keep(path: Path) -> bool:
    """False (and the file removed) for an MCAP file killed before its header reached the disk."""
    if path.suffix == SUFFIX["mcap"] and path.stat().st_size <= len(MCAP_MAGIC):
        path.unlink()
        return False
    return True


def end_mcap_file(path: Path) -> int:
    """Give an MCAP file cut short a data end and a footer; returns the bytes of a cut record dropped (0 for a
    file that has its footer)."""
    with path.open("r+b") as fh:
        size = fh.seek(0, os.SEEK_END)
        if size >= 2 * len(MCAP_MAGIC):
            fh.seek(size - len(MCAP_MAGIC))
            if fh.read(len(MCAP_MAGIC)) == MCAP_MAGIC:
                return 0
        fh.seek(0)
        if fh.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            raise BagError(f"cannot recover {path}: not an MCAP file")
        end = _end_of_whole_records(fh, size)
        fh.truncate(end)
        fh.seek(end)
        fh.write(_RECORD_HEAD.pack(_OP_DATA_END, 4) + struct.pack("<I", 0))  # no data section CRC
        fh.write(_RECORD_HEAD.pack(_OP_FOOTER, 20) + struct.pack("<QQI", 0, 0, 0))  # no summary
        fh.write(MCAP_MAGIC)
    return size - end


def _end_of_whole_records(fh: Any, size: int) -> int:
    """Offset after the data section's last whole record (before a data-end record, if one was written)."""
    pos = len(MCAP_MAGIC)
    while pos + _RECORD_HEAD.size <= size:
        fh.seek(pos)
        op, length = _RECORD_HEAD.unpack(fh.read(_RECORD_HEAD.size))
        end = pos + _RECORD_HEAD.size + length
        if op in (0, _OP_DATA_END) or end > size:
            break
        pos = end
    return pos


def _rebuilt_metadata(bag: Path, storage: str, files: list[Path]) -> dict[str, Any]:
    """Metadata of what the storage files hold; the topics as the recorder listed them, if it did."""
    topics = {t.name: t for t in _listed_topics(bag)}
    infos: list[FileInfo] = []
    for path in files:
        reader = (McapReader if storage == "mcap" else Sqlite3Reader)(path)
        reader.open()
        try:
            info = FileInfo(path.name, {c.topic: c.msgcount for c in reader.connections},
                            reader.metadata.start_time, max(0, reader.metadata.end_time - 1))
            for c in reader.connections:
                topics.setdefault(c.topic, TopicInfo(c.topic, c.msgtype, list(c.ext.offered_qos_profiles),
                                                     c.digest or _type_hash(c.msgtype)))
        finally:
            reader.close()
        infos.append(info)
    return bag_metadata(storage, list(topics.values()), infos)


def _listed_topics(bag: Path) -> list[TopicInfo]:
    """The topics of the bag's ``metadata.yaml`` (none if it has none)."""
    path = bag / "metadata.yaml"
    if not path.exists():
        return []
    info = yaml.safe_load(path.read_text(encoding="utf-8"))["rosbag2_bagfile_information"]
    return [TopicInfo(m["name"], m["type"], parse_qos(m.get("offered_qos_profiles", [])),
                      m.get("type_description_hash", ""))
            for m in (t["topic_metadata"] for t in info["topics_with_message_count"])]


def _type_hash(msgtype: str) -> str:
    try:
        return mal_msgs_py.type_hash(msgtype)
    except KeyError:
        return ""
