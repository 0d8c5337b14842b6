"""Kinds of arrival traffic: the numbers (nm, s, deg) of the thesis's small airspace and of a real terminal area.

:data:`PROFILES` holds :data:`THESIS` (the thesis's 6-nm box, 0.25 nm separation, 45 deg bank) and :data:`TMA` (a
real terminal area: 45 nm across, 3 nm separation, 90 s landing spacing, 30 deg bank). The traffic generator
(:mod:`mal_planner.campaign.traffic`) draws scenarios from them; the ADS-B converter (:mod:`mal_planner.geo.adsb`)
sizes a real moment's airspace and minima with :data:`TMA`. The README's tables give their sources.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

Range = tuple[float, float]


@dataclass(frozen=True)
class TrafficProfile:
    """The numbers of one kind of traffic (nm, s, deg); see the README's tables for their sources."""

    name: str
    speed_nm_s: float
    speed_spread: Range
    """Each aircraft's speed is ``speed_nm_s`` times a factor drawn from this range."""
    separation_nm: float
    separation_margin_nm: float
    """Initial 3-D distance of any two aircraft is at least the separation plus this."""
    landing_spacing_s: float
    max_landing_spacing_s: float
    bank_angle_deg: float
    n_h: Range
    n_v: Range
    landing_gap_s: Range
    """Each aircraft's path to the runway is this much flight longer than the previous one's."""
    first_beyond_fix_nm: Range
    """The first aircraft's distance beyond the approach fix."""
    bearing_sigma_deg: float
    max_bearing_deg: float
    heading_deviation_deg: float
    glide_slope: float
    """Altitude per distance to the runway (nm/nm) before jitter."""
    altitude_jitter_nm: float
    altitude_nm: Range
    """Initial altitudes are clipped to this range."""
    min_airspace: tuple[Range, Range, Range]
    airspace_spare_nm: float
    """The grown airspace holds every aircraft with this much to spare horizontally."""
    airspace_step_nm: float
    edge_nm: float
    """With a fixed airspace, aircraft keep this far from its x and y edges."""
    wall_fix_y_nm: Range
    hole_x_nm: Range
    hole_half_width_nm: Range
    hole_z_nm: Range
    hole_half_height_nm: Range
    wall_thickness_nm: float
    wall_ahead_nm: float
    """With a wall, every aircraft starts at least this far beyond it."""
    fix_y_nm: Range
    """The approach fix of the no-fly-zones layout, on the centre line."""
    fix_ahead_nm: float
    zone_count: tuple[int, int]
    zone_semi_axis_nm: Range
    zone_y_nm: tuple[float, float, float]
    """Zone centres: y from the first value to max(second, third * farthest aircraft's y)."""
    zone_reach_nm: float
    """Zone centres: |x| up to max(this, the farthest aircraft's |x|)."""
    corridor_half_width_nm: float
    corridor_beyond_fix_nm: float
    corridor_behind_runway_nm: float
    zone_edge_nm: float
    zone_clearance_nm: float
    """Zones keep this far (ray distance) from every aircraft and from the approach fix."""
    zone_gap_nm: float
    fix_point_z_nm: float
    """Height of the approach fix (for the zones' clearance)."""
    fixed_slack_s: Range
    """Fixed schedules: each landing time is its earliest plus this ..."""
    fixed_spacing_extra_s: Range
    """... and at least the previous landing plus the spacing plus this."""
    glide_path_share: float = 0.0
    """Share of the files with a glide path at the runway (and at the gate)."""
    glide_path_deg: float = 3.0


