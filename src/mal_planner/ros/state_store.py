"""Latest radar track per aircraft (thread-safe), input checks and constant-speed extrapolation.

Everything here is in planner units (nm, s, rad); conversion from ROS messages is done by
:mod:`mal_planner.ros.convert` before a track gets here.
"""

from __future__ import annotations

import math
import re
import threading
from dataclasses import dataclass

import numpy as np

CALLSIGN_RE = re.compile(r"^[A-Za-z0-9_]{1,16}$")
MAX_SPEED_NM_S = 1.0
"""Largest plausible airspeed (1 nm/s = 1852 m/s); faster tracks are taken as a unit error."""


@dataclass(frozen=True)
class Track:
    """One radar measurement: stamp [s], state (x, y, z, gamma, heading) [nm, rad], speed [nm/s]."""

    callsign: str
    stamp: float
    state: np.ndarray
    speed: float
    wake: str | None = None

    def at(self, t: float) -> np.ndarray:
        """The state extrapolated to time ``t`` at constant speed, heading and flight-path angle."""
        return extrapolate(self.state, self.speed, t - self.stamp)


def extrapolate(state: np.ndarray, speed: float, dt: float) -> np.ndarray:
    """Straight flight for ``dt`` seconds: x' = V cos(g) cos(h), y' = V cos(g) sin(h), z' = V sin(g)."""
    x, y, z, gamma, heading = (float(v) for v in state)
    d = speed * dt
    return np.array([x + d * math.cos(gamma) * math.cos(heading), y + d * math.cos(gamma) * math.sin(heading),
                     z + d * math.sin(gamma), gamma, heading])


SPEED_FACTOR = 2.0
"""A known aircraft's track may be this factor slower or faster than its scenario speed, no more."""
FLOOR_MARGIN_NM = 0.1
"""Tracks this far below the airspace floor (about 185 m) are taken as bad altitude data."""
FUTURE_TOLERANCE_S = 10.0
"""Stamps this far ahead of the node's clock are in the future."""


def check_track(track: Track, frame_id: str, expected_frame: str, airspace: np.ndarray | None = None,
                margin_nm: float = 1.0, *, expected_speed: float | None = None, newest: float | None = None,
                timeout_s: float = 0.0, now: float | None = None) -> str | None:
    """None when the track is usable, else a short reason (NaN, unknown frame/units, absurd values).

    ``expected_speed``: the scenario's speed of this callsign [nm/s]; ``newest``: the newest stamp held,
    older than ``timeout_s`` before it is stale; ``now``: the node's clock, for stamps in the future.
    """
    if not CALLSIGN_RE.match(track.callsign):
        return f"invalid callsign {track.callsign!r}"
    if frame_id and frame_id != expected_frame:
        return f"unknown frame {frame_id!r} (expected {expected_frame!r}, ENU metres)"
    values = [track.stamp, *track.state.tolist(), track.speed]
    if not all(math.isfinite(v) for v in values):
        names = ["stamp", "x", "y", "z", "flight_path_angle", "heading", "speed"]
        bad = [n for n, v in zip(names, values, strict=True) if not math.isfinite(v)]
        return "non-finite " + ", ".join(bad)
    if not 0.0 < track.speed <= MAX_SPEED_NM_S:
        return f"speed {track.speed * 1852.0:.6g} m/s is not in (0, {MAX_SPEED_NM_S * 1852.0:.0f}] m/s (units?)"
    if abs(track.state[3]) > math.pi / 2:
        return f"flight-path angle {track.state[3]:.6g} rad is not in [-pi/2, pi/2] (degrees given?)"
    if airspace is not None:
        pos = track.state[:3]
        if np.any(pos < airspace[:, 0] - margin_nm) or np.any(pos > airspace[:, 1] + margin_nm):
            xyz = ", ".join(f"{v * 1852.0:.1f}" for v in pos)
            return f"position ({xyz}) m is far outside the airspace (units?)"
        floor = float(airspace[2, 0])
        if pos[2] < floor - FLOOR_MARGIN_NM:
            return f"altitude {pos[2] * 1852.0:.0f} m is far below the airspace floor ({floor * 1852.0:.0f} m)"
    if expected_speed is not None and not expected_speed / SPEED_FACTOR <= track.speed <= expected_speed * SPEED_FACTOR:
        return (f"speed {track.speed * 1852.0:.1f} m/s is implausible for this aircraft (scenario: "
                f"{expected_speed * 1852.0:.1f} m/s)")
    if newest is not None and timeout_s > 0 and track.stamp < newest - timeout_s:
        return f"stale stamp: {newest - track.stamp:.1f} s older than the newest track (track_timeout_s {timeout_s:g})"
    if now is not None and track.stamp > now + FUTURE_TOLERANCE_S:
        return f"stamp {track.stamp:.3f} is {track.stamp - now:.1f} s in the future"
    return None


class TrackStore:
    """Newest track per callsign; older or duplicate stamps (the same track on two topics) are ignored."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._tracks: dict[str, Track] = {}

    def update(self, track: Track) -> bool:
        """Store ``track`` if it is newer than the one held; True when stored."""
        with self._lock:
            old = self._tracks.get(track.callsign)
            if old is not None and track.stamp <= old.stamp:
                return False
            self._tracks[track.callsign] = track
            return True

    def snapshot(self) -> dict[str, Track]:
        with self._lock:
            return dict(self._tracks)

    def latest_stamp(self) -> float | None:
        with self._lock:
            return max((t.stamp for t in self._tracks.values()), default=None)

    def drop_older_than(self, stamp: float) -> list[str]:
        """Forget tracks last seen before ``stamp`` (landed or lost aircraft); return their callsigns."""
        with self._lock:
            gone = [cs for cs, t in self._tracks.items() if t.stamp < stamp]
            for cs in gone:
                del self._tracks[cs]
            return gone

    def __len__(self) -> int:
        with self._lock:
            return len(self._tracks)

    def __contains__(self, callsign: object) -> bool:
        with self._lock:
            return callsign in self._tracks
