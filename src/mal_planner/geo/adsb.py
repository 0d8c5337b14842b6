"""Real arrivals from ADS-B: a moment of a recording and a runway -> a geodetic scenario and a radar bag.

    mal-adsb --time 2021-10-07T14:40Z --runway 08R --out scenarios/cdg_1440.yaml

(:mod:`mal_planner.ros.adsb`, which writes the radar bag too) reads the ``traffic`` library's sample
``quickstart`` (or ``--data FILE``, any file ``traffic`` reads: parquet,
csv, json, ...; columns timestamp, icao24, callsign, latitude, longitude, altitude, groundspeed, track), finds the
flights that land on the runway (or, ``--arrivals airport``, on any runway of the airport in the same direction),
and writes

* a geodetic scenario of those still flying at the moment inside a real-size terminal area (the numbers of
  ``mal-traffic --profile tma``: 3 nm separation, 90 s landing spacing, 30 deg bank, ceiling 1.2 nm, a -3 deg
  glide path at the runway): each aircraft's latitude, longitude, altitude, true track and ground speed at the
  moment (interpolated between the ADS-B samples), its flight-path angle from its climb over
  :data:`~mal_planner.geo.adsb_tracks.SLOPE_WINDOW_S`;
* with ``--bag``, a rosbag2 bag (MCAP) of their real tracks before the moment (``mal_msgs/AircraftState`` in
  the runway frame on ``/aircraft/<callsign>/state`` and ``/radar/tracks``, stamped in UTC), which
  ``mal-launch --replay`` / ``mal-replay`` play to the planner node;
* with ``--tracks``, their real tracks from the moment to the landing (CSV, for figures).

The planner's aircraft fly without wind: each gets its ground speed at the moment as its airspeed (``--flyable``:
brought into its type's envelope and the procedures' speed limit, :func:`airspeed_estimate`). An
aircraft that the scenario cannot hold is left out, with the reason logged: no samples around the moment,
already landed, outside the terminal area, above its ceiling, or closer than the separation to an aircraft that
lands before it (the planner needs a separated start).

Altitudes: ADS-B gives barometric (pressure) altitude, referred to 1013.25 hPa, not to the day's sea-level
pressure. The converter calibrates it on the recording's own landings: an ILS approach crosses the threshold at
:data:`~mal_planner.geo.adsb_tracks.THRESHOLD_CROSSING_HEIGHT_FT`, so the offset is the median, over the
landings detected, of the threshold elevation + that height - the recorded altitude at the threshold (the 3 deg
glide extrapolated to it).
The offset absorbs the day's pressure, the geoid and the table's airport-wide elevation alike.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from mal_planner.geo.adsb_tracks import (
    FINAL_TRACK_DEG,
    MAX_SAMPLE_GAP_S,
    THRESHOLD_CROSSING_HEIGHT_FT,
    Track,
    altimeter_offset_ft,
    detect_landing,
    flight_path_angle_deg,
    utc_text,
)
from mal_planner.geo.runways import Runway, runways
from mal_planner.geodesy import GeoFrame
from mal_planner.landing.margins import SafetyMargins
from mal_planner.landing.speeds import start_airspeed
from mal_planner.performance import DEFAULT_TYPE, performance_of
from mal_planner.profiles import TMA, TrafficProfile
from mal_planner.scenario.procedures import ProceduresConfig
from mal_planner.units import ft_to_nm, kt_to_nm_per_s, nm_per_s_to_kt, nm_to_ft

log = logging.getLogger("mal_planner.geo.adsb")

@dataclass(frozen=True)
class Area:
    """A terminal area in the runway frame (nm): x across, y along the approach (the approach side is +y)."""

    x: tuple[float, float]
    y: tuple[float, float]
    ceiling_nm: float

    @classmethod
    def square(cls, half_nm: float, ceiling_nm: float) -> Area:
        return cls((-half_nm, half_nm), (-half_nm, half_nm), ceiling_nm)

    def airspace(self) -> dict:
        return {"x": list(self.x), "y": list(self.y), "z": [0.0, self.ceiling_nm]}


DEFAULT_HALF_NM = 25.0
"""Default terminal area: 50 x 50 nm around the threshold (the runway sits in the middle, as at a real TMA, where
downwind legs run past the airport): a little over ``mal-traffic --profile tma``'s 45 nm."""


