"""The arrival procedures and the type's envelope, checked on a flown path (a scenario with ``procedures:``).

Every rule of :mod:`mal_planner.scenario.procedures` and the type's OpenAP envelope (:mod:`mal_planner.performance`),
on the flown samples, with no tolerance: speeds as calibrated airspeeds (the model's airspeed is a true airspeed: the
constant one, or the airspeed model's flown state), vertical speeds as the airspeed times the sine of the flight-path
angle, altitudes as the threshold's elevation plus the height above it.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from mal_planner.performance import Performance, cas_of_tas, performance_of
from mal_planner.scenario import Aircraft, Scenario
from mal_planner.scenario.procedures import Procedures
from mal_planner.units import nm_per_s_to_kt, nm_to_ft

FPM_PER_NM_S = nm_to_ft(60.0)
"""ft/min in one nm/s."""


class Break(NamedTuple):
    """A rule broken: one line naming the aircraft, its type, the value and the limit; when it first is; and whether
    the NLP keeps the rule (:mod:`mal_planner.landing.profile` and, for the airspeed model, :mod:`mal_planner.landing.
    speeds`: a finer mesh there may mend it) or not (the speed rules of the constant-speed model, which cannot keep
    them)."""

    text: str
    time_s: float
    kept_by_nlp: bool


def procedure_breaks(scenario: Scenario, aircraft: Aircraft, t: np.ndarray, x: np.ndarray) -> list[Break]:
    """What ``aircraft``'s flown path ``(t, x)`` breaks of the scenario's procedures and its type's envelope (each
    at the first sample that breaks it); without procedures, only an airspeed-model aircraft's speed envelope (the
    constant-speed model's airspeed is the scenario's own choice)."""
    rules = scenario.procedures
    airspeed = x.shape[1] > 5
    if rules is None and not airspeed:
        return []
    perf = performance_of(scenario.type_of(aircraft))
    altitude = x[:, 2] + scenario.elevation_nm
    tas = x[:, 5] if airspeed else np.full(len(t), aircraft.speed)
    cas = cas_of_tas(tas, altitude)
    found = [(what, k, airspeed) for what, k in _envelope(perf, cas, altitude)]
    if rules is not None:
        height = x[:, 2] - float(scenario.runway_state[2])
        distance = np.hypot(x[:, 0] - scenario.runway_state[0], x[:, 1] - scenario.runway_state[1])
        course = float(scenario.runway_state[4])
        past = (x[:, 0] - scenario.runway_state[0]) * np.cos(course) + \
            (x[:, 1] - scenario.runway_state[1]) * np.sin(course) > 0.0
        on_final = (distance < rules.final_distance_nm) & \
            (height < rules.final_approach_height(float(scenario.runway_state[3])))
        found += [(what, k, airspeed) for what, k in _speeds(rules, cas, altitude, distance, on_final)]
        found += [(what, k, True) for what, k in _vertical(rules, perf, tas * np.sin(x[:, 3]), x[:, 2]) +
                  _profile(rules, height, distance, past)]
    return [Break(f"{aircraft.callsign} ({perf.type_code}): {what} at t={t[k]:.1f} s", float(t[k]), kept)
            for what, k, kept in found]


def _first(bad: np.ndarray) -> int | None:
    hits = np.flatnonzero(bad)
    return int(hits[0]) if hits.size else None


def _speeds(rules: Procedures, cas: np.ndarray, altitude: np.ndarray, distance: np.ndarray,
            on_final: np.ndarray) -> list[tuple[str, int]]:
    """Below the speed-limit altitude at most the limit, or the speed it arrived with while it slows down; on the
    final approach (inside the final distance, below :meth:`Procedures.final_approach_height`) at most the final
    speed."""
    found = []
    slowing = np.minimum.accumulate(cas)
    low = altitude < rules.speed_limit_below_nm
    if (k := _first(low & (cas > np.maximum(rules.speed_limit, slowing)))) is not None:
        found.append((f"{nm_per_s_to_kt(cas[k]):.0f} kt CAS at {nm_to_ft(altitude[k]):.0f} ft (limit "
                      f"{nm_per_s_to_kt(rules.speed_limit):.0f} kt below {nm_to_ft(rules.speed_limit_below_nm):.0f} "
                      "ft)", k))
    if (k := _first(on_final & (cas > rules.final_speed))) is not None:
        found.append((f"{nm_per_s_to_kt(cas[k]):.0f} kt CAS {distance[k]:.2f} nm from the threshold (limit "
                      f"{nm_per_s_to_kt(rules.final_speed):.0f} kt inside {rules.final_distance_nm:g} nm)", k))
    return found


def _envelope(perf: Performance, cas: np.ndarray, altitude: np.ndarray | None = None) -> list[tuple[str, int]]:
    """Within the type's VMO/MMO and above its slowest final approach (or the speed it started with, if slower: a
    radar state); at the threshold at most its fastest final approach."""
    found = []
    if cas[-1] > perf.final_approach_cas.high:
        found.append((f"lands at {nm_per_s_to_kt(cas[-1]):.0f} kt CAS, above the type's final approach speeds "
                      f"({nm_per_s_to_kt(perf.final_approach_cas.high):.0f} kt at most)", len(cas) - 1))
    if altitude is not None and (k := _first(cas > perf.max_cas(altitude))) is not None:
        found.append((f"{nm_per_s_to_kt(cas[k]):.0f} kt CAS above the type's VMO/MMO", k))
    if (k := _first(cas < min(perf.final_approach_cas.low, cas[0]))) is not None:
        found.append((f"{nm_per_s_to_kt(cas[k]):.0f} kt CAS below the type's slowest final approach "
                      f"({nm_per_s_to_kt(perf.final_approach_cas.low):.0f} kt)", k))
    return found


def _vertical(rules: Procedures, perf: Performance, vertical: np.ndarray, z: np.ndarray) -> list[tuple[str, int]]:
    """Vertical speed within the rules and the type's observed range; no climb above the lowest level flown by more
    than the rules allow."""
    found = []
    down = max(-rules.max_descent_rate, perf.descent_rate.low)
    up = min(rules.max_climb_rate, perf.climb_rate.high)
    if (k := _first((vertical < down) | (vertical > up))) is not None:
        found.append((f"vertical speed {vertical[k] * FPM_PER_NM_S:+.0f} ft/min (limits {down * FPM_PER_NM_S:+.0f} "
                      f"/ {up * FPM_PER_NM_S:+.0f})", k))
    climbed = z - np.minimum.accumulate(z)
    if (k := _first(climbed > rules.max_climb_nm)) is not None:
        found.append((f"climbs {nm_to_ft(float(np.max(climbed))):.0f} ft (at most {nm_to_ft(rules.max_climb_nm):.0f})",
                      k))
    return found


def _profile(rules: Procedures, height: np.ndarray, distance: np.ndarray, past: np.ndarray) -> list[tuple[str, int]]:
    """Beyond the final distance at least the minimum height (or the first height, if lower); below the turn-away
    height never farther from the threshold than the sample before, until it is past the threshold (``past``:
    landed)."""
    found = []
    floor = min(rules.min_height_nm, float(height[0]))
    if (k := _first((distance > rules.final_distance_nm) & (height < floor))) is not None:
        found.append((f"{nm_to_ft(height[k]):.0f} ft above the threshold {distance[k]:.1f} nm out (at least "
                      f"{nm_to_ft(floor):.0f} ft beyond {rules.final_distance_nm:g} nm)", k))
    away = (np.diff(distance) > 0.0) & ~past[1:]
    if (k := _first((height[1:] < rules.turn_away_below_nm) & away)) is not None:
        found.append((f"flies away from the threshold {nm_to_ft(height[k + 1]):.0f} ft above it", k + 1))
    return found
