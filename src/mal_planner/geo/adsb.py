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
  :data:`SLOPE_WINDOW_S`;
* with ``--bag``, a rosbag2 bag (MCAP) of their real tracks before the moment (``mal_msgs/AircraftState`` in
  the runway frame on ``/aircraft/<callsign>/state`` and ``/radar/tracks``, stamped in UTC), which
  ``mal-launch --replay`` / ``mal-replay`` play to the planner node;
* with ``--tracks``, their real tracks from the moment to the landing (CSV, for figures).

The planner's aircraft fly at constant speed without wind: each gets its ground speed at the moment. An
aircraft that the scenario cannot hold is left out, with the reason logged: no samples around the moment,
already landed, outside the terminal area, above its ceiling, or closer than the separation to an aircraft that
lands before it (the planner needs a separated start).

Altitudes: ADS-B gives barometric (pressure) altitude, referred to 1013.25 hPa, not to the day's sea-level
pressure. The converter calibrates it on the recording's own landings: an ILS approach crosses the threshold at
:data:`THRESHOLD_CROSSING_HEIGHT_FT`, so the offset is the median, over the landings detected, of the threshold
elevation + that height - the recorded altitude at the threshold (the 3 deg glide extrapolated to it). The
offset absorbs the day's pressure, the geoid and the table's airport-wide elevation alike.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import yaml
from pymap3d.vincenty import vdist
from scipy.ndimage import median_filter

from mal_planner.geo.runways import Runway, runways
from mal_planner.geodesy import GeoFrame
from mal_planner.profiles import TMA, TrafficProfile
from mal_planner.units import ft_to_m, ft_to_nm, nm_to_ft

log = logging.getLogger("mal_planner.geo.adsb")

THRESHOLD_CROSSING_HEIGHT_FT = 50.0
"""ILS reference datum height: an ILS glide path crosses the threshold 15 m (50 ft) high (ICAO Annex 10)."""
FINAL_APPROACH_NM = (0.3, 4.0)
"""A landing's final approach: the part of the track between these distances before the threshold (nm) ..."""
FINAL_HALF_WIDTH_NM = 0.15
"""... within this of the extended centre line (half the 0.2-nm spacing of LFPG's close pairs would be 0.1;
ADS-B positions are good to tens of metres, and the nearer centre line wins) ..."""
FINAL_GLIDE_DEG = (2.0, 4.5)
"""... descending along a glide path this steep (the altitude against the distance to go) ..."""
PRESSURE_MARGIN_FT = 2000.0
"""... to a recorded altitude over the threshold within this of its elevation (barometric altitude is off by
about 28 ft per hPa of the day's sea-level pressure from 1013.25; 950-1070 hPa is -1700 to +1600 ft) ..."""
FINAL_TRACK_DEG = 20.0
"""... and flying within this of the runway's course."""
FINAL_MIN_SAMPLES = 5
FINAL_MIN_SPAN_NM = 1.0
"""A final approach holds this many samples over this distance at least."""
MAX_SAMPLE_GAP_S = 20.0
"""A state at a moment needs a sample this close before and after it (ADS-B: about one sample a second)."""
SLOPE_WINDOW_S = 10.0
"""The flight-path angle is the climb over +-this (altitudes come in 25-ft steps: a 20-s slope is good to 0.1 deg
at 200 kt)."""
ALTITUDE_MEDIAN_SAMPLES, ALTITUDE_OUTLIER_FT = 9, 500.0
"""A sample whose altitude is this far from the median of the 9 around it is an ADS-B glitch (9 s at one sample a
second: a 3,000-ft/min descent moves 450 ft, less than the outlier distance); it is dropped."""
FLIGHT_GAP = "10 min"
"""A flight ends where its samples stop for this long (traffic's iteration)."""


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


