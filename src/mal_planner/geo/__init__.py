"""Real-world frames and data: the runway frame on the Earth (WGS84), geodetic scenarios and outputs."""

from mal_planner.geodesy import GeoFrame

__all__ = ["GeoFrame"]
