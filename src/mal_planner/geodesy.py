"""The planner's runway frame anchored on the Earth: geodetic (WGS84 lat/lon, ft, kt) <-> local (nm, rad).

The local frame is the thesis's runway frame: origin at the runway threshold, z up, and turned about z so
that the landing direction is the local heading -90 deg (towards -y; the approach comes from +y, as in the
thesis). It is the local east-north-up tangent plane of pymap3d at the threshold (WGS84), turned by
``course_deg - 180`` deg: a runway with a true course of 180 deg (landing due south) has the local frame
equal to ENU, x east and y north.

Lengths are straight lines in that tangent plane, so the local z of a point is its height above the plane
through the threshold, not its altitude above the threshold: the two differ by the Earth's curvature,
about d^2 / (2 R), 27 m (88 ft) at 10 nm and 240 m at 30 nm. Altitudes (``alt_ft``, ``elevation_ft``) are
above mean sea level (MSL): runway elevations are published so and the ADS-B converter calibrates altitudes to
them. The frame's geometry takes them as heights above the WGS84 ellipsoid (no geoid model installs offline):
the frame then lies higher or lower by the geoid undulation (about 45 m at CDG), the same for every point, so local
positions and heights above the threshold are unaffected up to the undulation's variation across the area (metres
over tens of nm).

Directions (heading and flight-path angle) are those of the velocity vector: the true track at an aircraft
is measured from the north of its own position, which differs from the north of the threshold by the
meridian convergence (about 1 deg at 60 nm, lat 49 deg); pymap3d's ENU <-> ECEF vector rotations carry the
vector from one to the other.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pymap3d

from mal_planner.units import ft_to_m, m_to_ft, m_to_nm, nm_to_m, wrap_angle

LANDING_HEADING = -0.5 * math.pi
"""The runway's heading in the local frame (rad): the thesis's, landing towards -y."""


@dataclass(frozen=True)
class GeoFrame:
    """The local frame of a runway given by its threshold (WGS84) and true course."""

    lat_deg: float
    lon_deg: float
    elevation_ft: float
    """Altitude of the threshold (and of the frame's origin) above mean sea level, in ft (see the module's
    docstring for the datum)."""
    course_deg: float
    """True course of the landing direction, clockwise from true north, in degrees."""

    @property
    def _turn(self) -> tuple[float, float]:
        """cos and sin of the turn ENU -> local (counter-clockwise about z)."""
        angle = math.radians(self.course_deg - 180.0)
        return math.cos(angle), math.sin(angle)

    def _enu_to_local(self, e, n, u) -> np.ndarray:
        c, s = self._turn
        return np.stack([c * e - s * n, s * e + c * n, u], axis=-1)

    def _local_to_enu(self, points) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        p = np.asarray(points, dtype=float)
        c, s = self._turn
        return c * p[..., 0] + s * p[..., 1], -s * p[..., 0] + c * p[..., 1], p[..., 2]

    def to_local(self, lat_deg, lon_deg, alt_ft) -> np.ndarray:
        """Geodetic positions (scalars or arrays of one shape) to local points (..., 3) in nm."""
        e, n, u = pymap3d.geodetic2enu(np.asarray(lat_deg, float), np.asarray(lon_deg, float),
                                       ft_to_m(np.asarray(alt_ft, float)), self.lat_deg, self.lon_deg,
                                       ft_to_m(self.elevation_ft))
        return m_to_nm(self._enu_to_local(e, n, u))

    def to_geodetic(self, points) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Local points (..., 3) in nm to (lat_deg, lon_deg, alt_ft), each of shape (...)."""
        e, n, u = self._local_to_enu(nm_to_m(np.asarray(points, dtype=float)))
        lat, lon, h = pymap3d.enu2geodetic(e, n, u, self.lat_deg, self.lon_deg, ft_to_m(self.elevation_ft))
        return np.asarray(lat, float), np.asarray(lon, float), m_to_ft(np.asarray(h, float))

    def direction_to_local(self, lat_deg: float, lon_deg: float, track_deg: float,
                           flight_path_angle_deg: float) -> tuple[float, float]:
        """A velocity's true track and flight-path angle at a geodetic position -> local (heading, gamma) in rad."""
        track, fpa = math.radians(track_deg), math.radians(flight_path_angle_deg)
        # the unit velocity in the aircraft's own ENU frame: east, north, up
        vx, vy, vz = pymap3d.enu2ecefv(math.cos(fpa) * math.sin(track), math.cos(fpa) * math.cos(track),
                                       math.sin(fpa), lat_deg, lon_deg)
        e, n, u = pymap3d.ecef2enuv(vx, vy, vz, self.lat_deg, self.lon_deg)
        x, y, z = self._enu_to_local(e, n, u)
        return wrap_angle(math.atan2(y, x)), math.atan2(z, math.hypot(x, y))

    def heading_of_true_track(self, track_deg: float) -> float:
        """The local heading (rad) of a true track (deg) at the threshold (e.g. a wind's direction)."""
        return self.direction_to_local(self.lat_deg, self.lon_deg, track_deg, 0.0)[0]

    def direction_to_geodetic(self, point, heading: float, gamma: float) -> tuple[float, float]:
        """A local (heading, gamma) in rad at a local point (nm) -> (true track, flight-path angle) in degrees."""
        lat, lon, _ = self.to_geodetic(point)
        e, n, u = self._local_to_enu([math.cos(gamma) * math.cos(heading), math.cos(gamma) * math.sin(heading),
                                      math.sin(gamma)])
        vx, vy, vz = pymap3d.enu2ecefv(e, n, u, self.lat_deg, self.lon_deg)
        e1, n1, u1 = pymap3d.ecef2enuv(vx, vy, vz, float(lat), float(lon))
        return math.degrees(math.atan2(e1, n1)) % 360.0, math.degrees(math.atan2(u1, math.hypot(e1, n1)))

    def describe(self) -> dict:
        """The frame's definition, for outputs (plan.json)."""
        return {"datum": "WGS84", "altitude_datum": "MSL", "origin": {"lat_deg": self.lat_deg, "lon_deg": self.lon_deg,
                                             "elevation_ft": self.elevation_ft},
                "course_deg": self.course_deg,
                "axes": "origin at the runway threshold; z up (ellipsoid normal); the east-north-up tangent plane "
                        "turned by course_deg - 180 deg counter-clockwise, so that the landing direction is -y"}