@dataclass
class Track:
    """One flight's ADS-B samples: time (s since the epoch, UTC) and state, sorted by time."""

    flight_id: str
    callsign: str
    t: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    alt_ft: np.ndarray
    """Recorded (barometric) altitude, uncalibrated."""
    gs_kt: np.ndarray
    track_deg: np.ndarray
    landing: Landing | None = field(default=None, repr=False)

    def interp(self, t: float | np.ndarray) -> dict[str, np.ndarray]:
        """Linear interpolation of the samples at ``t`` (the track angle unwrapped)."""
        track = np.degrees(np.unwrap(np.radians(self.track_deg)))
        return {"lat": np.interp(t, self.t, self.lat), "lon": np.interp(t, self.t, self.lon),
                "alt_ft": np.interp(t, self.t, self.alt_ft), "gs_kt": np.interp(t, self.t, self.gs_kt),
                "track_deg": np.interp(t, self.t, track) % 360.0}

    def covers(self, t: float, gap_s: float = MAX_SAMPLE_GAP_S) -> bool:
        """True when a sample lies within ``gap_s`` before and after ``t``."""
        k = int(np.searchsorted(self.t, t))  # the first sample at or after t
        if k < len(self.t) and self.t[k] == t:
            return True
        return 0 < k < len(self.t) and t - self.t[k - 1] <= gap_s and self.t[k] - t <= gap_s


@dataclass(frozen=True)
class Landing:
    """Where and when a flight landed: runway, time over the threshold (s, UTC) and recorded altitude there."""

    runway: Runway
    time_s: float
    altitude_ft: float
    offset_nm: float
    """Median distance from the extended centre line on the final approach."""


def _clean(values) -> np.ndarray:
    return np.asarray(values, dtype=float)


def tracks_from_frame(df) -> list[Track]:
    """Tracks from a pandas DataFrame with traffic's columns (one flight per ``flight_id``, else per
    icao24/callsign); rows with a missing position, altitude, speed or track are dropped."""
    df = df.dropna(subset=["latitude", "longitude", "altitude", "groundspeed", "track", "timestamp"])
    keys = ["flight_id"] if "flight_id" in df.columns else ["icao24", "callsign"]
    out = []
    for key, g in df.groupby(keys, sort=True):
        g = g.sort_values("timestamp").drop_duplicates("timestamp")
        if len(g) < 2:
            continue
        t = g["timestamp"].astype("int64").to_numpy() / 1e9 if hasattr(g["timestamp"], "dt") else _clean(g["timestamp"])
        key = key if isinstance(key, tuple) else (key,)
        callsign = str(g["callsign"].iloc[0]) if "callsign" in g.columns else str(key[0])
        alt = _clean(g["altitude"])
        good = np.abs(alt - median_filter(alt, size=ALTITUDE_MEDIAN_SAMPLES, mode="nearest")) <= ALTITUDE_OUTLIER_FT
        if good.sum() < 2:
            continue
        out.append(Track("_".join(map(str, key)), callsign.strip(), _clean(t)[good], _clean(g["latitude"])[good],
                         _clean(g["longitude"])[good], alt[good], _clean(g["groundspeed"])[good],
                         _clean(g["track"])[good]))
    return out


def load_tracks(source: str | Path | None = None) -> list[Track]:
    """The flights of a recording: ``traffic``'s sample ``quickstart`` (None) or a file ``traffic`` reads.

    Flights are split where samples stop for :data:`FLIGHT_GAP` (traffic's own iteration); needs the ``adsb``
    extra (``pip install -e '.[adsb]'``)."""
    try:
        from traffic.core import Traffic
    except ImportError as exc:
        raise RuntimeError(f"the traffic library is missing ({exc}): pip install -e '.[adsb]'") from None
    if source is None:
        from traffic.data.samples import quickstart as data
    else:
        path = Path(source)
        if not path.is_file():
            raise FileNotFoundError(f"{path}: no such file")
        data = Traffic.from_file(path)
        if data is None:
            raise ValueError(f"{path}: traffic cannot read this file (parquet, csv, json, pickle, ...)")
    flights = []
    for i, flight in enumerate(data.iterate(by=FLIGHT_GAP)):
        frame = flight.data.assign(flight_id=f"{flight.callsign}_{flight.icao24}_{i}")
        flights.append(frame)
    import pandas as pd

    return tracks_from_frame(pd.concat(flights, ignore_index=True))


