"""The recorder's bag storage without DDS: one storage file (or a few, split by size or duration), flushed every
``flush_s`` so that a SIGKILL loses at most that much, and recovered when it is read (rosbags)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mal_planner.ros.bag_recovery import MCAP_MAGIC, end_mcap_file
from mal_planner.ros.bagio import BagError, RecordingBagWriter, open_reader, serialize

STRING = "std_msgs/msg/String"

WRITER = """
import sys, time
import mal_msgs_py
from mal_planner.ros.bagio import RecordingBagWriter, serialize
writer = RecordingBagWriter(sys.argv[1], sys.argv[2], flush_s=0.5, max_duration_s=float(sys.argv[3]))
key = writer.add_topic("/radar/tracks", "std_msgs/msg/String")
String = mal_msgs_py.get_type("std_msgs/msg/String")
k = 0
while True:
    writer.write(key, time.time_ns(), serialize(String(data=str(k)), "std_msgs/msg/String"))
    print(k, flush=True)
    k += 1
    time.sleep(0.02)
    writer.tick()
"""


def _string(k: int) -> bytes:
    import mal_msgs_py

    return serialize(mal_msgs_py.get_type(STRING)(data=str(k)), STRING)


def _read(bag: Path) -> tuple[list[int], int]:
    """The messages' numbers, and the count the bag's metadata gives."""
    reader = open_reader(bag)
    try:
        return [int(reader.deserialize(raw, c.msgtype).data) for c, _, raw in reader.messages()], reader.message_count
    finally:
        reader.close()


def test_a_short_recording_is_one_storage_file(tmp_path: Path) -> None:
    writer = RecordingBagWriter(tmp_path / "bag")
    key = writer.add_topic("/chatter", STRING)
    for k in range(368):
        writer.write(key, 1_000_000_000 + k * 10_000_000, _string(k))
    writer.close()
    assert sorted(p.name for p in (tmp_path / "bag").iterdir()) == ["bag_0.mcap", "metadata.yaml"]
    assert _read(tmp_path / "bag") == (list(range(368)), 368)


@pytest.mark.parametrize("split", ["size", "duration"])
def test_the_bag_is_split_by_size_or_duration(tmp_path: Path, split: str) -> None:
    kwargs = {"max_bytes": 1500} if split == "size" else {"max_duration_s": 0.2}
    writer = RecordingBagWriter(tmp_path / "bag", **kwargs)
    key = writer.add_topic("/chatter", STRING)
    for k in range(60):
        writer.write(key, 1_000_000_000 + k * 10_000_000, _string(k))
        time.sleep(0.01)
    writer.close()
    files = writer.files
    assert len(files) >= 2 and files == [f"bag_{n}.mcap" for n in range(len(files))]
    assert sorted(p.name for p in (tmp_path / "bag").iterdir()) == sorted([*files, "metadata.yaml"])
    assert _read(tmp_path / "bag") == (list(range(60)), 60)


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_a_killed_writer_loses_at_most_its_flush_period(tmp_path: Path, storage: str) -> None:
    """SIGKILL of a process writing at 50 Hz (flush every 0.5 s, a new file every 1 s): the bag reads back with
    the first messages, in order, all but at most about the last flush period's; it was split in several files."""
    bag = tmp_path / "bag"
    proc = subprocess.Popen([sys.executable, "-c", WRITER, str(bag), storage, "1.0"], stdout=subprocess.PIPE,
                            text=True)
    assert proc.stdout is not None
    written = int(proc.stdout.readline())  # started
    deadline = time.monotonic() + 3.3
    while time.monotonic() < deadline:
        written = int(proc.stdout.readline())
    proc.send_signal(signal.SIGKILL)
    proc.communicate()
    got, count = _read(bag)
    lost = written + 1 - len(got)
    print(f"{storage}: {len(got)} of {written + 1} messages kept after SIGKILL, {lost * 0.02:.2f} s lost")
    assert got == list(range(len(got))) and count == len(got)
    assert 0 <= lost * 0.02 <= 1.0
    assert not (bag / ".writing").exists() and len(list(bag.glob("bag_*"))) >= 2


def test_a_record_cut_short_is_dropped(tmp_path: Path) -> None:
    """An MCAP file cut in its last chunk: its whole chunks are read back, the cut one is dropped."""
    writer = RecordingBagWriter(tmp_path / "bag", flush_s=1e-9)  # a chunk per message
    key = writer.add_topic("/chatter", STRING)
    for k in range(10):
        writer.write(key, 1_000_000_000 + k, _string(k))
    writer.close()
    data = (tmp_path / "bag" / "bag_0.mcap").read_bytes()
    end_of_chunk_9 = data.rindex(b"\x06")  # not exact: any cut inside the summary or the last chunk does
    (tmp_path / "bag" / "bag_0.mcap").write_bytes(data[: end_of_chunk_9 + 20])
    (tmp_path / "bag" / ".writing").mkdir()  # as a killed recorder leaves it
    got, _ = _read(tmp_path / "bag")
    assert got == list(range(len(got))) and len(got) >= 8
    assert (tmp_path / "bag" / "bag_0.mcap").read_bytes().endswith(MCAP_MAGIC)
    assert end_mcap_file(tmp_path / "bag" / "bag_0.mcap") == 0  # once ended, left alone


def test_a_bag_being_recorded_is_not_recovered(tmp_path: Path) -> None:
    writer = RecordingBagWriter(tmp_path / "bag")
    try:
        writer.add_topic("/chatter", STRING)
        with pytest.raises(BagError, match="being recorded"):
            open_reader(tmp_path / "bag")
    finally:
        writer.close()
    assert _read(tmp_path / "bag") == ([], 0)
    assert sorted(os.listdir(tmp_path / "bag")) == ["bag_0.mcap", "metadata.yaml"]


def test_bad_settings_are_refused(tmp_path: Path) -> None:
    with pytest.raises(BagError, match="flush period must be > 0"):
        RecordingBagWriter(tmp_path / "a", flush_s=0.0)
    with pytest.raises(BagError, match="unknown storage"):
        RecordingBagWriter(tmp_path / "b", "bag")
    (tmp_path / "c").mkdir()
    with pytest.raises(BagError, match="exists already"):
        RecordingBagWriter(tmp_path / "c")
