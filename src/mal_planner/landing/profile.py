"""The arrival procedures as the landing NLP keeps them (a scenario with ``procedures:``; see
:mod:`mal_planner.scenario.procedures`, which the verification checks with no tolerance).

The NLP keeps them with margins of its own:

* **Vertical speed**: the flight-path angle is bounded so that the airspeed times its sine stays inside the
  rules' and the type's descent rate, less :data:`RATE_RESERVE` of it. Arrivals do not climb: the upper bound is
  level flight, which leaves the rules' climb allowance (+1,500 ft/min, 1,000 ft) to the interpolation between
  collocation points and to an aircraft that starts climbing.
* **Minimum height**: above the threshold, at least the minimum height beyond the final distance (or the
  aircraft's first height, if lower), and from a little inside it (:data:`KNEE_INSET`) a cone down to the threshold
  a little shallower than the glide path: min(h, h + k (d - D')), with k such that the cone passes below the
  threshold. Inside the final
  distance the rules ask nothing; the cone keeps low loops and dives near the runway out as well.

The speed rules need the airspeed as a state: with the constant-speed model a plan keeps them only if the speed it
starts with does.
"""

from __future__ import annotations

import math

import casadi as ca

from mal_planner.scenario import Aircraft, Scenario

RATE_RESERVE = 0.05
"""The share of a vertical-speed limit the optimizer leaves free (between the collocation points the flight-path
angle's polynomial may pass its bound a little; the verification allows nothing)."""
CONE_UNDERSHOOT = 0.1
"""The cone reaches zero height this share of the final distance before the threshold, so that the final
state (at the threshold, on the floor) is inside it."""
KNEE_INSET = 0.05
"""The NLP's floor keeps the minimum height this share of the final distance inside it (a terminal area 0.2 nm),
then the cone: a path that rides the floor bends down at the knee, and between its collocation points (and flown
by its controls) it starts down a little before it. At the rules' own knee 8 of 10 airliner plans of 10 aircraft
dipped 0-1 ft below 1,000 ft 4.0-4.2 nm out and were refined and solved again (20-60 s each). Inset, the dip comes
where the rules ask nothing and the cone is already lower (about 55 ft at 1,000 ft over 4 nm); must be below
:data:`CONE_UNDERSHOOT`."""
DISTANCE_SMOOTHING = 1e-3
"""The distance to the threshold is sqrt(d^2 + e^2) with e this share of the final distance: smooth at the
threshold itself (where the final state is), and never shorter than d, so the floor is only higher."""


def gamma_bounds(scenario: Scenario, aircraft: Aircraft, default: float) -> tuple[float, float]:
    """The flight-path angle bounds of ``aircraft`` in the NLP (rad): +-``default`` without procedures; else the
    steepest descent the rules and the type allow (less the reserve) and level flight (the airspeed model:
    -``default`` and level flight, and :mod:`mal_planner.landing.speeds` bounds the descent rate)."""
    limit = scenario.descent_rate_limit(aircraft)
    if limit is None:
        return -default, default
    if aircraft.dynamics.variable_airspeed:  # the rate depends on the airspeed: a row of its own
        return -default, 0.0
    return -math.asin(min(1.0, limit * (1.0 - RATE_RESERVE) / aircraft.speed)), 0.0


def floor_height(scenario: Scenario, aircraft: Aircraft, x, y, margin_nm: float):
    """The lowest height above the threshold the NLP lets ``aircraft`` fly at horizontal position (x, y), less
    ``margin_nm`` (which the NLP keeps above it): the profile's floor (None without procedures). An aircraft that
    starts lower than the minimum height has its first height less the margin as its floor, so that it starts above
    it. Works on CasADi symbols."""
    rules = scenario.procedures
    if rules is None:
        return None
    runway = scenario.runway_state
    first = float(aircraft.state0[2] - runway[2])
    height = min(rules.min_height_nm, first - margin_nm)
    slope = height / ((1.0 - CONE_UNDERSHOOT) * rules.final_distance_nm)
    smoothing = DISTANCE_SMOOTHING * rules.final_distance_nm
    distance = ca.sqrt((x - runway[0]) ** 2 + (y - runway[1]) ** 2 + smoothing**2)
    return ca.fmin(height, height + slope * (distance - (1.0 - KNEE_INSET) * rules.final_distance_nm))
