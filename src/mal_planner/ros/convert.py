"""The one place for ROS message <-> planner conversions (pure functions, no DDS).

Planner side: nm, s, rad, state ``(x, y, z, gamma, heading)`` in the runway frame (ENU, heading = ENU yaw).
ROS side: SI units and ENU (REP 103). Every unit factor comes from :mod:`mal_planner.units`.

``types`` arguments are a node's ``node.types`` (anything with ``.msg("pkg/msg/Name")``), so the same code
builds messages for the rclpy and the built-in Cyclone backend; both have the same field names.

Orientation (REP 103 body frame: x forward, y left, z up): yaw = heading, pitch = -flight_path_angle
(positive pitch is nose down), roll = -bank, where ``bank`` is the planner's bank angle
``mu = atan2(n_h, n_v)``: positive ``n_h`` turns the aircraft counter-clockwise (left) in this model, so
a positive ``mu`` is a left-wing-down bank, which REP 103 calls a negative roll.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from mal_planner.obstacles import Superquadric
from mal_planner.units import PLANNER_FRAME, ft_to_m, m_per_s_to_nm_per_s, m_to_nm, nm_per_s_to_m_per_s, nm_to_m

if TYPE_CHECKING:
    from mal_planner.geodesy import GeoFrame

__all__ = [
    "NoFlyZoneError",
    "aircraft_state_to_planner",
    "euler_from_quaternion",
    "frame_origin_fields",
    "geodetic_path_fields",
    "msg_to_time",
    "no_fly_zone_update",
    "path_msg",
    "path_to_planner",
    "planner_to_aircraft_state",
    "pose_from_state",
    "quaternion_from_euler",
    "time_to_msg",
    "wind_msg",
    "wind_to_planner",
]

_NS_PER_S = 1_000_000_000


def time_to_msg(types: Any, t_s: float) -> Any:
    """``builtin_interfaces/msg/Time`` for ``t_s`` seconds (rounded to the nanosecond)."""
    ns = int(round(float(t_s) * _NS_PER_S))
    return types.msg("builtin_interfaces/msg/Time")(sec=ns // _NS_PER_S, nanosec=ns % _NS_PER_S)


def byte_field(types: Any, value: int) -> Any:
    """Value for a ``byte`` field (e.g. DiagnosticStatus.level): rclpy wants ``bytes`` of length 1 (an int
    is accepted but serialized wrongly), the built-in backend an int."""
    return bytes([value]) if getattr(types, "bytes_for_byte", False) else value


def byte_value(value: Any) -> int:
    """An int from a received ``byte`` field of either backend."""
    return value[0] if isinstance(value, bytes | bytearray) else int(value)


def msg_to_time(msg: Any) -> float:
    """Seconds from a ``Time`` message, or from the stamp of a ``Header`` or of any message with a header."""
    if hasattr(msg, "header"):
        msg = msg.header
    if hasattr(msg, "stamp"):
        msg = msg.stamp
    return int(msg.sec) + int(msg.nanosec) / _NS_PER_S


def _header(types: Any, t_s: float, frame: str) -> Any:
    return types.msg("std_msgs/msg/Header")(stamp=time_to_msg(types, t_s), frame_id=frame)


def aircraft_state_to_planner(msg: Any) -> tuple[str, float, np.ndarray, float, str | None]:
    """``mal_msgs/AircraftState`` -> ``(callsign, stamp_s, state (5,) nm/rad, speed nm/s, wake or None)``."""
    p = msg.position
    state = np.array(
        [m_to_nm(float(p.x)), m_to_nm(float(p.y)), m_to_nm(float(p.z)), float(msg.flight_path_angle),
         float(msg.heading)]
    )  # fmt: skip
    wake = str(msg.wake_category) or None
    return str(msg.callsign), msg_to_time(msg), state, m_per_s_to_nm_per_s(float(msg.speed)), wake


def wind_to_planner(msg: Any, frame: str) -> tuple[float, float]:
    """``geometry_msgs/Vector3Stamped`` wind (the air's velocity over the ground, m/s, ENU in ``frame``) ->
    ``(w_x, w_y)`` nm/s; ValueError (one line) for another frame, a non-finite or a vertical component."""
    if str(msg.header.frame_id) != frame:
        raise ValueError(f"frame {msg.header.frame_id!r}, expected {frame!r}")
    v = msg.vector
    wx, wy, wz = float(v.x), float(v.y), float(v.z)
    if not all(math.isfinite(c) for c in (wx, wy, wz)):
        raise ValueError("non-finite component")
    if wz != 0.0:
        raise ValueError(f"vertical component {wz:g} m/s (the planner's wind is horizontal)")
    return m_per_s_to_nm_per_s(wx), m_per_s_to_nm_per_s(wy)


def wind_msg(types: Any, t_s: float, wind_nm_s: Sequence[float], frame: str = PLANNER_FRAME) -> Any:
    """``geometry_msgs/Vector3Stamped`` [m/s] of a planner wind (w_x, w_y) [nm/s]."""
    vec = types.msg("geometry_msgs/msg/Vector3")(x=nm_per_s_to_m_per_s(float(wind_nm_s[0])),
                                                 y=nm_per_s_to_m_per_s(float(wind_nm_s[1])), z=0.0)
    return types.msg("geometry_msgs/msg/Vector3Stamped")(header=_header(types, t_s, frame), vector=vec)


def planner_to_aircraft_state(
    types: Any,
    callsign: str,
    stamp_s: float,
    state: Sequence[float] | np.ndarray,
    speed_nm_s: float,
    wake: str | None = None,
    frame: str = PLANNER_FRAME,
) -> Any:
    """Planner state ``(x, y, z, gamma, heading)`` [nm, rad] and speed [nm/s] -> ``mal_msgs/AircraftState``."""
    x, y, z, gamma, heading = (float(v) for v in np.asarray(state, dtype=float)[:5])
    return types.msg("mal_msgs/msg/AircraftState")(
        header=_header(types, stamp_s, frame),
        callsign=callsign,
        position=types.msg("geometry_msgs/msg/Point")(x=nm_to_m(x), y=nm_to_m(y), z=nm_to_m(z)),
        flight_path_angle=gamma,
        heading=heading,
        speed=nm_per_s_to_m_per_s(float(speed_nm_s)),
        wake_category=wake or "",
    )


def quaternion_from_euler(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    """Quaternion ``(x, y, z, w)`` of the intrinsic z-y'-x'' rotation (yaw, then pitch, then roll)."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    )


def euler_from_quaternion(x: float, y: float, z: float, w: float) -> tuple[float, float, float]:
    """``(roll, pitch, yaw)`` of a quaternion (inverse of :func:`quaternion_from_euler`)."""
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return roll, pitch, yaw


def pose_from_state(
    types: Any, t_s: float, state: Sequence[float] | np.ndarray, bank: float = 0.0, frame: str = PLANNER_FRAME
) -> Any:
    """``geometry_msgs/PoseStamped`` [m] of a planner state; roll = -bank, pitch = -gamma, yaw = heading."""
    x, y, z, gamma, heading = (float(v) for v in np.asarray(state, dtype=float)[:5])
    qx, qy, qz, qw = quaternion_from_euler(-float(bank), -gamma, heading)
    pose = types.msg("geometry_msgs/msg/Pose")(
        position=types.msg("geometry_msgs/msg/Point")(x=nm_to_m(x), y=nm_to_m(y), z=nm_to_m(z)),
        orientation=types.msg("geometry_msgs/msg/Quaternion")(x=qx, y=qy, z=qz, w=qw),
    )
    return types.msg("geometry_msgs/msg/PoseStamped")(header=_header(types, t_s, frame), pose=pose)


def path_msg(
    types: Any,
    callsign: str,
    t0_s: float,
    t: Sequence[float] | np.ndarray,
    states: np.ndarray,
    bank: Sequence[float] | np.ndarray | None = None,
    frame: str = PLANNER_FRAME,
) -> Any:
    """``nav_msgs/Path`` of a trajectory: pose k is stamped ``t0_s + t[k]``; header stamp ``t0_s``.

    ``callsign`` is not part of ``nav_msgs/Path`` (the topic ``aircraft/<callsign>/path`` names the aircraft);
    it is accepted so that callers keep one signature for all trajectory messages.
    """
    del callsign
    times = np.asarray(t, dtype=float)
    xs = np.asarray(states, dtype=float).reshape(len(times), -1)
    banks = np.zeros(len(times)) if bank is None else np.asarray(bank, dtype=float)
    poses = [pose_from_state(types, t0_s + tk, xk, bk, frame) for tk, xk, bk in zip(times, xs, banks, strict=True)]
    return types.msg("nav_msgs/msg/Path")(header=_header(types, t0_s, frame), poses=poses)


def frame_origin_fields(frame: GeoFrame | None) -> dict[str, Any]:
    """``LandingPlan``'s geodetic fields: where the runway frame lies on the Earth (deg, m above mean sea
    level, true course in deg); ``geodetic`` false and NaNs for a local frame."""
    if frame is None:
        return {"geodetic": False, "origin_latitude": math.nan, "origin_longitude": math.nan,
                "origin_altitude": math.nan, "course": math.nan}
    return {"geodetic": True, "origin_latitude": float(frame.lat_deg), "origin_longitude": float(frame.lon_deg),
            "origin_altitude": float(ft_to_m(frame.elevation_ft)), "course": float(frame.course_deg)}


def geodetic_path_fields(frame: GeoFrame | None, states: np.ndarray) -> dict[str, list[float]]:
    """``AircraftPlan``'s ``latitude``/``longitude`` [deg] and ``altitude`` [m above mean sea level] of planner
    states (n, 5) in the runway frame; empty lists for a local frame."""
    if frame is None:
        return {"latitude": [], "longitude": [], "altitude": []}
    lat, lon, alt_ft = frame.to_geodetic(np.asarray(states, dtype=float)[:, :3])
    return {"latitude": np.atleast_1d(lat).tolist(), "longitude": np.atleast_1d(lon).tolist(),
            "altitude": ft_to_m(np.atleast_1d(alt_ft)).tolist()}


def path_to_planner(msg: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``nav_msgs/Path`` -> ``(stamps_s (n,), states (n, 5) nm/rad, bank (n,) rad)`` (inverse of path_msg)."""
    n = len(msg.poses)
    stamps, states, banks = np.zeros(n), np.zeros((n, 5)), np.zeros(n)
    for k, ps in enumerate(msg.poses):
        p, q = ps.pose.position, ps.pose.orientation
        roll, pitch, yaw = euler_from_quaternion(float(q.x), float(q.y), float(q.z), float(q.w))
        stamps[k] = msg_to_time(ps)
        states[k] = [m_to_nm(float(p.x)), m_to_nm(float(p.y)), m_to_nm(float(p.z)), -pitch, yaw]
        banks[k] = -roll
    return stamps, states, banks


class NoFlyZoneError(ValueError):
    """An invalid ``mal_msgs/NoFlyZone`` message (one-line reason)."""


def no_fly_zone_update(msg: Any) -> tuple[str, Superquadric | None]:
    """``mal_msgs/NoFlyZone`` (metres) -> (its name, the zone as a :class:`Superquadric` in nm, or None to remove
    it); raises NoFlyZoneError."""
    name = str(msg.name).strip()
    if not name:
        raise NoFlyZoneError("empty name")
    if bool(msg.remove):
        return name, None
    center = [float(msg.center.x), float(msg.center.y), float(msg.center.z)]
    axes = [float(msg.semi_axes.x), float(msg.semi_axes.y), float(msg.semi_axes.z)]
    if not all(math.isfinite(v) for v in center + axes):
        raise NoFlyZoneError(f"{name!r}: non-finite center or semi-axes")
    if min(axes) <= 0.0:
        raise NoFlyZoneError(f"{name!r}: semi-axes {axes} m must all be > 0")
    p = int(msg.p)
    if p < 2 or p % 2:
        raise NoFlyZoneError(f"{name!r}: p must be an even integer >= 2, got {p}")
    return name, Superquadric(name, tuple(float(m_to_nm(v)) for v in center),  # type: ignore[arg-type]
                              tuple(float(m_to_nm(v)) for v in axes), p)  # type: ignore[arg-type]
