"""Build the scenario of one plan from the base scenario, radar tracks and no-fly zone updates."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from mal_planner.dynamics import make_dynamics
from mal_planner.obstacles import Superquadric
from mal_planner.scenario import Aircraft, Scenario
from mal_planner.sequencing.schedule import landing_spacing, start_conflicts, vertical_escape_problem
from mal_planner.service.tracks import Track
from mal_planner.units import m_to_nm, nm_per_s_to_kt
from mal_planner.wake import categories

DEFAULT_MODEL = "point_mass"
AIRSPACE_TOL_NM = 0.05
"""Extrapolated states this far outside the airspace are clipped back in; further out they are left out."""
MIN_TIME_FACTOR = 1.0
"""Fixed landing times shorter than this factor x (straight distance / speed) cannot be met: given up."""
UNKNOWN_MARGIN_S = 5.0
"""An aircraft the scenario does not know lands this long after its straight-line time at the earliest."""


class NoFlyZoneError(ValueError):
    """An invalid ``mal_msgs/NoFlyZone`` message (one-line reason)."""


def no_fly_zone_to_superquadric(msg: Any) -> Superquadric:
    """``mal_msgs/NoFlyZone`` (metres) -> :class:`Superquadric` (nm); raises NoFlyZoneError."""
    name = str(msg.name).strip()
    if not name:
        raise NoFlyZoneError("empty name")
    center = [float(msg.center.x), float(msg.center.y), float(msg.center.z)]
    axes = [float(msg.semi_axes.x), float(msg.semi_axes.y), float(msg.semi_axes.z)]
    if not all(math.isfinite(v) for v in center + axes):
        raise NoFlyZoneError(f"{name!r}: non-finite center or semi-axes")
    if min(axes) <= 0.0:
        raise NoFlyZoneError(f"{name!r}: semi-axes {axes} m must all be > 0")
    p = int(msg.p)
    if p < 2 or p % 2:
        raise NoFlyZoneError(f"{name!r}: p must be an even integer >= 2, got {p}")
    return Superquadric(name, tuple(float(m_to_nm(v)) for v in center),  # type: ignore[arg-type]
                        tuple(float(m_to_nm(v)) for v in axes), p)  # type: ignore[arg-type]


def apply_no_fly_zone(obstacles: tuple[Superquadric, ...], msg: Any) -> tuple[tuple[Superquadric, ...], str]:
    """New obstacle tuple after a NoFlyZone message, and a description; raises NoFlyZoneError."""
    name = str(msg.name).strip()
    if bool(msg.remove):
        if not any(ob.name == name for ob in obstacles):
            raise NoFlyZoneError(f"cannot remove {name!r}: no such obstacle")
        return tuple(ob for ob in obstacles if ob.name != name), f"removed no-fly zone {name!r}"
    zone = no_fly_zone_to_superquadric(msg)
    replaced = any(ob.name == name for ob in obstacles)
    out = tuple(ob for ob in obstacles if ob.name != name) + (zone,)
    return out, f"{'replaced' if replaced else 'added'} no-fly zone {name!r} (p={zone.p})"


def radar_wake(base: Scenario, category: str | None) -> str | None:
    """An aircraft's wake category (the scenario's, else its radar track's) for the wake table in use: None (the
    worst case in each role, see :func:`~mal_planner.wake.wake_distance_nm`) when the table does not
    know it (none given, or one of another table, e.g. a node parameter chose another table than the file's)."""
    if not category or base.wake == "none":
        return category or None
    return category if category in categories(base.wake) else None


@dataclass(frozen=True)
class PlanInputs:
    """The scenario to plan (initial states at ``plan_start``) and the aircraft left out (with reasons)."""

    scenario: Scenario
    plan_start: float
    left_out: dict[str, str]


def build_plan_scenario(base: Scenario, tracks: Mapping[str, Track], plan_start: float,
                        landing_shift: float) -> PlanInputs:
    """Aircraft = the tracked ones, extrapolated to ``plan_start``; scenario data where the scenario knows
    them (speed, model, limits, landing time minus ``landing_shift``), defaults otherwise. Aircraft that no plan
    can serve are left out with the reason (outside the airspace or in an obstacle, leaving it, slower than the
    wind, a pair closer than the separation), so that the others are planned."""
    left_out: dict[str, str] = {}
    aircraft: list[Aircraft] = []
    lo, hi = base.airspace[:, 0], base.airspace[:, 1]
    default_limits = base.config.limits.to_limits()
    for cs in sorted(tracks):
        tr = tracks[cs]
        state = tr.at(plan_start)
        pos = state[:3]
        if np.any(pos < lo - AIRSPACE_TOL_NM) or np.any(pos > hi + AIRSPACE_TOL_NM):
            left_out[cs] = "outside the airspace at the plan start"
            continue
        state[:3] = np.clip(pos, lo, hi)
        if base.collides(state[:3]):
            left_out[cs] = "inside an obstacle at the plan start"
            continue
        wind = math.hypot(*base.wind)
        if wind > 0.0 and wind >= tr.speed * math.cos(state[3]):
            left_out[cs] = (f"the wind ({nm_per_s_to_kt(wind):.0f} kt) is not below its horizontal airspeed "
                            f"({nm_per_s_to_kt(tr.speed * math.cos(state[3])):.0f} kt)")
            continue
        try:
            known = base.aircraft_by_callsign(cs)
        except KeyError:
            dyn = make_dynamics(DEFAULT_MODEL, tr.speed, gravity=base.gravity, wind_x=base.wind[0], wind_y=base.wind[1])
            aircraft.append(Aircraft(cs, state, dyn, default_limits, radar_wake(base, tr.wake), None))
            continue
        def shifted(t: float | None) -> float | None:  # the scenario's times count from the first radar stamp
            return None if t is None else t - landing_shift

        candidate = replace(known, state0=state, wake_category=radar_wake(base, known.wake_category or tr.wake),
                            landing_time=shifted(known.landing_time), target_time=shifted(known.target_time),
                            latest_time=shifted(known.latest_time))
        leaving = vertical_escape_problem(base, candidate)
        if leaving is not None:  # like an aircraft outside: no plan can keep it inside the airspace
            left_out[cs] = f"leaving the airspace ({leaving.split(': ', 1)[1]})"
            continue
        aircraft.append(candidate)
    for a, b, d in start_conflicts(base, aircraft):  # no plan separates them: the others are planned
        for one, other in ((a, b), (b, a)):
            left_out[one.callsign] = (f"lost separation with {other.callsign} at the plan start ({d:.3f} nm, "
                                      f"minimum {base.separation_nm:g} nm)")
    aircraft = [a for a in aircraft if a.callsign not in left_out]
    aircraft = _feasible_landing_times(base, aircraft)
    return PlanInputs(replace(base, aircraft=tuple(aircraft)), plan_start, left_out)


def _min_time(a: Aircraft, runway: np.ndarray) -> float:
    """Straight to the runway at the best crab (in the wind its model carries)."""
    return MIN_TIME_FACTOR * float(a.dynamics.air_distance(runway - a.position)) / a.speed


def _feasible_landing_times(base: Scenario, aircraft: list[Aircraft]) -> list[Aircraft]:
    """Keep the fixed landing times of the known aircraft; aircraft without one (not in the scenario) land
    after them, each its pair's landing spacing (wake included) behind the one before. Only if that fails, or a
    fixed time cannot be met, the sequencer decides all."""
    runway = base.runway_state[:3]
    fixed = [a for a in aircraft if a.landing_time is not None]
    if not fixed:
        return aircraft
    if not all(a.landing_time is None or a.landing_time >= _min_time(a, runway) for a in aircraft):
        return [replace(a, landing_time=None) for a in aircraft]
    out = list(aircraft)
    leader = max(fixed, key=lambda a: a.landing_time)  # type: ignore[arg-type, return-value]
    for i in sorted((i for i, a in enumerate(aircraft) if a.landing_time is None),
                    key=lambda i: _min_time(aircraft[i], runway)):
        spacing = landing_spacing(base, leader, aircraft[i])
        last = float(leader.landing_time)  # type: ignore[arg-type]
        t = max(last + spacing, _min_time(aircraft[i], runway) + UNKNOWN_MARGIN_S)
        if t - last > max(base.max_landing_spacing_s, spacing):  # cannot be slotted in: the sequencer decides all
            return [replace(a, landing_time=None) for a in aircraft]
        out[i] = leader = replace(aircraft[i], landing_time=t)
    return out
