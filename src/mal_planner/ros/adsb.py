"""``mal-adsb``: real arrivals from ADS-B as a geodetic scenario, a radar bag and the real tracks.

The selection and the scenario are :mod:`mal_planner.geo.adsb`'s; this module adds what needs the ROS side: the
radar bag (``mal_msgs/AircraftState`` on ``/aircraft/<callsign>/state`` and ``/radar/tracks``, in the runway frame,
stamped in UTC), which ``mal-launch --replay`` / ``mal-replay`` play to the planner node.
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
from collections.abc import Iterator
from pathlib import Path

from mal_planner.geo.adsb import (
    DEFAULT_HALF_NM,
    Area,
    Selection,
    header_lines,
    local_state,
    log,
    scenario_data,
    select_arrivals,
    write_scenario,
    write_tracks_csv,
)
from mal_planner.geo.adsb_tracks import load_tracks, utc_seconds, utc_text
from mal_planner.geo.runways import Runway, UnknownRunwayError, runway
from mal_planner.profiles import TMA
from mal_planner.ros.bagio import STATE_TYPE, MsgTypes, serialize, write_bag
from mal_planner.ros.convert import planner_to_aircraft_state
from mal_planner.units import kt_to_nm_per_s


def radar_messages(sel: Selection, start_s: float, end_s: float, rate_hz: float) -> Iterator[tuple[str, int, bytes]]:
    """``(topic, stamp_ns, cdr)`` of the kept aircraft's real tracks from ``start_s`` to ``end_s`` at ``rate_hz``
    (interpolated between ADS-B samples; none where a track has a gap), in the runway frame, stamped in UTC."""
    frame = sel.runway.frame
    n = int(math.floor((end_s - start_s) * rate_hz + 1e-9)) + 1
    for k in range(n):
        t = start_s + k / rate_hz
        t_ns = round(t * 1e9)
        for a in sel.kept:
            if not a.track.covers(t):
                continue
            s = a.track.interp(t)
            local = local_state(frame, a.track, t, sel.altitude_offset_ft)
            msg = planner_to_aircraft_state(MsgTypes, a.callsign, t_ns / 1e9, local, kt_to_nm_per_s(float(s["gs_kt"])))
            data = serialize(msg, STATE_TYPE)
            yield f"/aircraft/{a.callsign}/state", t_ns, data
            yield "/radar/tracks", t_ns, data


def write_radar_bag(sel: Selection, path: Path, before_s: float, rate_hz: float = 1.0) -> Path:
    """A rosbag2 bag (``.mcap``: one file; else a directory) of the kept aircraft's tracks over the ``before_s``
    seconds up to the moment."""
    topics = [(f"/aircraft/{a.callsign}/state", STATE_TYPE) for a in sel.kept] + [("/radar/tracks", STATE_TYPE)]
    return write_bag(path, topics, radar_messages(sel, sel.moment_s - before_s, sel.moment_s, rate_hz))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="mal-adsb", description=__doc__.split("\n")[0])
    p.add_argument("--time", required=True, help="the moment, ISO 8601 UTC (e.g. 2021-10-07T14:40Z)")
    p.add_argument("--runway", required=True, help="landing runway, e.g. 27R (see mal_planner.geo.runways)")
    p.add_argument("--airport", default="LFPG", help="ICAO code in the runway table (default LFPG)")
    p.add_argument("--data", type=Path, default=None, help="ADS-B file traffic reads (default: its sample quickstart)")
    p.add_argument("--arrivals", choices=("runway", "airport"), default="runway",
                   help="flights landing on the runway (default) or on any of the airport's runways in its direction "
                        "(all planned onto the one runway)")
    p.add_argument("--area-nm", type=float, default=DEFAULT_HALF_NM,
                   help=f"half the terminal area's width, around the threshold (default {DEFAULT_HALF_NM:g} nm)")
    p.add_argument("--ceiling-nm", type=float, default=TMA.min_airspace[2][1],
                   help=f"terminal area's ceiling above the threshold (default {TMA.min_airspace[2][1]:g} nm)")
    p.add_argument("--vertical-ft", type=float, default=None,
                   help="vertical minimum (ft): separated when 3 nm apart OR this far apart vertically (default: "
                        "none, the 3-nm sphere of --profile tma)")
    p.add_argument("--altitude-offset-ft", type=float, default=None,
                   help="added to recorded altitudes (default: calibrated on the recording's landings)")
    p.add_argument("--out", type=Path, required=True, help="scenario YAML to write")
    p.add_argument("--name", default=None, help="scenario name (default: the file's stem)")
    p.add_argument("--bag", type=Path, default=None, help="also write a radar bag (.mcap) of the tracks")
    p.add_argument("--bag-seconds", type=float, default=30.0, help="radar before the moment (default 30 s)")
    p.add_argument("--bag-rate", type=float, default=1.0, help="radar rate (default 1 Hz)")
    p.add_argument("--tracks", type=Path, default=None, help="also write the real tracks to the landing (CSV)")
    p.add_argument("--flyable", action="store_true",
                   help="plan the aircraft as airliners: the airspeed model (model: point_mass_airspeed) under the "
                        "default arrival procedures (procedures:, type A320); mal-plan plans it, the service not yet")
    p.add_argument("--force", action="store_true", help="replace existing output files")
    args = p.parse_args(argv)
    handler = logging.StreamHandler()
    handler.setFormatter(logging.Formatter("%(message)s"))
    log.addHandler(handler)
    log.setLevel(logging.INFO)
    log.propagate = False
    try:
        moment, rw = _checked(args)
        sel = _convert(args, moment, rw, "mal-adsb " + " ".join(argv if argv is not None else sys.argv[1:]))
    except (OSError, ValueError, RuntimeError, UnknownRunwayError) as exc:
        print(f"{p.prog}: error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {args.out}: {len(sel.kept)} arrivals ({', '.join(a.callsign for a in sel.kept)}), "
          f"{len(sel.skipped)} left out; altitude offset {sel.altitude_offset_ft:+.0f} ft")
    if args.bag is not None:
        write_radar_bag(sel, args.bag, args.bag_seconds, args.bag_rate)
        print(f"wrote {args.bag}: {args.bag_seconds:g} s of radar at {args.bag_rate:g} Hz")
    if args.tracks is not None:
        write_tracks_csv(sel, args.tracks)
        print(f"wrote {args.tracks}")
    return 0


def _checked(args: argparse.Namespace) -> tuple[float, Runway]:
    """The moment and the runway; ValueError (one line) for a bad option or an output that exists."""
    moment = utc_seconds(args.time)
    rw = runway(args.airport, args.runway)
    if not (args.area_nm > 0 and args.ceiling_nm > 0 and args.bag_seconds >= 0 and args.bag_rate > 0):
        raise ValueError("--area-nm, --ceiling-nm and --bag-rate must be > 0, --bag-seconds >= 0")
    for out in (args.out, args.bag, args.tracks):
        if out is not None and out.exists() and not args.force:
            raise ValueError(f"{out} exists already (--force replaces it)")
    return moment, rw


def _convert(args: argparse.Namespace, moment: float, rw: Runway, command: str) -> Selection:
    """Read the recording, select the moment's arrivals and write the scenario (validated first)."""
    tracks = load_tracks(args.data)
    if not tracks or not tracks[0].t.size:
        raise ValueError("the recording holds no flight")
    t_min, t_max = min(t.t[0] for t in tracks), max(t.t[-1] for t in tracks)
    if not t_min <= moment <= t_max:
        raise ValueError(f"--time {utc_text(moment)} is outside the recording ({utc_text(t_min)} to "
                         f"{utc_text(t_max)})")
    sel = select_arrivals(tracks, rw, moment, Area.square(args.area_nm, args.ceiling_nm), TMA, args.arrivals,
                          args.altitude_offset_ft, args.vertical_ft)
    data = scenario_data(sel, args.name or args.out.stem, TMA, vertical_ft=args.vertical_ft, flyable=args.flyable)
    source = str(args.data) if args.data else "traffic.data.samples.quickstart"
    for out in (args.out, args.bag, args.tracks):
        if out is not None and args.force and out.is_file():
            out.unlink()
    write_scenario(sel, args.out, data, header_lines(sel, source, command, args.flyable))
    return sel

if __name__ == "__main__":
    sys.exit(main())