@dataclass(frozen=True)
class Arrival:
    """An aircraft of the scenario: its track and its geodetic state at the moment."""

    track: Track
    callsign: str
    lat: float
    lon: float
    alt_ft: float
    """Calibrated altitude (the runway's datum)."""
    track_deg: float
    flight_path_angle_deg: float
    speed_kt: float
    local: np.ndarray
    """Position in the runway frame (nm)."""


@dataclass
class Selection:
    """The converter's result: aircraft kept and left out (callsign, reason), with its inputs."""

    runway: Runway
    moment_s: float
    area: Area
    altitude_offset_ft: float
    kept: list[Arrival]
    skipped: list[tuple[str, str]]


def _callsign(track: Track, taken: set[str]) -> str:
    base = "".join(ch for ch in track.callsign if ch.isalnum()) or track.flight_id.split("_")[0]
    name, k = base[:16], 2
    while name in taken:
        name, k = f"{base[:13]}_{k}", k + 1
    taken.add(name)
    return name


def select_arrivals(tracks: list[Track], rw: Runway, moment_s: float, area: Area, profile: TrafficProfile = TMA,
                    arrivals: str = "runway", altitude_offset_ft: float | None = None,
                    vertical_ft: float | None = None) -> Selection:
    """The arrivals on ``rw`` (``arrivals="airport"``: on every runway of its airport within 20 deg of its course)
    still flying at ``moment_s`` inside ``area``; see the module's docstring for who is left out and why."""
    if arrivals not in ("runway", "airport"):
        raise ValueError(f"arrivals must be 'runway' or 'airport', got {arrivals!r}")
    table = runways(rw.airport)
    for tr in tracks:
        if tr.landing is None:
            tr.landing = detect_landing(tr, table.values())
    offset = altimeter_offset_ft(tracks) if altitude_offset_ft is None else float(altitude_offset_ft)
    same_way = {name for name, other in table.items()
                if abs((other.frame.course_deg - rw.frame.course_deg + 180.0) % 360.0 - 180.0) < FINAL_TRACK_DEG}
    landing_here = [tr for tr in tracks if tr.landing is not None and (
        tr.landing.runway.name == rw.name or (arrivals == "airport" and tr.landing.runway.name in same_way))]
    landing_here.sort(key=lambda tr: tr.landing.time_s)
    frame, kept, skipped, taken = rw.frame, [], [], set()
    separation_nm = profile.separation_nm
    for tr in landing_here:
        callsign = _callsign(tr, taken)
        if tr.landing.time_s <= moment_s:
            continue  # landed before the moment: not an arrival any more (not worth a line)
        if not tr.covers(moment_s):
            if tr.t[0] > moment_s:
                continue  # not yet in the recording: not worth a line either
            skipped.append((callsign, f"no ADS-B sample within {MAX_SAMPLE_GAP_S:g} s of the moment"))
            continue
        s = tr.interp(moment_s)
        alt = float(s["alt_ft"]) + offset
        p = frame.to_local(float(s["lat"]), float(s["lon"]), alt)
        if not (area.x[0] <= p[0] <= area.x[1] and area.y[0] <= p[1] <= area.y[1]):
            skipped.append((callsign, f"outside the terminal area at ({p[0]:.1f}, {p[1]:.1f}) nm "
                                      f"(lands {tr.landing.time_s - moment_s:.0f} s later)"))
            continue
        if not 0.0 <= p[2] <= area.ceiling_nm:
            skipped.append((callsign, f"at {nm_to_ft(float(p[2])):.0f} ft above the threshold: outside the terminal "
                                      f"area's 0-{nm_to_ft(area.ceiling_nm):.0f} ft"))
            continue
        gamma = flight_path_angle_deg(tr, moment_s)
        conflict = next((k for k in kept if _too_close(p, k.local, separation_nm, vertical_ft)), None)
        if conflict is not None:
            skipped.append((callsign, f"{np.linalg.norm(p - conflict.local):.2f} nm from {conflict.callsign} "
                                      f"(landing before it): closer than the separation"))
            continue
        kept.append(Arrival(tr, callsign, float(s["lat"]), float(s["lon"]), alt, float(s["track_deg"]), gamma,
                            float(s["gs_kt"]), p))
    for callsign, reason in skipped:
        log.info("left out %s: %s", callsign, reason)
    return Selection(rw, moment_s, area, offset, kept, skipped)


def _too_close(p: np.ndarray, q: np.ndarray, separation_nm: float, vertical_ft: float | None) -> bool:
    if vertical_ft is not None:
        return bool(np.hypot(*(p[:2] - q[:2])) < separation_nm and abs(p[2] - q[2]) < ft_to_nm(vertical_ft))
    return bool(np.linalg.norm(p - q) < separation_nm)


def airspeed_estimate(a: Arrival) -> tuple[float, str | None]:
    """The true airspeed (kt) an airspeed-model aircraft starts with: its ground speed (the sample has no wind)
    brought into what its type may fly and the default procedures allow at its altitude
    (:func:`~mal_planner.landing.speeds.start_airspeed`, with the optimizer's speed share). The note says what was
    changed (None: nothing)."""
    share = SafetyMargins().speed
    start = start_airspeed(kt_to_nm_per_s(a.speed_kt), ft_to_nm(a.alt_ft), performance_of(DEFAULT_TYPE),
                           ProceduresConfig().to_procedures(), share)
    if start.cas == start.measured_cas:
        return a.speed_kt, None
    tas_kt = nm_per_s_to_kt(start.tas)
    why = (f"below the type's slowest final approach plus {share:.0%}" if start.cas == start.low else
           f"above what it may fly there ({nm_per_s_to_kt(start.high / (1.0 - share)):.0f} kt) less {share:.0%}")
    return tas_kt, (f"{a.callsign}: ground speed {a.speed_kt:.0f} kt is {nm_per_s_to_kt(start.measured_cas):.0f} kt "
                    f"CAS at {a.alt_ft:,.0f} ft, {why}: starts at {nm_per_s_to_kt(start.cas):.1f} kt CAS "
                    f"({tas_kt:.1f} kt true airspeed; the rest is wind)")


def scenario_data(sel: Selection, name: str, profile: TrafficProfile = TMA, glide_path_deg: float | None = None,
                  vertical_ft: float | None = None, flyable: bool = False) -> dict:
    """The geodetic scenario (a mapping for YAML) of a selection, with the terminal-area numbers of ``profile``;
    ``flyable``: every aircraft flies the airspeed model under the default arrival procedures (of the default
    type: the sample names no types)."""
    if not sel.kept:
        raise ValueError(f"no arrival on {sel.runway.airport} {sel.runway.name} inside the terminal area at "
                         f"{utc_text(sel.moment_s)}")
    f = sel.runway.frame
    glide = profile.glide_path_deg if glide_path_deg is None else glide_path_deg
    separation = {"distance_nm": profile.separation_nm, "landing_spacing_s": profile.landing_spacing_s,
                  "max_landing_spacing_s": profile.max_landing_spacing_s}
    if vertical_ft is not None:
        separation["vertical_ft"] = vertical_ft
    model = {"model": "point_mass_airspeed"} if flyable else {}
    speeds = {a.callsign: airspeed_estimate(a)[0] if flyable else a.speed_kt for a in sel.kept}
    data = {
        "name": name,
        "description": f"{len(sel.kept)} real arrivals on {sel.runway.airport} {sel.runway.name} at "
                       f"{utc_text(sel.moment_s)} (ADS-B)",
        "gravity": 0.0052952,
        "runway": {"threshold": {"lat": f.lat_deg, "lon": f.lon_deg, "elevation_ft": f.elevation_ft},
                   "course_deg": f.course_deg, "flight_path_angle_deg": -abs(glide)},
        "airspace": sel.area.airspace(),
        "aircraft": [{"callsign": a.callsign, "lat": round(a.lat, 7), "lon": round(a.lon, 7),
                      "alt_ft": round(a.alt_ft, 1), "track_deg": round(a.track_deg, 2),
                      "flight_path_angle_deg": round(a.flight_path_angle_deg, 3),
                      "speed_kt": round(speeds[a.callsign], 1), **model}
                     for a in sel.kept],
        "separation": separation,
        "limits": {"bank_angle_deg": profile.bank_angle_deg, "n_h": list(profile.n_h), "n_v": list(profile.n_v)},
    }
    if flyable:
        data["procedures"] = {"aircraft_type": DEFAULT_TYPE}
    return data