def _last_run(mask: np.ndarray) -> np.ndarray:
    """Only the last run of True values of a mask (the flight's last pass through the final approach)."""
    idx = np.flatnonzero(mask)
    out = np.zeros_like(mask)
    if idx.size:
        start = idx[-1]
        while start > 0 and mask[start - 1]:
            start -= 1
        out[start:idx[-1] + 1] = True
    return out


def detect_landing(track: Track, candidates: Iterable[Runway]) -> Landing | None:
    """The runway a flight lands on: the candidate whose final approach holds :data:`FINAL_MIN_SAMPLES` of the
    flight's samples nearest its centre line (see :data:`FINAL_APPROACH_NM` and the following), or None."""
    best: Landing | None = None
    top_ft = nm_to_ft(FINAL_APPROACH_NM[1]) * math.tan(math.radians(FINAL_GLIDE_DEG[1]))
    for rw in candidates:
        p = rw.frame.to_local(track.lat, track.lon, np.full_like(track.lat, rw.frame.elevation_ft))
        x, y = p[:, 0], p[:, 1]
        heading_off = (track.track_deg - rw.frame.course_deg + 180.0) % 360.0 - 180.0
        final = ((y > FINAL_APPROACH_NM[0]) & (y < FINAL_APPROACH_NM[1]) & (np.abs(x) < FINAL_HALF_WIDTH_NM)
                 & (np.abs(heading_off) < FINAL_TRACK_DEG)
                 & (track.alt_ft < rw.frame.elevation_ft + PRESSURE_MARGIN_FT + top_ft))
        final = _last_run(final)
        if final.sum() < FINAL_MIN_SAMPLES or np.ptp(y[final]) < FINAL_MIN_SPAN_NM:
            continue
        offset = float(np.median(np.abs(x[final])))
        if best is not None and best.offset_nm <= offset:
            continue
        # over the threshold: the final approach's straight line (time and altitude against y) at y = 0
        alt_fit = np.polyfit(y[final], track.alt_ft[final], 1)
        slope_deg = math.degrees(math.atan(alt_fit[0] / nm_to_ft(1.0)))
        over = float(np.polyval(alt_fit, 0.0))
        if not (FINAL_GLIDE_DEG[0] <= slope_deg <= FINAL_GLIDE_DEG[1]
                and abs(over - rw.frame.elevation_ft) <= PRESSURE_MARGIN_FT):
            continue
        t_fit = np.polyfit(y[final], track.t[final], 1)
        best = Landing(rw, float(np.polyval(t_fit, 0.0)), over, offset)
    return best


def altimeter_offset_ft(tracks: Iterable[Track]) -> float:
    """What to add to the recorded altitudes: median of (threshold elevation + crossing height - recorded
    altitude at the threshold) over the detected landings; ValueError without landings."""
    diffs = [t.landing.runway.frame.elevation_ft + THRESHOLD_CROSSING_HEIGHT_FT - t.landing.altitude_ft
             for t in tracks if t.landing is not None]
    if not diffs:
        raise ValueError("no landing in the recording: the altitudes cannot be calibrated (give --altitude-offset-ft)")
    return float(np.median(diffs))


def flight_path_angle_deg(track: Track, t: float) -> float:
    """The flight-path angle at ``t`` (deg, at the aircraft: climb over the geodesic distance flown) over
    +-:data:`SLOPE_WINDOW_S`."""
    a, b = track.interp(t - SLOPE_WINDOW_S), track.interp(t + SLOPE_WINDOW_S)
    distance_m, _ = vdist(float(a["lat"]), float(a["lon"]), float(b["lat"]), float(b["lon"]))
    return math.degrees(math.atan2(ft_to_m(float(b["alt_ft"]) - float(a["alt_ft"])), float(distance_m)))


