"""Unit and frame conversions between the planner (nm, s, rad) and ROS topics (SI).

The planner frame is the runway frame of the thesis: right-handed, z up, origin at the runway threshold; in a
local scenario x is east and y north (ENU), in a geodetic one it is the threshold's east-north-up plane turned so
that the landing direction is -y (:mod:`mal_planner.geodesy`). ROS topics use the same frame (``runway``), so the
boundary only scales lengths and speeds. Headings are mathematical angles from +x, counter-clockwise, the same
convention as yaw in REP 103.
This is the only place where these factors are written.
"""

from __future__ import annotations

import math

import numpy as np

METRES_PER_NM: float = 1852.0
"""International nautical mile in metres."""

METRES_PER_FT: float = 0.3048
"""International foot in metres."""

SECONDS_PER_HOUR: float = 3600.0
"""A knot is one nautical mile per hour."""

PLANNER_FRAME = "runway"


def nm_to_m(value):
    """Nautical miles (scalar or array) to metres."""
    return np.asarray(value, dtype=float) * METRES_PER_NM if not np.isscalar(value) else value * METRES_PER_NM


def m_to_nm(value):
    """Metres (scalar or array) to nautical miles."""
    return np.asarray(value, dtype=float) / METRES_PER_NM if not np.isscalar(value) else value / METRES_PER_NM


def ft_to_nm(value: float) -> float:
    """Feet to nautical miles."""
    return value * METRES_PER_FT / METRES_PER_NM


def nm_to_ft(value: float) -> float:
    """Nautical miles to feet."""
    return value * METRES_PER_NM / METRES_PER_FT


def ft_to_m(value):
    """Feet (scalar or array) to metres."""
    return value * METRES_PER_FT


def m_to_ft(value):
    """Metres (scalar or array) to feet."""
    return value / METRES_PER_FT


def kt_to_nm_per_s(value):
    """Knots (scalar or array) to nm/s."""
    return value / SECONDS_PER_HOUR


def nm_per_s_to_kt(value):
    """nm/s (scalar or array) to knots."""
    return value * SECONDS_PER_HOUR


def nm_per_s_to_m_per_s(value: float) -> float:
    return value * METRES_PER_NM


def m_per_s_to_nm_per_s(value: float) -> float:
    return value / METRES_PER_NM


def deg(value_rad):
    """Radians to degrees."""
    return np.degrees(value_rad)


def rad(value_deg):
    """Degrees to radians."""
    return np.radians(value_deg)


def wrap_angle(angle: float) -> float:
    """Wrap an angle to (-pi, pi]."""
    wrapped = math.remainder(angle, 2.0 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped
