"""Runway thresholds of a few airports, so a real runway needs no download (``traffic``'s airport database loads
at run time).

Source: X-Plane's ``apt.dat`` (data cycle 2013.10, GPL), as shipped in bluesky-navdata 1.0.0
(``bluesky/resources/navdata/apt.zip``), rows ``100`` (land runway) of LFPG: each runway end's number, its
latitude and longitude (WGS84) and its displaced-threshold length (m); the airport's elevation (row ``1``,
392 ft). The landing threshold is the runway end moved along the runway by its displaced length; the landing
course is the true azimuth from the end to the opposite end (pymap3d's Vincenty geodesics, WGS84).

apt.dat gives one elevation per airport (the highest point of its landing area): a threshold's own height is
unknown here. :mod:`mal_planner.geo.adsb` does not depend on it: it calibrates the recorded altitudes on the
landings themselves.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

from pymap3d.vincenty import vdist, vreckon

from mal_planner.geodesy import GeoFrame


@dataclass(frozen=True)
class RunwayEnd:
    """One end of a runway as apt.dat gives it."""

    name: str
    lat_deg: float
    lon_deg: float
    displaced_m: float


# (end, end) pairs of LFPG's four runways: apt.dat 2013.10 rows 100, verbatim (lat, lon, displaced threshold m).
_APT_DAT: dict[str, tuple[float, tuple[RunwayEnd, RunwayEnd]]] = {
    "LFPG": (392.0, (
        (RunwayEnd("08L", 48.99566392, 2.55215505, 0.0), RunwayEnd("26R", 48.99875734, 2.61060285, 576.99)),
        (RunwayEnd("09L", 49.02473614, 2.52489020, 0.0), RunwayEnd("27R", 49.02667786, 2.56169447, 0.0)),
        (RunwayEnd("08R", 48.99292932, 2.56581580, 0.0), RunwayEnd("26L", 48.99486268, 2.60243818, 0.0)),
        (RunwayEnd("09R", 49.02064475, 2.51305527, 0.0), RunwayEnd("27L", 49.02366525, 2.57030334, 600.15)),
    )),
}
AIRPORTS = tuple(_APT_DAT)


class UnknownRunwayError(ValueError):
    """A runway (or airport) not in the table."""


@dataclass(frozen=True)
class Runway:
    """A landing direction: its threshold (WGS84) and true course, and the frame the planner uses for it."""

    airport: str
    name: str
    frame: GeoFrame
    length_m: float
    """Landing distance available from the threshold to the opposite end."""


def _landing(airport: str, elevation_ft: float, end: RunwayEnd, other: RunwayEnd) -> Runway:
    length, course = vdist(end.lat_deg, end.lon_deg, other.lat_deg, other.lon_deg)
    lat, lon = end.lat_deg, end.lon_deg
    if end.displaced_m > 0.0:
        lat, lon = vreckon(end.lat_deg, end.lon_deg, end.displaced_m, float(course))
        length, course = vdist(lat, lon, other.lat_deg, other.lon_deg)
    frame = GeoFrame(float(lat), float(lon), elevation_ft, round(float(course), 4))
    return Runway(airport, end.name, frame, float(length))


@cache
def runways(airport: str) -> dict[str, Runway]:
    """Every landing direction of an airport of the table, by runway name (e.g. ``27R``)."""
    if airport.upper() not in _APT_DAT:
        raise UnknownRunwayError(f"airport {airport!r} is not in the runway table (known: {', '.join(AIRPORTS)})")
    elevation, pairs = _APT_DAT[airport.upper()]
    out = {}
    for a, b in pairs:
        out[a.name] = _landing(airport.upper(), elevation, a, b)
        out[b.name] = _landing(airport.upper(), elevation, b, a)
    return dict(sorted(out.items()))


def runway(airport: str, name: str) -> Runway:
    """One landing direction, e.g. ``runway("LFPG", "27R")``; UnknownRunwayError names the known ones."""
    table = runways(airport)
    if name.upper() not in table:
        raise UnknownRunwayError(f"runway {name!r} is not in the table for {airport.upper()} "
                                 f"(known: {', '.join(table)})")
    return table[name.upper()]
