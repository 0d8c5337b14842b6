"""Place a local scenario on the Earth: the same file with its runway at a real threshold and its aircraft in
lat/lon/ft/kt (airspace, obstacles and gates stay in the runway frame, nm).

``python -m mal_planner.geo.convert scenarios/thesis.yaml --threshold 49.02667786 2.56169447 392 --course 265.43
-o thesis_geodetic.yaml`` writes such a copy; loading it gives the local scenario back (to round-off).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import yaml

from mal_planner.geodesy import LANDING_HEADING, GeoFrame
from mal_planner.units import nm_per_s_to_kt

_LOCAL_ONLY = ("position", "heading_deg", "speed", "flight_path_angle_deg")


def geodetic_copy(data: dict, frame: GeoFrame) -> dict:
    """A parsed local scenario (its runway at the origin, landing towards -y) with the runway at ``frame``'s
    threshold and every aircraft in lat/lon/alt_ft, true track and speed in kt. Raises ValueError otherwise."""
    runway = data.get("runway") or {}
    if "threshold" in runway:
        raise ValueError("runway: the scenario is already geodetic")
    if list(runway.get("position", (0.0, 0.0, 0.0))) != [0.0, 0.0, 0.0] or not math.isclose(
            math.radians(runway.get("heading_deg", -90.0)), LANDING_HEADING, abs_tol=1e-12):
        raise ValueError("runway: only a runway at the origin landing towards -y (heading_deg -90) can be placed")
    out = {k: v for k, v in data.items() if k not in ("runway", "aircraft")}
    out["runway"] = {"threshold": {"lat": frame.lat_deg, "lon": frame.lon_deg, "elevation_ft": frame.elevation_ft},
                     "course_deg": frame.course_deg,
                     "flight_path_angle_deg": runway.get("flight_path_angle_deg", 0.0)}
    aircraft = []
    for ac in data["aircraft"]:
        point = np.asarray(ac["position"], float)
        lat, lon, alt = frame.to_geodetic(point)
        track, fpa = frame.direction_to_geodetic(point, math.radians(ac["heading_deg"]),
                                                 math.radians(ac["flight_path_angle_deg"]))
        geo = {"callsign": ac["callsign"], "lat": float(lat), "lon": float(lon), "alt_ft": float(alt),
               "track_deg": track, "flight_path_angle_deg": fpa, "speed_kt": nm_per_s_to_kt(ac["speed"])}
        geo.update({k: v for k, v in ac.items() if k not in _LOCAL_ONLY and k != "callsign"})
        aircraft.append(geo)
    # keep the file's key order: runway and aircraft where they were
    ordered = {}
    for key in data:
        ordered[key] = out["runway"] if key == "runway" else aircraft if key == "aircraft" else out[key]
    ordered.setdefault("runway", out["runway"])
    return ordered


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m mal_planner.geo.convert",
                                     description="Place a local scenario's runway at a real threshold; write the "
                                                 "geodetic copy (aircraft in lat/lon/ft/kt).")
    parser.add_argument("scenario", type=Path)
    parser.add_argument("--threshold", nargs=3, type=float, required=True, metavar=("LAT", "LON", "ELEVATION_FT"))
    parser.add_argument("--course", type=float, required=True, help="true course of the landing direction (deg)")
    parser.add_argument("-o", "--output", type=Path, required=True)
    args = parser.parse_args(argv)
    try:
        data = yaml.safe_load(args.scenario.read_text(encoding="utf-8"))
        copy = geodetic_copy(data, GeoFrame(*args.threshold, course_deg=args.course))
    except (OSError, ValueError, KeyError, TypeError, yaml.YAMLError) as exc:
        print(f"{parser.prog}: error: {args.scenario}: {exc}", file=sys.stderr)
        return 2
    args.output.write_text(yaml.safe_dump(copy, sort_keys=False, default_flow_style=None, width=118),
                           encoding="utf-8")
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
