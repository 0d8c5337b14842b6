"""Replay recorded radar tracks from a rosbag2 bag (MCAP or sqlite3; directory or single storage file).

Publishes the bag's ``mal_msgs/AircraftState`` topics (or ``--topics``) on their recorded names, keeping
the relative timing of the bag timestamps scaled by ``--rate`` (0 = as fast as possible). ``--restamp``
shifts each ``header.stamp`` by (publish time - bag time), so a live planner sees fresh data.

    python -m mal_planner.ros.replay data/thesis_radar.mcap --rate 1 --restamp
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from typing import Any

from mal_planner.ros.bagio import STATE_TYPE, BagError, open_reader, qos_for_type, stop_event, to_backend
from mal_planner.ros.convert import msg_to_time, time_to_msg

PROGRESS_PERIOD_S = 5.0
_WRITER_DEPTH = 1000


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="mal-replay", description=__doc__.split("\n")[0])
    p.add_argument("bag", help="rosbag2 directory or .mcap/.db3 file")
    p.add_argument("--rate", type=float, default=1.0, help="playback speed factor, 0 = as fast as possible")
    p.add_argument("--topics", nargs="+", default=None, help="topics to play (default: AircraftState topics)")
    p.add_argument("--loop", action="store_true", help="play the bag again and again")
    p.add_argument("--restamp", action="store_true", help="shift header stamps to the publish time")
    p.add_argument("--wait-for-subscribers", type=float, default=0.0, metavar="S",
                   help="wait up to S seconds until every topic has a subscriber (default 0)")  # fmt: skip
    p.add_argument("--namespace", default="", help="node namespace")
    args = p.parse_args(argv)
    if args.rate < 0:
        p.error("--rate must be >= 0")
    return args


def select_connections(reader: Any, topics: list[str] | None) -> list[Any]:
    """Connections to play: the named topics (BagError if one is missing), else all AircraftState ones."""
    if topics is None:
        conns = [c for c in reader.connections if c.msgtype == STATE_TYPE]
        if not conns:
            raise BagError("no mal_msgs/msg/AircraftState topics in the bag")
        return conns
    wanted = {"/" + t.strip("/") for t in topics}
    conns = [c for c in reader.connections if c.topic in wanted]
    if missing := wanted - {c.topic for c in conns}:
        raise BagError(f"topics not in the bag: {', '.join(sorted(missing))}")
    return conns


def _restamp(node: Any, msg: Any, offset_s: float) -> None:
    if hasattr(msg, "header"):
        msg.header.stamp = time_to_msg(node.types, msg_to_time(msg) + offset_s)


def main(argv: list[str] | None = None) -> int:
    """Play the bag; 0 when done (or stopped by SIGINT/SIGTERM), 2 for a missing/corrupt bag."""
    args = parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="[%(levelname)s] [%(name)s]: %(message)s")
    try:
        reader = open_reader(args.bag)
        conns = select_connections(reader, args.topics)
    except BagError as exc:
        print(f"replay: {exc}", file=sys.stderr)
        return 2
    from mal_planner.ros.transport import QoSProfile, create_node

    node = create_node("replay", args.namespace)
    stop = stop_event()
    pubs = {}
    for c in conns:
        if c.topic not in pubs:
            qos = qos_for_type(c.msgtype)
            if not qos.transient_local:  # deep writer history: bursts (--rate 0) are not overwritten before acked
                qos = QoSProfile(depth=_WRITER_DEPTH, reliable=qos.reliable)
            pubs[c.topic] = node.create_publisher(c.msgtype, c.topic, qos)
    deadline = time.monotonic() + args.wait_for_subscribers
    while time.monotonic() < deadline and not stop.is_set():
        if all(p.get_subscription_count() > 0 for p in pubs.values()):
            break
        stop.wait(0.05)
    count, bag_span, rc = 0, 0.0, 0
    wall_start = time.monotonic()
    try:
        count, bag_span = _play(node, reader, conns, pubs, args, stop)
    except Exception as exc:  # a bag that breaks while reading
        print(f"replay: cannot read bag {args.bag}: {exc}", file=sys.stderr)
        rc = 2
    stop.wait(0.5)  # let reliable readers fetch the last samples before the writers go
    node.shutdown()
    reader.close()
    if rc == 0:
        print(f"replay: {count} messages, {bag_span:.1f} s of bag time in {time.monotonic() - wall_start:.1f} s",
              flush=True)  # fmt: skip
    return rc


def _play(
    node: Any, reader: Any, conns: list[Any], pubs: dict[str, Any], args: argparse.Namespace, stop: Any
) -> tuple[int, float]:
    """Publish the messages (once, or until stopped with --loop); returns (count, bag seconds played)."""
    count, span = 0, 0.0
    next_log = time.monotonic() + PROGRESS_PERIOD_S
    while not stop.is_set():
        wall0, bag0 = time.monotonic(), None
        for conn, ts, raw in reader.messages(connections=conns):
            bag0 = ts if bag0 is None else bag0
            rel = (ts - bag0) / 1e9
            if args.rate > 0:
                while (left := wall0 + rel / args.rate - time.monotonic()) > 0 and not stop.is_set():
                    stop.wait(min(left, 0.1))
            if stop.is_set():
                return count, span
            msg = to_backend(raw, conn.msgtype, reader, node)
            if args.restamp:
                _restamp(node, msg, node.now() - ts / 1e9)
            pubs[conn.topic].publish(msg)
            count += 1
            span = max(span, rel)
            if time.monotonic() >= next_log:
                node.get_logger().info("replayed %d messages, %.1f s of bag time", count, rel)
                next_log += PROGRESS_PERIOD_S
        if not args.loop or bag0 is None:
            break
    return count, span


if __name__ == "__main__":
    sys.exit(main())
