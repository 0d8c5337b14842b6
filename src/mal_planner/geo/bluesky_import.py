"""Import a BlueSky scenario's aircraft (its ``CRE`` lines) as the initial states of a geodetic scenario.

``python -m mal_planner.geo.bluesky_import traffic.scn --template scenarios/thesis_geodetic.yaml -o out.yaml``
writes the template (runway on the Earth, airspace, obstacles, gates, separation, sequencing) with its aircraft
replaced by those the ``.scn`` file creates: ``CRE acid,type,lat,lon,hdg,alt,spd`` (BlueSky's argument order;
commas or spaces), at the time of the first ``CRE`` (``--at`` another time: those created up to then).

* Positions: decimal degrees (BlueSky also takes navaids and degree-minute-second text: refused, one line
  naming the line); altitude in ft or as a flight level ``FL70``.
* Speed: CAS in kt, or a Mach number (``0.78``, ``M.78``, ``M0.78``); made a true airspeed in the ISA
  (OpenAP's atmosphere, as the export's :func:`~mal_planner.geo.bluesky.tas_to_cas_kt`).
* Heading: BlueSky's true heading; in still air (as BlueSky creates aircraft) also the track, which the
  scenario's ``track_deg`` is; level flight (BlueSky creates aircraft level).
* The aircraft type becomes the aircraft's ``aircraft_type`` where OpenAP has its performance (else it is left out,
  with a warning); a wake category is not guessed from it (set ``wake_category`` with ``--wake TYPE=CAT``, e.g.
  ``--wake A320=M --wake B744=H``).
"""

from __future__ import annotations

import argparse
import logging
import re
import sys
from dataclasses import dataclass
from pathlib import Path

import yaml

from mal_planner.geo.bluesky import cas_to_tas_kt, mach_to_tas_kt
from mal_planner.performance import UnknownAircraftType, known_type

log = logging.getLogger("mal_planner.geo.bluesky_import")

_TIME = re.compile(r"^\s*(\d+):(\d{1,2}):(\d{1,2}(?:\.\d*)?)\s*>\s*(.*)$")
_CREATE = ("CRE", "CREATE")
_FLIGHT_LEVEL_FT = 100.0
"""A flight level is hundreds of feet (on the standard pressure, taken here as the altitude: the ISA)."""


class ScnError(ValueError):
    """A ``.scn`` file or line that cannot be imported (one line: where and why)."""


@dataclass(frozen=True)
class Created:
    """One aircraft a ``CRE`` line creates, in the file's units."""

    time_s: float
    callsign: str
    aircraft_type: str
    lat_deg: float
    lon_deg: float
    heading_deg: float
    alt_ft: float
    tas_kt: float