THESIS = TrafficProfile(
    name="thesis", speed_nm_s=0.04, speed_spread=(0.9, 1.1), separation_nm=0.25, separation_margin_nm=0.25,
    landing_spacing_s=15.0, max_landing_spacing_s=30.0, bank_angle_deg=45.0, n_h=(-2.0, 2.0), n_v=(0.0, 2.0),
    landing_gap_s=(15.0, 30.0), first_beyond_fix_nm=(2.0, 3.0), bearing_sigma_deg=35.0, max_bearing_deg=70.0,
    heading_deviation_deg=40.0, glide_slope=0.04, altitude_jitter_nm=0.03, altitude_nm=(0.08, math.inf),
    min_airspace=((-3.0, 3.0), (0.0, 6.0), (0.0, 0.3)), airspace_spare_nm=1.0, airspace_step_nm=0.5, edge_nm=0.3,
    wall_fix_y_nm=(2.5, 3.5), hole_x_nm=(-0.5, 0.5), hole_half_width_nm=(0.6, 1.1), hole_z_nm=(0.12, 0.18),
    hole_half_height_nm=(0.04, 0.06), wall_thickness_nm=0.001, wall_ahead_nm=1.5, fix_y_nm=(2.0, 3.0),
    fix_ahead_nm=0.5, zone_count=(1, 3), zone_semi_axis_nm=(0.3, 0.9), zone_y_nm=(1.0, 1.5, 0.8), zone_reach_nm=1.5,
    corridor_half_width_nm=0.6, corridor_beyond_fix_nm=0.5, corridor_behind_runway_nm=1.0, zone_edge_nm=0.2,
    zone_clearance_nm=0.5, zone_gap_nm=0.3, fix_point_z_nm=0.15, fixed_slack_s=(5.0, 25.0),
    fixed_spacing_extra_s=(1.0, 8.0))
"""The thesis's box (chapter 6): V = 0.04 nm/s, 0.25 nm separation, 15 s landing spacing, 45 deg bank."""

TMA = TrafficProfile(
    name="tma", speed_nm_s=0.05, speed_spread=(0.84, 1.16), separation_nm=3.0, separation_margin_nm=1.0,
    landing_spacing_s=90.0, max_landing_spacing_s=180.0, bank_angle_deg=30.0, n_h=(-1.0, 1.0), n_v=(0.7, 1.3),
    landing_gap_s=(30.0, 60.0), first_beyond_fix_nm=(9.0, 14.0), bearing_sigma_deg=45.0, max_bearing_deg=80.0,
    heading_deviation_deg=40.0, glide_slope=0.03, altitude_jitter_nm=0.15, altitude_nm=(0.5, 1.0),
    min_airspace=((-22.5, 22.5), (-5.0, 40.0), (0.0, 1.2)), airspace_spare_nm=3.0, airspace_step_nm=2.5,
    edge_nm=2.0, wall_fix_y_nm=(8.0, 11.0), hole_x_nm=(-1.0, 1.0), hole_half_width_nm=(1.5, 3.0),
    hole_z_nm=(0.35, 0.55), hole_half_height_nm=(0.08, 0.12), wall_thickness_nm=0.01, wall_ahead_nm=4.0,
    fix_y_nm=(8.0, 11.0), fix_ahead_nm=2.0, zone_count=(1, 2), zone_semi_axis_nm=(2.0, 5.0), zone_y_nm=(5.0, 8.0, 0.8),
    zone_reach_nm=12.0, corridor_half_width_nm=3.0, corridor_beyond_fix_nm=3.0, corridor_behind_runway_nm=5.0,
    zone_edge_nm=1.5, zone_clearance_nm=3.0, zone_gap_nm=2.0, fix_point_z_nm=0.45, fixed_slack_s=(10.0, 60.0),
    fixed_spacing_extra_s=(2.0, 20.0), glide_path_share=0.5)
"""A real terminal area: 45 x 45 nm, ceiling 1.2 nm (about 7,300 ft), arrivals 18-40 nm out at 0.5-1.0 nm
(3,000-6,000 ft) and 0.042-0.058 nm/s (150-210 kt), 3 nm radar separation, 90 s landing spacing, 30 deg bank,
a 3 deg glide path in half the files, 1-2 restricted areas 4-10 nm across (sources: README, "Real-size traffic")."""

PROFILES: dict[str, TrafficProfile] = {p.name: p for p in (THESIS, TMA)}
