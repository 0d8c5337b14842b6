"""The inputs of one plan: the scenario built from the base scenario, the tracks and the no-fly zones."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from mal_planner.dynamics import make_dynamics
from mal_planner.landing.margins import SafetyMargins
from mal_planner.landing.speeds import start_airspeed
from mal_planner.obstacles import Superquadric
from mal_planner.performance import performance_of
from mal_planner.scenario import Aircraft, Scenario
from mal_planner.sequencing.schedule import slot_after_fixed, start_conflicts, vertical_escape_problem
from mal_planner.service.tracks import Track
from mal_planner.units import nm_per_s_to_kt
from mal_planner.wake import categories

DEFAULT_MODEL = "point_mass"
AIRSPACE_TOL_NM = 0.05
"""Extrapolated states this far outside the airspace are clipped back in; further out they are left out."""




def apply_zone(obstacles: tuple[Superquadric, ...], name: str, zone: Superquadric | None
               ) -> tuple[tuple[Superquadric, ...], str]:
    """The obstacles after a no-fly zone update (``zone`` None: remove the zone ``name``), and what changed;
    ValueError when there is no such zone to remove."""
    if zone is None:
        if not any(ob.name == name for ob in obstacles):
            raise ValueError(f"cannot remove {name!r}: no such obstacle")
        return tuple(ob for ob in obstacles if ob.name != name), f"removed no-fly zone {name!r}"
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


def _model_start(base: Scenario, known: Aircraft, state: np.ndarray, speed: float) -> dict:
    """A known aircraft's initial state (and model) from a track's ``state`` and airspeed: an airspeed-model
    aircraft starts at the track's airspeed brought into what its type may fly and the procedures allow there
    (:func:`~mal_planner.landing.speeds.start_airspeed`); a constant-speed one keeps the scenario's."""
    if not known.dynamics.variable_airspeed:
        return {"state0": state}
    speed = start_airspeed(float(speed), float(state[2]) + base.elevation_nm, performance_of(base.type_of(known)),
                           base.procedures, SafetyMargins().speed).tas
    return {"state0": np.append(state, speed), "dynamics": replace(known.dynamics, speed=float(speed))}


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

        wake = radar_wake(base, known.wake_category or tr.wake)
        candidate = replace(known, **_model_start(base, known, state, tr.speed), wake_category=wake,
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
    aircraft = slot_after_fixed(base, aircraft)
    return PlanInputs(replace(base, aircraft=tuple(aircraft)), plan_start, left_out)

