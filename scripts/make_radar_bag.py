#!/usr/bin/env python3
"""Generate the radar bag of the thesis scenario (``data/thesis_radar.mcap``) without DDS.

The scenario's aircraft fly level along their initial headings (``mal_planner.ros.radar_sim``) for 20 s at
2 Hz with seeded Gaussian position noise; each track goes to ``/aircraft/<callsign>/state`` and
``/radar/tracks`` as ``mal_msgs/msg/AircraftState``. Output is deterministic. A path ending in ``.mcap``
or ``.db3`` gives one storage file, any other path a rosbag2 directory with ``metadata.yaml``.

    python scripts/make_radar_bag.py [--out data/thesis_radar.mcap] [--storage mcap|sqlite3]
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator
from pathlib import Path

from mal_planner.ros.bagio import STATE_TYPE, BagError, MsgTypes, serialize, write_bag
from mal_planner.ros.convert import planner_to_aircraft_state
from mal_planner.ros.radar_sim import RadarSimulator
from mal_planner.scenario import Scenario, load_scenario

ROOT = Path(__file__).resolve().parents[1]
START_S = 1_700_000_000  # fixed start stamp (2023-11-14T22:13:20Z) so the bag is reproducible


def radar_messages(
    scenario: Scenario, duration: float, rate: float, noise_m: float, seed: int, start_s: float = START_S
) -> Iterator[tuple[str, int, bytes]]:
    """``(topic, timestamp_ns, cdr)`` of every track update, in time order."""
    sim = RadarSimulator(scenario, t0=start_s, noise_m=noise_m, seed=seed)
    for k in range(int(round(duration * rate)) + 1):
        t_ns = int(start_s * 1_000_000_000) + round(k * 1e9 / rate)
        sim.step_to(t_ns / 1e9)
        for callsign, state, speed, wake in sim.measurements():
            data = serialize(planner_to_aircraft_state(MsgTypes, callsign, t_ns / 1e9, state, speed, wake), STATE_TYPE)
            yield f"/aircraft/{callsign}/state", t_ns, data
            yield "/radar/tracks", t_ns, data


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--scenario", default=str(ROOT / "scenarios" / "thesis.yaml"))
    p.add_argument("--out", default=None, help="bag path (default data/thesis_radar.mcap or .db3)")
    p.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap")
    p.add_argument("--duration", type=float, default=20.0)
    p.add_argument("--rate", type=float, default=2.0)
    p.add_argument("--noise-m", type=float, default=5.0)
    p.add_argument("--seed", type=int, default=2024)
    p.add_argument("--force", action="store_true", help="replace an existing output file")
    args = p.parse_args(argv)
    out = Path(args.out or ROOT / "data" / ("thesis_radar.mcap" if args.storage == "mcap" else "thesis_radar.db3"))
    scenario = load_scenario(args.scenario)
    if args.force and out.is_file():
        out.unlink()
    topics = [(f"/aircraft/{a.callsign}/state", STATE_TYPE) for a in scenario.aircraft]
    topics.append(("/radar/tracks", STATE_TYPE))
    messages = radar_messages(scenario, args.duration, args.rate, args.noise_m, args.seed)
    try:
        write_bag(out, topics, messages, args.storage)
    except BagError as exc:
        print(f"make_radar_bag: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