def utc_seconds(text: str) -> float:
    """ISO 8601 time (``2021-10-07T12:30Z``, ``2021-10-07 12:30:00+00:00``; no zone: UTC) -> s since the epoch."""
    try:
        value = datetime.fromisoformat(text.strip().replace("Z", "+00:00").replace("z", "+00:00"))
    except ValueError:
        raise ValueError(f"time {text!r} is not ISO 8601 (e.g. 2021-10-07T14:43Z)") from None
    if value.tzinfo is None:
        value = value.replace(tzinfo=timezone.utc)
    return value.timestamp()


def utc_text(t: float) -> str:
    return datetime.fromtimestamp(t, tz=timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


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


def scenario_data(sel: Selection, name: str, profile: TrafficProfile = TMA, glide_path_deg: float | None = None,
                  vertical_ft: float | None = None) -> dict:
    """The geodetic scenario (a mapping for YAML) of a selection, with the terminal-area numbers of ``profile``."""
    if not sel.kept:
        raise ValueError(f"no arrival on {sel.runway.airport} {sel.runway.name} inside the terminal area at "
                         f"{utc_text(sel.moment_s)}")
    f = sel.runway.frame
    glide = profile.glide_path_deg if glide_path_deg is None else glide_path_deg
    separation = {"distance_nm": profile.separation_nm, "landing_spacing_s": profile.landing_spacing_s,
                  "max_landing_spacing_s": profile.max_landing_spacing_s}
    if vertical_ft is not None:
        separation["vertical_ft"] = vertical_ft
    return {
        "name": name,
        "description": f"{len(sel.kept)} real arrivals on {sel.runway.airport} {sel.runway.name} at "
                       f"{utc_text(sel.moment_s)} (ADS-B)",
        "gravity": 0.0052952,
        "runway": {"threshold": {"lat": f.lat_deg, "lon": f.lon_deg, "elevation_ft": f.elevation_ft},
                   "course_deg": f.course_deg, "flight_path_angle_deg": -abs(glide)},
        "airspace": sel.area.airspace(),
        "aircraft": [{"callsign": a.callsign, "lat": round(a.lat, 7), "lon": round(a.lon, 7),
                      "alt_ft": round(a.alt_ft, 1), "track_deg": round(a.track_deg, 2),
                      "flight_path_angle_deg": round(a.flight_path_angle_deg, 3), "speed_kt": round(a.speed_kt, 1)}
                     for a in sel.kept],
        "separation": separation,
        "limits": {"bank_angle_deg": profile.bank_angle_deg, "n_h": list(profile.n_h), "n_v": list(profile.n_v)},
    }


def header_lines(sel: Selection, source: str, command: str) -> list[str]:
    """The scenario file's comment: where it comes from and who was left out."""
    rw = sel.runway
    lines = [f"Real arrivals at {rw.airport} {rw.name} at {utc_text(sel.moment_s)}, from ADS-B ({source}), written by",
             f"  {command}",
             "Runway threshold and course: X-Plane apt.dat 2013.10 via bluesky-navdata 1.0.0 "
             "(mal_planner.geo.runways).",
             f"Altitudes: recorded barometric altitude {sel.altitude_offset_ft:+.1f} ft (calibrated on the "
             f"recording's landings: {THRESHOLD_CROSSING_HEIGHT_FT:.0f} ft over the threshold).",
             "Speeds are ground speeds at the moment (the planner flies constant speed, without wind).",
             "Real landings (s after the moment): " + ", ".join(
                 f"{a.callsign} {a.track.landing.time_s - sel.moment_s:.0f} ({a.track.landing.runway.name})"
                 for a in sel.kept)]
    lines += [f"Left out {c}: {r}" for c, r in sel.skipped]
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


