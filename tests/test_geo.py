"""The runway frame on the Earth: local <-> geodetic round trips, against pymap3d's own."""

from __future__ import annotations

import math

import numpy as np
import pymap3d
import pytest

from mal_planner.geo import GeoFrame
from mal_planner.units import ft_to_m, m_to_nm

# Paris-Charles de Gaulle 27L threshold (approximate, as an example place), a runway landing due west
CDG = GeoFrame(lat_deg=49.0247, lon_deg=2.6106, elevation_ft=355.0, course_deg=266.7)
SOUTH = GeoFrame(lat_deg=-33.95, lon_deg=151.18, elevation_ft=21.0, course_deg=180.0)
ARCTIC = GeoFrame(lat_deg=78.25, lon_deg=15.47, elevation_ft=88.0, course_deg=280.0)


def _area(n: int = 2000, half_nm: float = 30.0) -> np.ndarray:
    """Points over a 60 nm x 60 nm area, from the ground to 40 000 ft."""
    rng = np.random.default_rng(19)
    xy = rng.uniform(-half_nm, half_nm, (n, 2))
    z = rng.uniform(-0.1, m_to_nm(ft_to_m(40000.0)), (n, 1))
    return np.hstack([xy, z])


@pytest.mark.parametrize("frame", [CDG, SOUTH, ARCTIC], ids=["cdg", "south", "arctic"])
def test_round_trip_local_geodetic_local(frame: GeoFrame) -> None:
    pts = _area()
    back = frame.to_local(*frame.to_geodetic(pts))
    assert np.max(np.abs(back - pts)) < 1e-9
    # pymap3d's own round trip of the same ENU points is as good (the frame adds a turn and unit changes only)
    e, n, u = frame._local_to_enu(pts * 1852.0)
    h0 = ft_to_m(frame.elevation_ft)
    lib = np.stack(pymap3d.geodetic2enu(*pymap3d.enu2geodetic(e, n, u, frame.lat_deg, frame.lon_deg, h0),
                                        frame.lat_deg, frame.lon_deg, h0), axis=-1)
    lib_err = m_to_nm(np.max(np.abs(lib - np.stack([e, n, u], axis=-1))))
    assert lib_err < 1e-9


def test_geodetic_agrees_with_pymap3d_enu() -> None:
    """Local points are pymap3d's ENU turned by course - 180: distances from the threshold and heights agree."""
    pts = _area(200)
    lat, lon, alt = CDG.to_geodetic(pts)
    e, n, u = pymap3d.geodetic2enu(lat, lon, ft_to_m(alt), CDG.lat_deg, CDG.lon_deg, ft_to_m(CDG.elevation_ft))
    np.testing.assert_allclose(m_to_nm(np.hypot(e, n)), np.hypot(pts[:, 0], pts[:, 1]), rtol=0, atol=1e-9)
    np.testing.assert_allclose(m_to_nm(u), pts[:, 2], rtol=0, atol=1e-9)
    # the runway axis: the local +y axis points back along the approach, i.e. at true bearing course + 180
    az, _, _ = pymap3d.enu2aer(*CDG._local_to_enu(np.array([0.0, 10.0, 0.0])))
    assert az == pytest.approx((CDG.course_deg + 180.0) % 360.0, abs=1e-9)


def test_course_180_is_plain_enu() -> None:
    lat, lon, alt = SOUTH.to_geodetic(np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]))
    assert lon[0] > SOUTH.lon_deg and lat[0] == pytest.approx(SOUTH.lat_deg, abs=1e-3)  # +x is east
    assert lat[1] > SOUTH.lat_deg and lon[1] == pytest.approx(SOUTH.lon_deg, abs=1e-9)  # +y is north
    assert alt[0] > SOUTH.elevation_ft  # the tangent plane rises above the curved Earth


@pytest.mark.parametrize("frame", [CDG, ARCTIC], ids=["cdg", "arctic"])
def test_direction_round_trip_and_landing_course(frame: GeoFrame) -> None:
    # on the runway the landing course is the local heading -90 deg
    heading, gamma = frame.direction_to_local(frame.lat_deg, frame.lon_deg, frame.course_deg, -3.0)
    assert heading == pytest.approx(-0.5 * math.pi, abs=1e-12)
    assert gamma == pytest.approx(math.radians(-3.0), abs=1e-12)
    rng = np.random.default_rng(7)
    for point in _area(20):
        h0, g0 = rng.uniform(-math.pi, math.pi), rng.uniform(-0.3, 0.3)
        track, fpa = frame.direction_to_geodetic(point, h0, g0)
        lat, lon, _ = frame.to_geodetic(point)
        h1, g1 = frame.direction_to_local(float(lat), float(lon), track, fpa)
        assert abs(math.remainder(h1 - h0, 2 * math.pi)) < 1e-12 and abs(g1 - g0) < 1e-12


def test_track_far_from_threshold_includes_meridian_convergence() -> None:
    """Due north 30 nm east of the threshold is not the local 'north' of the threshold (lat 49: ~0.6 deg)."""
    lat, lon, _ = CDG.to_geodetic(np.array(CDG._enu_to_local(30 * 1852.0, 0.0, 0.0)) / 1852.0)
    heading, _ = CDG.direction_to_local(float(lat), float(lon), 0.0, 0.0)
    north_at_threshold, _ = CDG.direction_to_local(CDG.lat_deg, CDG.lon_deg, 0.0, 0.0)
    convergence = math.degrees(heading - north_at_threshold)
    expected = (float(lon) - CDG.lon_deg) * math.sin(math.radians(CDG.lat_deg))
    assert convergence == pytest.approx(expected, rel=0.02)
