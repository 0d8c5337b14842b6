"""ADS-B recordings: flights read with ``traffic``, cleaned, their landings detected and their altitudes calibrated.

The selection of a moment's arrivals and the scenario they make are :mod:`mal_planner.geo.adsb`'s.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
from pymap3d.vincenty import vdist
from scipy.ndimage import median_filter

from mal_planner.geo.runways import Runway
from mal_planner.units import ft_to_m, nm_to_ft

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


def _live(g):
    """The samples of one flight (sorted by time) whose position is new: a receiver repeats the last position until a
    new one is decoded (in ``traffic``'s sample 7.8 % of the rows; 65 runs longer than 20 s, up to 334 s, mostly after
    touchdown). A repeat is dropped, so a position is at most :data:`MAX_SAMPLE_GAP_S` old where a moment is
    interpolated (:meth:`Track.covers`), landings are detected and altitudes calibrated on live samples, and a flight
    ends at its last live sample."""
    lat, lon = _clean(g["latitude"]), _clean(g["longitude"])
    return g[np.r_[True, (np.diff(lat) != 0.0) | (np.diff(lon) != 0.0)]]


def tracks_from_frame(df) -> list[Track]:
    """Tracks from a pandas DataFrame with traffic's columns (one flight per ``flight_id``, else per
    icao24/callsign); rows with a missing position, altitude, speed or track are dropped."""
    df = df.dropna(subset=["latitude", "longitude", "altitude", "groundspeed", "track", "timestamp"])
    keys = ["flight_id"] if "flight_id" in df.columns else ["icao24", "callsign"]
    out = []
    for key, g in df.groupby(keys, sort=True):
        g = _live(g.sort_values("timestamp").drop_duplicates("timestamp"))
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
