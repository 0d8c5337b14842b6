"""When can each aircraft land at the earliest, and which requests can never be met.

Two numbers per aircraft, both in seconds from the initial states:

* :func:`earliest_landing_time`: a turn-aware *estimate* used to order the aircraft and to schedule free
  landing times. The horizontal path is a Dubins path (OMPL's ``DubinsStateSpace``) from the initial
  position and heading to the gate (through the best point of the hole, with the gate's heading) and on
  to the runway threshold with the runway's heading, flown with the level-turn radius at the bank limit,
  ``R = V^2 / (g min(tan mu_max, n_h_max))``. When an obstacle-free polyline is known (the initializer's
  shortest path), the detour it makes around obstacles is added. In a wind the time is scaled by what the wind
  does to the straight route start -> hole -> runway (its air distance over its length, the wind triangle on
  each leg).
* :func:`reachable_lower_bound`: a *proof* of impossibility: the straight-line distance from the start
  through the nearest point of the hole to the runway, flown at full speed, and with arrival procedures the
  height flown down at the steepest descent they and the type allow. A fixed landing time below it cannot be met
  by any trajectory that keeps the rules. In a wind: the straight line start -> runway at the best crab (exact: the
  ground moved is the air path plus the wind's drift), and the legs via the hole at the fastest ground speed
  V + |w|.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from mal_planner.dynamics import DynamicsModel
from mal_planner.obstacles import Gate
from mal_planner.performance import performance_of, tas_of_cas
from mal_planner.scales import level_turn_radius
from mal_planner.scenario import Aircraft, Scenario

HOLE_SAMPLES = 9
"""Points across the hole tried for the gate passage (the best one is kept)."""


def dubins_length(start: np.ndarray, start_heading: float, goal: np.ndarray, goal_heading: float,
                  radius: float) -> float:
    """Length of the shortest planar path with curvature <= 1/radius between two (x, y, heading) poses."""
    from ompl import base as ob

    space = ob.DubinsStateSpace(radius)
    a, b = space.allocState(), space.allocState()
    a.setXY(float(start[0]), float(start[1]))
    a.setYaw(float(start_heading))
    b.setXY(float(goal[0]), float(goal[1]))
    b.setYaw(float(goal_heading))
    return float(space.distance(a, b))


def _hole_points(gate: Gate, count: int, margin: float = 0.0) -> np.ndarray:
    """Points across the hole on the gate plane (at the hole's mid height), (count, 3)."""
    (a_lo, a_hi), (b_lo, b_hi) = gate.bounds
    ax_a, ax_b = gate.other_axes
    pts = np.zeros((count, 3))
    pts[:, gate.axis] = gate.position
    pts[:, ax_a] = np.linspace(a_lo + margin, a_hi - margin, count) if a_hi - a_lo > 2 * margin else 0.5 * (a_lo + a_hi)
    pts[:, ax_b] = 0.5 * (b_lo + b_hi)
    return pts


def _ahead_of(gate: Gate | None, aircraft: Aircraft) -> bool:
    return gate is not None and float(gate.signed_distance(aircraft.position)) > 0.0


def _nearest_hole_point(gate: Gate, point: np.ndarray) -> np.ndarray:
    out = np.asarray(point, float).copy()
    out[gate.axis] = gate.position
    for (lo, hi), ax in zip(gate.bounds, gate.other_axes, strict=True):
        out[ax] = min(max(out[ax], lo), hi)
    return out


SCHEDULE_SAMPLES = 200
"""Samples of the way to go over which :func:`flight_time` integrates an airspeed-model aircraft's speed."""


def flight_time(scenario: Scenario, aircraft: Aircraft, length_nm: float) -> float:
    """Seconds ``aircraft`` takes to fly ``length_nm`` to the threshold in still air: at its constant airspeed; an
    airspeed-model aircraft with arrival procedures at a nominal speed schedule (as an arrival manager's speed
    profile: the sequencer then asks for times the plan can keep): its first airspeed slowed down at a share of its
    idle deceleration to the final speed at the final distance, v(d)^2 = v_f^2 + 2 a (d - D), then evenly to its
    type's usual final approach speed over the threshold."""
    if length_nm <= 0.0:
        return 0.0
    d = np.linspace(0.0, length_nm, SCHEDULE_SAMPLES)
    return float(np.trapezoid(1.0 / nominal_speeds(scenario, aircraft, d), d))


def nominal_speeds(scenario: Scenario, aircraft: Aircraft, to_go_nm: np.ndarray) -> np.ndarray:
    """The airspeed (nm/s) of :func:`flight_time`'s schedule with ``to_go_nm`` left to the threshold."""
    rules = scenario.procedures
    to_go = np.asarray(to_go_nm, float)
    if not aircraft.dynamics.variable_airspeed or rules is None:
        return np.full(to_go.shape, aircraft.speed)
    landing = performance_of(scenario.type_of(aircraft)).final_approach_cas.default
    final = max(min(rules.final_speed, aircraft.speed), landing)
    slowing = NOMINAL_SLOWING_SHARE * -aircraft.limits.n_x[0] * aircraft.dynamics.gravity
    beyond = np.sqrt(final**2 + 2.0 * slowing * np.maximum(to_go - rules.final_distance_nm, 0.0))
    inside = np.sqrt(landing**2 + (final**2 - landing**2) * np.clip(to_go / rules.final_distance_nm, 0.0, 1.0))
    # No faster than the speed limit's true airspeed where it applies (or at the first altitude, if lower).
    altitude = min(rules.speed_limit_below_nm, float(aircraft.position[2]) + scenario.elevation_nm)
    top = min(aircraft.speed, float(tas_of_cas(rules.speed_limit, max(altitude, 0.0))))
    return np.minimum(top, np.where(to_go > rules.final_distance_nm, beyond, inside))


def length_for_time(scenario: Scenario, aircraft: Aircraft, seconds: float) -> float:
    """The length (nm) :func:`flight_time` flies in ``seconds`` (its inverse, by bisection: it grows with the
    length)."""
    if not aircraft.dynamics.variable_airspeed or scenario.procedures is None or seconds <= 0.0:
        return max(seconds, 0.0) * aircraft.speed
    lo, hi = 0.0, seconds * aircraft.speed
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if flight_time(scenario, aircraft, mid) < seconds else (lo, mid)
    return 0.5 * (lo + hi)


NOMINAL_SLOWING_SHARE = 0.5
"""The share of an aircraft's idle deceleration in level flight its nominal speed schedule slows down at."""


def fastest_dynamics(scenario: Scenario, aircraft: Aircraft) -> DynamicsModel:
    """``aircraft``'s model at the fastest airspeed it may fly (for bounds that prove): its constant one, or an
    airspeed-model aircraft's first airspeed or its type's VMO as a true airspeed where it is, if faster."""
    dyn = aircraft.dynamics
    if not dyn.variable_airspeed:
        return dyn
    vmo = float(tas_of_cas(performance_of(scenario.type_of(aircraft)).vmo,
                           max(float(aircraft.position[2]) + scenario.elevation_nm, 0.0)))
    return replace(dyn, speed=max(aircraft.speed, vmo))


def descent_time(scenario: Scenario, aircraft: Aircraft) -> float:
    """The shortest time (s) ``aircraft`` takes down to the threshold at the steepest descent the scenario's
    procedures and its type allow (0 without procedures), and for the airspeed model at least its
    :func:`energy_distance` at its fastest airspeed."""
    limit = scenario.descent_rate_limit(aircraft)
    height = float(aircraft.position[2] - scenario.runway_state[2])
    rate = 0.0 if limit is None or height <= 0.0 else height / limit
    return max(rate, energy_distance(scenario, aircraft) / fastest_dynamics(scenario, aircraft).speed)


ENERGY_RESERVE = 0.1
"""The share of the idle deceleration an arrival manager's estimate keeps in reserve (:func:`energy_distance` of
:func:`earliest_landing_time`): a plan that must stay at idle all the way is at the edge of what the NLP can find."""


def energy_distance(scenario: Scenario, aircraft: Aircraft, reserve: float = 0.0) -> float:
    """The shortest way (nm, through the air) an airspeed-model aircraft flies while it loses the energy between its
    start and the threshold at its fastest final approach speed (0 for the constant-speed models).

    The energy height h + V^2 / 2g changes at V n_x (the point mass's energy equation, from V' = g (n_x - sin
    gamma)), so per nm flown it falls by |n_x_low| at most, at idle thrust, whatever the speed: an aircraft high and
    fast must fly that far (SVA127 at Paris-CDG, 11,100 ft and 302 kt 6.7 nm out: 42 nm; it really landed 644 s
    later). ``reserve``: the share of the idle deceleration left unused.
    """
    dyn = aircraft.dynamics
    if not dyn.variable_airspeed or aircraft.limits.n_x[0] >= 0.0:
        return 0.0
    landing = float(tas_of_cas(performance_of(scenario.type_of(aircraft)).final_approach_cas.high,
                               float(scenario.runway_state[2]) + scenario.elevation_nm))
    first = float(aircraft.position[2]) + aircraft.speed**2 / (2.0 * dyn.gravity)
    last = float(scenario.runway_state[2]) + landing**2 / (2.0 * dyn.gravity)
    return max(first - last, 0.0) / (-aircraft.limits.n_x[0] * (1.0 - reserve))


def reachable_lower_bound(scenario: Scenario, aircraft: Aircraft) -> float:
    """A landing time (s) no trajectory can beat: straight lines via the hole at full speed (in a wind: see the
    module docstring)."""
    start, goal = aircraft.position, scenario.runway_state[:3]
    dyn = fastest_dynamics(scenario, aircraft)
    # Straight to the runway at the best crab: the air path covers (goal - start) - w t, at most V t long.
    direct = float(dyn.air_distance(goal - start)) / dyn.speed
    direct = max(direct, descent_time(scenario, aircraft))
    gate = scenario.gates[0] if scenario.gates else None
    if not _ahead_of(gate, aircraft):
        return direct
    assert gate is not None
    # Each leg is at least the distance from its end to the (convex) hole, flown at most at V + |w|.
    to_hole = float(np.linalg.norm(_nearest_hole_point(gate, start) - start))
    hole_to_goal = float(np.linalg.norm(goal - _nearest_hole_point(gate, goal)))
    return max((to_hole + hole_to_goal) / dyn.fastest_ground_speed, direct)


def _dubins_route(scenario: Scenario, aircraft: Aircraft) -> tuple[float, float, np.ndarray]:
    """Turn-aware horizontal length (nm) to the runway (via the gate), the straight-line length and the straight
    route's points (start, hole point, runway). Poses are ground tracks (the start's: of its ground velocity)."""
    radius = level_turn_radius(aircraft)
    start, goal = aircraft.position, scenario.runway_state[:3]
    heading0 = aircraft.dynamics.ground_track(float(aircraft.state0[3]), float(aircraft.state0[4]))
    heading_rw = float(scenario.runway_state[4])
    gate = scenario.gates[0] if scenario.gates else None
    if not _ahead_of(gate, aircraft) or gate is None or gate.axis == 2:
        straight = float(np.linalg.norm(goal - start))
        turning = max(dubins_length(start, heading0, goal, heading_rw, radius), straight)
        return turning, straight, np.array([start, goal])
    best, best_straight, best_route = math.inf, math.inf, np.array([start, goal])
    for h in _hole_points(gate, HOLE_SAMPLES, margin=0.01 * min(hi - lo for lo, hi in gate.bounds)):
        straight = float(np.linalg.norm(h - start) + np.linalg.norm(goal - h))
        length = (dubins_length(start, heading0, h, gate.heading, radius)
                  + dubins_length(h, gate.heading, goal, heading_rw, radius))
        if length < best:
            best, best_straight, best_route = max(length, straight), straight, np.array([start, h, goal])
    return best, best_straight, best_route


def dubins_path_length(scenario: Scenario, aircraft: Aircraft) -> tuple[float, float]:
    """Turn-aware horizontal length (nm) to the runway (via the gate) and the straight-line length."""
    length, straight, _ = _dubins_route(scenario, aircraft)
    return length, straight


def wind_factor(aircraft: Aircraft, route: np.ndarray) -> float:
    """How much longer (> 1) or shorter the wind makes the polyline ``route`` to fly: its air distance over its
    length (1 in still air)."""
    dyn = aircraft.dynamics
    seg = np.diff(np.asarray(route, float), axis=0)
    seg = seg[np.linalg.norm(seg, axis=1) > 0.0]
    if not dyn.has_wind or not len(seg):
        return 1.0
    return float(np.sum(dyn.air_distance(seg)) / np.sum(np.linalg.norm(seg, axis=1)))


def earliest_landing_time(scenario: Scenario, aircraft: Aircraft, detour_nm: float = 0.0) -> float:
    """Turn-aware estimate (s) of the earliest landing; ``detour_nm``: extra length around obstacles."""
    length, _, route = _dubins_route(scenario, aircraft)
    climb = abs(float(scenario.runway_state[2] - aircraft.position[2]))
    length = max(math.hypot(length + max(detour_nm, 0.0), climb), energy_distance(scenario, aircraft, ENERGY_RESERVE))
    return max(flight_time(scenario, aircraft, length) * wind_factor(aircraft, route),
               reachable_lower_bound(scenario, aircraft))


def earliest_landing_times(scenario: Scenario, shortest_paths: Mapping[str, np.ndarray] | None = None
                           ) -> dict[str, float]:
    """:func:`earliest_landing_time` of every aircraft (s from the initial states).

    ``shortest_paths`` (callsign -> obstacle-free polyline to the runway, e.g. the initializer's) adds
    each aircraft's detour around obstacles: its length minus the straight line via the hole.
    """
    out = {}
    for ac in scenario.aircraft:
        detour = 0.0
        if shortest_paths is not None and ac.callsign in shortest_paths:
            path = np.asarray(shortest_paths[ac.callsign], float)
            poly = float(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)))
            _, straight = dubins_path_length(scenario, ac)
            detour = max(poly - straight, 0.0)
        out[ac.callsign] = earliest_landing_time(scenario, ac, detour)
    return out
