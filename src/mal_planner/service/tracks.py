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
AHEAD_TOLERANCE_S = 2.0
"""Radar time may run this far ahead of the newest track (plus the wall time since it came): more is a bad
stamp, which, if kept, would make every later message of that aircraft look old (a frozen track)."""


class Rejection(str):
    """Why a track is refused: the text for the log, ``key`` for the counts (frame, heading, jump, ...)."""

    key: str

    def __new__(cls, key: str, text: str) -> Rejection:
        obj = super().__new__(cls, text)
        obj.key = key
        return obj


def check_track(track: Track, frame_id: str, expected_frame: str, airspace: np.ndarray | None = None,
                margin_nm: float = 1.0, *, expected_speed: float | None = None, newest: float | None = None,
                timeout_s: float = 0.0, now: float | None = None, max_ahead_s: float | None = None,
                previous: Track | None = None, jump_tol_nm: float = 0.0) -> Rejection | None:
    """None when the track is usable, else the reason (NaN, unknown frame/units, absurd values, bad stamps).

    ``expected_speed``: the scenario's speed of this callsign [nm/s]; ``newest``: the newest stamp held,
    older than ``timeout_s`` before it is stale, more than ``max_ahead_s`` after it too far ahead; ``now``: the
    node's clock, for stamps in the future; ``previous``: this aircraft's last track, for jumps it cannot fly
    (more than ``SPEED_FACTOR`` times its speed, plus ``jump_tol_nm`` of radar error).
    """
    if not CALLSIGN_RE.match(track.callsign):
        return Rejection("callsign", f"invalid callsign {track.callsign!r}")
    if frame_id != expected_frame:
        what = "empty frame_id" if not frame_id else f"unknown frame {frame_id!r}"
        return Rejection("frame", f"{what} (expected {expected_frame!r}, ENU metres)")
    values = [track.stamp, *track.state.tolist(), track.speed]
    if not all(math.isfinite(v) for v in values):
        names = ["stamp", "x", "y", "z", "flight_path_angle", "heading", "speed"]
        bad = [n for n, v in zip(names, values, strict=True) if not math.isfinite(v)]
        return Rejection("non_finite", "non-finite " + ", ".join(bad))
    if track.stamp <= 0.0:
        return Rejection("stamp", f"stamp {track.stamp:g} is not set (a time origin of 0 is refused)")
    if not 0.0 < track.speed <= MAX_SPEED_NM_S:
        return Rejection("speed", f"speed {track.speed * 1852.0:.6g} m/s is not in (0, "
                                  f"{MAX_SPEED_NM_S * 1852.0:.0f}] m/s (units?)")
    if abs(track.state[3]) > math.pi / 2:
        return Rejection("flight_path_angle",
                         f"flight-path angle {track.state[3]:.6g} rad is not in [-pi/2, pi/2] (degrees given?)")
    if abs(track.state[4]) > 2 * math.pi:
        return Rejection("heading", f"heading {track.state[4]:.6g} rad is not in [-2 pi, 2 pi] (degrees given?)")
    if airspace is not None:
        pos = track.state[:3]
        if np.any(pos < airspace[:, 0] - margin_nm) or np.any(pos > airspace[:, 1] + margin_nm):
            xyz = ", ".join(f"{v * 1852.0:.1f}" for v in pos)
            return Rejection("position", f"position ({xyz}) m is far outside the airspace (units?)")
        floor = float(airspace[2, 0])
        if pos[2] < floor - FLOOR_MARGIN_NM:
            return Rejection("altitude", f"altitude {pos[2] * 1852.0:.0f} m is far below the airspace floor "
                                         f"({floor * 1852.0:.0f} m)")
    if expected_speed is not None and not expected_speed / SPEED_FACTOR <= track.speed <= expected_speed * SPEED_FACTOR:
        return Rejection("speed", f"speed {track.speed * 1852.0:.1f} m/s is implausible for this aircraft "
                                  f"(scenario: {expected_speed * 1852.0:.1f} m/s)")
    if newest is not None and timeout_s > 0 and track.stamp < newest - timeout_s:
        return Rejection("stale", f"stale stamp: {newest - track.stamp:.1f} s older than the newest track "
                                  f"(track_timeout_s {timeout_s:g})")
    if now is not None and track.stamp > now + FUTURE_TOLERANCE_S:
        return Rejection("future", f"stamp {track.stamp:.3f} is {track.stamp - now:.1f} s in the future")
    if newest is not None and max_ahead_s is not None and track.stamp > newest + max_ahead_s:
        return Rejection("future", f"stamp {track.stamp:.3f} is {track.stamp - newest:.1f} s ahead of the newest "
                                   f"track (at most {max_ahead_s:.1f} s)")
    if previous is not None and track.stamp > previous.stamp:
        dt = track.stamp - previous.stamp
        moved = float(np.linalg.norm(track.state[:3] - previous.state[:3]))
        reach = SPEED_FACTOR * max(track.speed, previous.speed) * dt + jump_tol_nm
        if moved > reach:
            return Rejection("jump", f"jump of {moved * 1852.0:.0f} m in {dt:.2f} s (it can fly at most "
                                     f"{reach * 1852.0:.0f} m)")
    return None


class TrackStore:
    """Newest track per callsign; older or duplicate stamps (the same track on two topics) are ignored."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._tracks: dict[str, Track] = {}

    def update(self, track: Track) -> str:
        """Store ``track`` if it is newer than the one held: ``stored``; else ``older``, ``duplicate`` (the same
        state again, e.g. from a second topic) or ``conflict`` (another state with the same stamp)."""
        with self._lock:
            old = self._tracks.get(track.callsign)
            if old is not None and track.stamp < old.stamp:
                return "older"
            if old is not None and track.stamp == old.stamp:
                same = np.allclose(track.state, old.state, rtol=0.0, atol=1e-9) and abs(track.speed - old.speed) < 1e-12
                return "duplicate" if same else "conflict"
            self._tracks[track.callsign] = track
            return "stored"

    def get(self, callsign: str) -> Track | None:
        with self._lock:
            return self._tracks.get(callsign)

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
