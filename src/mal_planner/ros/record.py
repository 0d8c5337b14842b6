"""Record named topics into a rosbag2 bag (rosbags writer; MCAP by default, sqlite3 on request).

Topic discovery of other nodes is not available in the built-in backend, so topics are named: ``--topics``,
or the defaults (``radar/tracks``, ``landing_plan``, ``diagnostics``, plus ``aircraft/<cs>/state`` and
``aircraft/<cs>/path`` for the callsigns of ``--callsigns`` or of a ``--scenario``). Types come from the
topic names (:data:`mal_planner.ros.bagio.TOPIC_TYPES`) or ``topic:pkg/msg/Type``. Latched types (paths,
landing plan, markers) are subscribed TRANSIENT_LOCAL. Bag timestamps are receive times. SIGINT/SIGTERM
closes the bag (metadata.yaml written) and exits 0. Like ``ros2 bag record``, the bag is one storage file, or a
new one after ``--max-bag-size`` bytes or ``--max-bag-duration`` seconds. What is recorded reaches the disk (and
metadata.yaml) every ``--flush-s`` seconds, so a SIGKILL loses at most that much: reading the bag afterwards
recovers it (:func:`mal_planner.ros.bagio.recover_bag`).

    python -m mal_planner.ros.record out_bag --scenario scenarios/thesis.yaml
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from typing import Any

import mal_msgs_py
from mal_planner.ros.bag_recording import FLUSH_S, MAX_BAG_BYTES, MAX_BAG_DURATION_S
from mal_planner.ros.bagio import BagError, RecordingBagWriter, qos_for_type, serialize, stop_event, topic_type
from mal_planner.ros.transport import QoSProfile, resolve_name

DEFAULT_TOPICS = ("radar/tracks", "landing_plan", "diagnostics")
_READER_DEPTH = 100  # generous reader history so bursts are not dropped before the callback runs


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="mal-record", description=__doc__.split("\n")[0])
    p.add_argument("out", help="bag directory to create (must not exist)")
    p.add_argument("--topics", nargs="+", default=None, metavar="T", help="topics (optionally topic:pkg/msg/Type)")
    p.add_argument("--callsigns", nargs="+", default=(), help="add aircraft/<cs>/state and /path topics")
    p.add_argument("--scenario", default=None, help="take the callsigns from this scenario file")
    p.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap")
    p.add_argument("--duration", type=float, default=0.0, help="stop after this many seconds (0 = until signal)")
    p.add_argument("--flush-s", type=float, default=FLUSH_S,
                   help="write what was recorded to disk every this many seconds: at most this much is lost on a crash")
    p.add_argument("--split-s", dest="flush_s", type=float, default=FLUSH_S, help=argparse.SUPPRESS)  # its old name
    p.add_argument("--max-bag-size", type=int, default=MAX_BAG_BYTES, metavar="BYTES",
                   help="start a new storage file after this many bytes (default 1 GiB)")
    p.add_argument("--max-bag-duration", type=float, default=MAX_BAG_DURATION_S, metavar="S",
                   help="start a new storage file after this many seconds (default 600)")
    p.add_argument("--namespace", default="", help="namespace for relative topic names")
    return p.parse_args(argv)


def plan_topics(args: argparse.Namespace) -> list[tuple[str, str]]:
    """``(absolute topic, msgtype)`` to record; BagError for a topic of unknown type."""
    callsigns = list(args.callsigns)
    if args.scenario:
        from mal_planner.scenario import ScenarioError, load_scenario

        try:
            callsigns += [a.callsign for a in load_scenario(args.scenario).aircraft]
        except ScenarioError as exc:
            raise BagError(str(exc)) from None
    names = list(args.topics) if args.topics is not None else list(DEFAULT_TOPICS)
    names += [f"aircraft/{cs}/{kind}" for cs in dict.fromkeys(callsigns) for kind in ("state", "path")]
    out: dict[str, str] = {}
    for spec in names:
        name, _, explicit = spec.partition(":")
        msgtype = explicit or topic_type(name)
        if msgtype is None:
            raise BagError(f"unknown type of topic {name!r} (give it as {name}:pkg/msg/Type)")
        try:
            mal_msgs_py.typestore().get_msgdef(msgtype)
        except Exception:
            raise BagError(f"unknown message type {msgtype!r} for topic {name!r}") from None
        out[resolve_name(name, args.namespace, "recorder")] = msgtype
    return list(out.items())


def main(argv: list[str] | None = None) -> int:
    """Record until SIGINT/SIGTERM (or --duration); 0 on success, 2 on bad input."""
    args = parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="[%(levelname)s] [%(name)s]: %(message)s")
    try:
        topics = plan_topics(args)
        writer = RecordingBagWriter(args.out, args.storage, flush_s=args.flush_s, max_bytes=args.max_bag_size,
                                    max_duration_s=args.max_bag_duration)
    except (BagError, ValueError) as exc:
        print(f"record: {exc}", file=sys.stderr)
        return 2
    counts: dict[int, int] = {}
    try:
        from mal_planner.ros.transport import create_node

        node = create_node("recorder", args.namespace)
        stop = stop_event()
        for topic, msgtype in topics:
            conn = writer.add_topic(topic, msgtype)
            base = qos_for_type(msgtype)
            qos = QoSProfile(depth=_READER_DEPTH, reliable=base.reliable, transient_local=base.transient_local)
            node.create_subscription(msgtype, topic, _writer_callback(writer, conn, msgtype, counts), qos)
        print(f"record: recording {len(topics)} topics to {args.out}", flush=True)
        end = time.monotonic() + args.duration if args.duration > 0 else float("inf")
        try:
            while not stop.is_set() and time.monotonic() < end:
                node.spin_once(0.1)
                writer.tick()
        except KeyboardInterrupt:
            pass
        node.shutdown()
    finally:
        writer.close()
    print(f"record: wrote {sum(counts.values())} messages to {args.out}", flush=True)
    return 0


def _writer_callback(writer: RecordingBagWriter, conn: int, msgtype: str, counts: dict[int, int]) -> Any:
    def callback(msg: Any) -> None:
        writer.write(conn, time.time_ns(), serialize(msg, msgtype))
        counts[conn] = counts.get(conn, 0) + 1

    return callback


if __name__ == "__main__":
    sys.exit(main())
