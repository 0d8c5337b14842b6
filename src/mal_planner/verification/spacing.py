"""The time between consecutive landings against the time they need (the landing spacing, the wake minimum)."""

from __future__ import annotations

import itertools
from collections.abc import Set

from mal_planner.scenario import Scenario
from mal_planner.verification.report import AircraftCheck, LandingGap, Tolerances
from mal_planner.wake import wake_distance_nm


def landing_gaps(scenario: Scenario, checks: list[AircraftCheck], tol: Tolerances, fail,
                 fixed: Set[str] = frozenset()) -> list[LandingGap]:
    """Landing-time spacing in landing order (``fail(callsigns, text)`` for each pair too close); a pair of two
    ``fixed`` aircraft (not this plan's) is not checked."""
    order = sorted(checks, key=lambda c: c.landing_time)
    landings: list[LandingGap] = []
    for a, b in itertools.pairwise(order):
        if a.callsign in fixed and b.callsign in fixed:
            continue
        gap = b.landing_time - a.landing_time
        record = LandingGap(f"{a.callsign}->{b.callsign}", gap, scenario.landing_spacing_s)
        landings.append(record)
        if gap < scenario.landing_spacing_s - tol.landing_time_s:
            fail((a.callsign, b.callsign), f"{a.callsign}->{b.callsign}: landings {gap:.2f} s apart "
                                           f"(minimum {scenario.landing_spacing_s:.1f} s)")
        if scenario.wake != "none":
            # The wake table's distance, flown by the follower at its own speed (checked here, not taken from
            # the schedule's spacing), with no tolerance: the schedule keeps a margin for round-off.
            lead, follow = scenario.aircraft_by_callsign(a.callsign), scenario.aircraft_by_callsign(b.callsign)
            nm = wake_distance_nm(scenario.wake, lead.wake_category, follow.wake_category, scenario.separation_nm)
            record.wake, record.wake_nm = f"{lead.wake_category}->{follow.wake_category}", nm
            # On final at its ground speed (longer into a headwind); an airspeed-model follower at the slowest
            # airspeed it flies (its landing speed or less).
            need = nm / scenario.final_ground_speed(follow, b.slowest_airspeed)
            record.needed_s = max(record.needed_s, need)
            if gap < need:
                fail((a.callsign, b.callsign), f"{a.callsign}->{b.callsign}: landings {gap:.2f} s apart, the "
                                               f"{scenario.wake} wake minimum {lead.wake_category}->"
                                               f"{follow.wake_category} of {nm:g} nm needs {need:.1f} s")
    return landings