def _number(text: str, what: str, where: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise ScnError(f"{where}: {what} {text!r} is not a number (only decimal values are imported)") from None


def _altitude_ft(text: str, where: str) -> float:
    if text.upper().startswith("FL"):
        return _number(text[2:], "flight level", where) * _FLIGHT_LEVEL_FT
    return _number(text, "altitude (ft)", where)


def _tas_kt(text: str, alt_ft: float, where: str) -> float:
    mach = text.upper().startswith("M")
    value = _number(text[1:] if mach else text, "speed", where)
    if not value > 0.0:
        raise ScnError(f"{where}: speed {text!r} must be > 0")
    if mach or value < 1.0:  # BlueSky reads a speed below 1 as a Mach number
        return mach_to_tas_kt(value, alt_ft)
    return cas_to_tas_kt(value, alt_ft)


def parse_create(time_s: float, arguments: str, where: str) -> Created:
    """The aircraft of one ``CRE`` command's arguments ``acid,type,lat,lon,hdg,alt,spd``."""
    words = [w for w in re.split(r"[,\s]+", arguments.strip()) if w]
    if len(words) != 7:
        raise ScnError(f"{where}: CRE needs 7 arguments (acid,type,lat,lon,hdg,alt,spd), got {len(words)}")
    callsign, actype, lat, lon, hdg, alt, spd = words
    lat_deg, lon_deg = _number(lat, "latitude", where), _number(lon, "longitude", where)
    if not (-90.0 <= lat_deg <= 90.0 and -180.0 <= lon_deg <= 180.0):
        raise ScnError(f"{where}: position {lat_deg}, {lon_deg} is not a latitude/longitude in degrees")
    alt_ft = _altitude_ft(alt, where)
    return Created(time_s, callsign.upper(), actype.upper(), lat_deg, lon_deg, _number(hdg, "heading", where) % 360.0,
                   alt_ft, _tas_kt(spd, alt_ft, where))


def read_creates(text: str, source: str = "<scn>") -> list[Created]:
    """Every aircraft a ``.scn`` text creates, in file order (other commands are ignored)."""
    out: list[Created] = []
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        match = _TIME.match(line)
        if match is None:
            raise ScnError(f"{source}:{number}: not a .scn line 'HH:MM:SS.ss>COMMAND args': {raw.strip()!r}")
        hours, minutes, seconds, commands = match.groups()
        time_s = int(hours) * 3600.0 + int(minutes) * 60.0 + float(seconds)
        for command in commands.split(";"):
            name, _, arguments = command.strip().partition(" ")
            if name.upper() in _CREATE:
                out.append(parse_create(time_s, arguments, f"{source}:{number}"))
    return out


def initial_aircraft(created: list[Created], at_s: float | None = None,
                     wake: dict[str, str] | None = None) -> list[dict]:
    """Scenario aircraft (geodetic format) of those created up to ``at_s`` (default: the first creation time);
    a callsign created twice keeps its last state, as BlueSky replaces it."""
    if not created:
        raise ScnError("the file creates no aircraft (no CRE line)")
    at_s = min(c.time_s for c in created) if at_s is None else at_s
    chosen = {c.callsign: c for c in created if c.time_s <= at_s}
    if not chosen:
        raise ScnError(f"no aircraft is created at or before {at_s} s (the first CRE is at "
                       f"{min(c.time_s for c in created)} s)")
    wake = wake or {}
    out = []
    for c in chosen.values():
        entry = {"callsign": c.callsign, "lat": c.lat_deg, "lon": c.lon_deg, "alt_ft": c.alt_ft,
                 "track_deg": c.heading_deg, "flight_path_angle_deg": 0.0, "speed_kt": round(c.tas_kt, 6)}
        if c.aircraft_type in wake:
            entry["wake_category"] = wake[c.aircraft_type]
        try:
            entry["aircraft_type"] = known_type(c.aircraft_type)
        except UnknownAircraftType:
            log.warning("%s: type %r has no OpenAP performance: left out (the scenario's default type applies)",
                        c.callsign, c.aircraft_type)
        out.append(entry)
    return out


def scenario_with_aircraft(template: dict, aircraft: list[dict], name: str) -> dict:
    """The template scenario (a parsed geodetic file) with its aircraft replaced."""
    if "threshold" not in (template.get("runway") or {}):
        raise ScnError("the template's runway is not on the Earth (runway: {threshold: {lat, lon, elevation_ft}, "
                       "course_deg}): BlueSky's aircraft are in latitude/longitude")
    out = dict(template)
    out["name"] = name
    out["aircraft"] = aircraft
    return out


def _wake_option(text: str) -> tuple[str, str]:
    actype, sep, category = text.partition("=")
    if not sep or not actype or category.upper() not in ("L", "M", "H", "J"):
        raise argparse.ArgumentTypeError(f"{text!r}: give TYPE=CATEGORY, the category one of L, M, H, J")
    return actype.upper(), category.upper()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m mal_planner.geo.bluesky_import",
                                     description="A geodetic scenario whose aircraft are those a BlueSky .scn "
                                                 "file creates (CRE), in a template's runway and airspace.")
    parser.add_argument("scn", type=Path, help="BlueSky scenario file (.scn)")
    parser.add_argument("--template", type=Path, required=True,
                        help="geodetic scenario giving the runway, airspace, obstacles and separation")
    parser.add_argument("-o", "--out", type=Path, required=True, help="scenario file to write")
    parser.add_argument("--at", type=float, default=None,
                        help="import the aircraft created up to this time [s] (default: the first CRE's time)")
    parser.add_argument("--wake", type=_wake_option, action="append", default=[], metavar="TYPE=CAT",
                        help="wake category of an aircraft type, e.g. A320=M (repeatable)")
    args = parser.parse_args(argv)
    try:
        text = args.scn.read_text(encoding="utf-8")
        template = yaml.safe_load(args.template.read_text(encoding="utf-8"))
        if not isinstance(template, dict):
            raise ScnError(f"{args.template}: not a scenario (a YAML mapping)")
        aircraft = initial_aircraft(read_creates(text, str(args.scn)), args.at, dict(args.wake))
        document = scenario_with_aircraft(template, aircraft, args.out.stem)
        from mal_planner.scenario import ScenarioError, parse_scenario  # validate before writing

        try:
            parse_scenario(document, str(args.out))
        except ScenarioError as exc:
            raise ScnError(str(exc)) from None
        args.out.write_text(yaml.safe_dump(document, sort_keys=False), encoding="utf-8")
    except (OSError, UnicodeDecodeError, yaml.YAMLError, ScnError) as exc:
        print(f"error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    print(f"{args.out}: {len(aircraft)} aircraft from {args.scn} ({', '.join(a['callsign'] for a in aircraft)})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
