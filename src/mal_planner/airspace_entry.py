"""Initial states at the airspace's edge: radar noise puts aircraft just outside, or on the edge heading out.

The verification flies the published controls from the initial states and allows no excursion out of the airspace.
An aircraft on the floor while descending (or at a wall while heading out) cannot help leaving it for a moment: it
needs some distance to pull up or turn away. In closed loop that happened to one replan in ten at ten aircraft
(descents onto the runway's floor, measured a few metres low): the replan was refused by 5e-6 nm at t = 0.05 s. So
before planning, an initial position is moved

* onto the airspace when the radar put it outside (by at most ``tolerance_nm``; further out is bad input), and, when it
  is then within the optimizer's airspace margin of a face (every other point of a plan keeps that margin) and does not
  leave that band within a turn time, to the margin: a start on the floor flying level dipped 5e-6 nm under it at
  t = 0.02 s in the flown controls, which the collocation does not see between its points;
* away from a face it moves towards by twice the distance it needs to turn away from it (at the load-factor and bank
  limits; twice, so the optimizer needs only half its authority and keeps the rest for its own margins), at most by
  ``tolerance_nm`` (an aircraft that needs more gets a plan the verification refuses, as it should).

The moves are metres (the thesis's floor: 4.6 m for the margin, 0.1 m for a 1 deg descent), less than radar noise.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from mal_planner.scales import Scales
from mal_planner.scenario import Aircraft, Scenario

log = logging.getLogger("mal_planner")

TURN_AWAY_FACTOR = 2.0
"""An aircraft heading towards a face is kept this many times its turn-away distance from it (see the module)."""


def initial_velocity(ac: Aircraft) -> np.ndarray:
    """``ac``'s ground velocity (nm/s) at its initial state (wind included: the dynamics model's own)."""
    state = np.asarray(ac.state0, float)
    return np.asarray(ac.dynamics.rhs(state, ac.dynamics.level_flight_control(state[3])), float)[:3]


def turn_away_nm(ac: Aircraft, velocity: np.ndarray, axis: int, side: int) -> float:
    """How far ``ac``, at ``velocity`` (:func:`initial_velocity`), flies towards the face of the airspace on ``side``
    (-1 low, +1 high) of ``axis`` (0-2) before it moves away from it again, at full load factor (0 when it is moving
    away already)."""
    gamma = float(ac.state0[3])
    towards = side * float(velocity[axis])
    if towards <= 0.0:
        return 0.0
    g, limits = ac.dynamics.gravity, ac.limits
    if axis == 2:  # pull up from the floor, push over below the ceiling: z'' = g cos(gamma) (n_v - cos(gamma))
        n_v = limits.n_v[1] - math.cos(gamma) if side < 0 else math.cos(gamma) - limits.n_v[0]
        accel = g * math.cos(gamma) * n_v
        return math.inf if accel <= 0.0 else towards**2 / (2.0 * accel)
    # A level turn at the bank limit: radius R = V_h^2 / (g n_h); turning away from a face approached at the angle
    # theta takes R (1 - cos theta).
    n_h = min(limits.n_h[1], math.cos(gamma) * math.tan(limits.bank_angle_max))
    v_h = float(np.hypot(velocity[0], velocity[1]))
    if n_h <= 0.0:
        return math.inf
    radius = v_h**2 / (g * n_h)
    return radius * (1.0 - math.sqrt(max(0.0, 1.0 - (towards / v_h) ** 2)))


def inside_airspace(scenario: Scenario, tolerance_nm: float | None = None, margin_nm: float = 0.0,
                    ceiling_margin_nm: float | None = None) -> Scenario:
    """``scenario`` with its initial positions moved off the airspace's edge (see the module docstring).

    Raises ValueError naming the aircraft when one is further out than ``tolerance_nm`` (default: twice the
    scenario's path accuracy, 0.01 nm in the thesis). ``margin_nm``: the optimizer's airspace margin;
    ``ceiling_margin_nm``: its margin below the ceiling (None: ``margin_nm``).
    """
    scales = Scales.of(scenario)
    if tolerance_nm is None:
        tolerance_nm = 2.0 * scales.accuracy_nm
    turn_time = scales.seconds(1.0)
    lo, hi = scenario.airspace[:, 0], scenario.airspace[:, 1]
    moved = {}
    for ac in scenario.aircraft:
        clipped = np.clip(ac.position, lo, hi)
        offset = float(np.max(np.abs(clipped - ac.position)))
        if offset > tolerance_nm:
            raise ValueError(f"{ac.callsign}: initial position {np.round(ac.position, 4).tolist()} nm is "
                             f"{offset:.3f} nm outside the airspace")
        position = clipped.copy()
        velocity = initial_velocity(ac)
        for axis in range(3):
            for side, face in ((-1, lo[axis]), (1, hi[axis])):
                margin = ceiling_margin_nm if axis == 2 and side == 1 and ceiling_margin_nm is not None else margin_nm
                lingers = -side * velocity[axis] * turn_time < margin  # still within the margin a turn time on
                turn = min(TURN_AWAY_FACTOR * turn_away_nm(ac, velocity, axis, side), tolerance_nm)  # more: bad luck
                clearance = (margin if lingers else 0.0) + turn
                if side * (position[axis] - face) > -clearance:
                    position[axis] = face - side * min(clearance, 0.5 * (hi[axis] - lo[axis]))
        shift = float(np.max(np.abs(position - ac.position)))
        if shift > 0.0:
            log.warning("%s: initial position moved %.4f nm %s", ac.callsign, shift,
                        "into the airspace" if offset > 0.0 else "off the airspace's edge")
            moved[ac.callsign] = np.concatenate([position, ac.state0[3:]])
    return scenario.with_initial_states(moved) if moved else scenario