def header_lines(sel: Selection, source: str, command: str, flyable: bool = False) -> list[str]:
    """The scenario file's comment: where it comes from, who was left out and (``flyable``) whose airspeed was
    brought into its type's envelope (:func:`airspeed_estimate`)."""
    rw = sel.runway
    lines = [f"Real arrivals at {rw.airport} {rw.name} at {utc_text(sel.moment_s)}, from ADS-B ({source}), written by",
             f"  {command}",
             "Runway threshold and course: X-Plane apt.dat 2013.10 via bluesky-navdata 1.0.0 "
             "(mal_planner.geo.runways).",
             f"Altitudes: recorded barometric altitude {sel.altitude_offset_ft:+.1f} ft (calibrated on the "
             f"recording's landings: {THRESHOLD_CROSSING_HEIGHT_FT:.0f} ft over the threshold).",
             "Speeds are ground speeds at the moment, taken as airspeeds (no wind).",
             "Real landings (s after the moment): " + ", ".join(
                 f"{a.callsign} {a.track.landing.time_s - sel.moment_s:.0f} ({a.track.landing.runway.name})"
                 for a in sel.kept)]
    lines += [f"Left out {c}: {r}" for c, r in sel.skipped]
    if flyable:
        lines += [note for a in sel.kept if (note := airspeed_estimate(a)[1]) is not None]
    return lines


def write_scenario(sel: Selection, path: Path, data: dict, header: list[str]) -> Path:
    text = "".join(f"# {line}\n" for line in header)
    text += yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=118)
    from mal_planner.scenario import scenario_from_text

    scenario_from_text(text, str(path))  # validated before it is written (ScenarioError names the field)
    path.write_text(text, encoding="utf-8")
    return path


def local_state(frame: GeoFrame, track: Track, t: float, offset_ft: float) -> np.ndarray:
    """The planner state (x, y, z, gamma, heading) of a track at ``t`` (nm, rad)."""
    s = track.interp(t)
    lat, lon, alt = float(s["lat"]), float(s["lon"]), float(s["alt_ft"]) + offset_ft
    heading, gamma = frame.direction_to_local(lat, lon, float(s["track_deg"]), flight_path_angle_deg(track, t))
    return np.array([*frame.to_local(lat, lon, alt), gamma, heading])


TRACK_CSV_STEP_S = 4.0
"""The tracks CSV keeps one sample every this many seconds (a 250-kt aircraft flies 0.28 nm: a line at figure
scale)."""


def write_tracks_csv(sel: Selection, path: Path, step_s: float = TRACK_CSV_STEP_S) -> Path:
    """The kept aircraft's real tracks from the moment to their threshold, a sample every ``step_s``: callsign,
    t_s (from the moment), lat, lon, alt_ft (calibrated), and x, y, z in the runway frame (nm)."""
    rows = ["callsign,t_s,lat,lon,alt_ft,x_nm,y_nm,z_nm"]
    for a in sel.kept:
        tr = a.track
        keep = (tr.t >= sel.moment_s) & (tr.t <= tr.landing.time_s)
        picked = np.zeros_like(keep)
        last = -math.inf
        for k in np.flatnonzero(keep):
            if tr.t[k] - last >= step_s or k == np.flatnonzero(keep)[-1]:
                picked[k], last = True, tr.t[k]
        keep = picked
        alt = tr.alt_ft[keep] + sel.altitude_offset_ft
        p = sel.runway.frame.to_local(tr.lat[keep], tr.lon[keep], alt)
        for t, la, lo, h, (x, y, z) in zip(tr.t[keep], tr.lat[keep], tr.lon[keep], alt, p, strict=True):
            rows.append(f"{a.callsign},{t - sel.moment_s:.1f},{la:.6f},{lo:.6f},{h:.0f},{x:.4f},{y:.4f},{z:.4f}")
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path


