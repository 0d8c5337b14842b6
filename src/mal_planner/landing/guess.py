"""Initial guesses for the landing problem: from the RRT initializer, or naive straight lines.

Both give, per aircraft, a time series of the states at constant speed, time-scaled so that the
aircraft lands at its fixed landing time when the scenario fixes one, and the time at which the
path crosses the gate plane (which places the phase boundaries). In a wind each segment is flown at its ground
speed and its states carry the air-relative (crabbed) angles that fly it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mal_planner.dynamics import DynamicsModel
from mal_planner.obstacles import Gate
from mal_planner.scales import level_turn_radius
from mal_planner.scenario import Aircraft, Scenario
from mal_planner.sequencing.timing import nominal_speeds


@dataclass(frozen=True)
class AircraftGuess:
    callsign: str
    t: np.ndarray
    states: np.ndarray
    """(K, 5) x, y, z, gamma, heading (heading unwrapped); (K, 6) with the airspeed where cut from an airspeed-model
    plan."""
    landing_time: float
    gate_time: float | None
    shifted_by: float = 0.0
    """Seconds by which the plan this guess was cut from had been flown (a replan, see
    :func:`~mal_planner.landing.solve.shift_guesses`): its meshes are cut by as much (:func:`meshes_after`)."""

    def controls(self, model_gravity: float, speed: float) -> np.ndarray:
        """Load factors that reproduce the guess's angle rates (finite differences), clipped later."""
        gamma, heading = self.states[:, 3], self.states[:, 4]
        dt = np.gradient(self.t)
        dt = np.where(dt > 0, dt, 1.0)
        gamma_rate = np.gradient(gamma) / dt
        heading_rate = np.gradient(heading) / dt
        n_v = np.cos(gamma) + speed / model_gravity * gamma_rate
        n_h = speed / model_gravity * heading_rate * np.cos(gamma)
        return np.column_stack([n_h, n_v])

    def state_at(self, t: np.ndarray) -> np.ndarray:
        return np.column_stack([np.interp(t, self.t, self.states[:, k]) for k in range(5)])

    def model_states(self, aircraft: Aircraft, t: np.ndarray) -> np.ndarray:
        """The states of ``aircraft``'s model at ``t``: the path's five, and an airspeed model's airspeed (its first
        airspeed, at which the path is timed)."""
        if self.states.shape[1] == aircraft.dynamics.n_states:  # cut from a plan of the same model
            return np.column_stack([np.interp(t, self.t, self.states[:, k]) for k in range(self.states.shape[1])])
        path = self.state_at(t)
        extra = aircraft.state0[5:]
        return np.column_stack([path, np.tile(extra, (len(path), 1))]) if extra.size else path

    def model_controls(self, aircraft: Aircraft, t: np.ndarray) -> np.ndarray:
        """The controls of ``aircraft``'s model at ``t`` that fly the path, within its limits."""
        u_all = self.controls(aircraft.dynamics.gravity, aircraft.speed)
        u = np.column_stack([np.interp(t, self.t, u_all[:, k]) for k in range(2)])
        limits = aircraft.limits
        u[:, 1] = np.clip(u[:, 1], max(limits.n_v[0], 1e-3), limits.n_v[1])
        cap = np.tan(limits.bank_angle_max) * u[:, 1]
        u[:, 0] = np.clip(u[:, 0], np.maximum(-cap, limits.n_h[0]), np.minimum(cap, limits.n_h[1]))
        if aircraft.dynamics.variable_airspeed:  # hold the airspeed, or change it as a scheduled guess does
            gamma = np.interp(t, self.t, self.states[:, 3])
            rate = np.zeros_like(t)
            if self.states.shape[1] > 5 and len(self.t) > 1:
                rate = np.interp(t, self.t, np.gradient(self.states[:, 5], self.t))
            n_x = np.sin(gamma) + rate / aircraft.dynamics.gravity
            u = np.column_stack([u, np.clip(n_x, *limits.n_x)])
        return u


def _crossing_time(gate: Gate | None, t: np.ndarray, points: np.ndarray) -> float | None:
    if gate is None:
        return None
    d = gate.signed_distance(points)
    idx = np.flatnonzero((d[:-1] > 0) & (d[1:] <= 0))
    if idx.size == 0:
        return None
    k = int(idx[0])
    w = d[k] / (d[k] - d[k + 1])
    return float(t[k] + w * (t[k + 1] - t[k]))


def _smooth_angles(states: np.ndarray, window: int) -> np.ndarray:
    """Moving-average the piecewise-constant path angles so the guess has finite rates."""
    if window <= 1 or len(states) < window:
        return states
    out = states.copy()
    kernel = np.ones(window) / window
    for k in (3, 4):
        padded = np.pad(states[:, k], (window // 2, window - 1 - window // 2), mode="edge")
        out[:, k] = np.convolve(padded, kernel, mode="valid")
    return out


def _make_guess(aircraft: Aircraft, t: np.ndarray, states: np.ndarray, gate: Gate | None,
                landing_time: float) -> AircraftGuess:
    """Scale the time axis so the guess lands at ``landing_time``; start from the true initial state, whose
    attitude blends into the path's over one turn time of the aircraft (thesis: 8 s)."""
    smooth_s = level_turn_radius(aircraft) / aircraft.speed
    scale = landing_time / t[-1]
    t = t * scale
    states = states.copy()
    states[:, 4] = np.unwrap(states[:, 4])
    # The first sample carries the aircraft's actual attitude, then blends into the path's angles.
    # The path's headings are shifted by 2 pi k to start within half a turn of the aircraft's own heading
    # (not a full circle away from it, which would guess a turn of a full circle more).
    heading0 = float(aircraft.state0[4])
    first = states[1, 4] + np.remainder(heading0 - states[1, 4] + np.pi, 2 * np.pi) - np.pi
    states[1:, 4] += heading0 - first
    states[0, 3:] = aircraft.state0[3:5]
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    states = _smooth_angles(states, max(1, int(round(smooth_s / dt))))
    return AircraftGuess(aircraft.callsign, t, states, landing_time, _crossing_time(gate, t, states[:, :3]))


def _path_states(points: np.ndarray, dynamics: DynamicsModel, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """States along a polyline at the constant airspeed: positions interpolated, angles per segment. Time advances
    with the air distance (the segment's length in still air; its ground speed sets it in a wind) and the angles
    are the air-relative ones that fly each segment (:meth:`DynamicsModel.air_angles`)."""
    speed = dynamics.speed
    seg = np.diff(points, axis=0)
    length = np.linalg.norm(seg, axis=1)
    keep = length > 1e-12
    seg = seg[keep]
    pts = np.vstack([points[:1], points[1:][keep]])
    s_nodes = np.concatenate([[0.0], np.cumsum(dynamics.air_distance(seg))])
    total = s_nodes[-1]
    n = max(int(np.ceil(total / speed / dt)), 2) + 1
    s = np.linspace(0.0, total, n)
    pos = np.column_stack([np.interp(s, s_nodes, pts[:, k]) for k in range(3)])
    which = np.clip(np.searchsorted(s_nodes, s, side="right") - 1, 0, len(seg) - 1)
    gamma, heading = dynamics.air_angles(seg)
    return s / speed, np.column_stack([pos, gamma[which], np.unwrap(heading[which])])


SAMPLES_PER_TURN_TIME = 7.5
"""Guess samples per turn time of the aircraft (thesis: one a second)."""


def guess_from_initial_plan(scenario: Scenario, trajectories: Sequence, landing_times: Sequence[float]
                            ) -> list[AircraftGuess]:
    """Guesses from the initializer's paths (objects with ``callsign`` and ``waypoints``) in landing order.

    (Rounding the paths' corners at the turn radius was tried: 24 % more planning time on thesis-size and real-size
    scenarios, so the corners stay and the angles are smoothed over a turn time, see :func:`_make_guess`.)"""
    gate = scenario.gates[0] if scenario.gates else None
    out = []
    for traj, t_land in zip(trajectories, landing_times, strict=True):
        ac = scenario.aircraft_by_callsign(traj.callsign)
        t, states = _path_states(np.asarray(traj.waypoints, float), ac.dynamics,
                                 level_turn_radius(ac) / ac.speed / SAMPLES_PER_TURN_TIME)
        out.append(scheduled_guess(scenario, ac, _make_guess(ac, t, states, gate, t_land), gate))
    return out


def straight_line_guess(scenario: Scenario, callsigns: Sequence[str], landing_times: Sequence[float]
                        ) -> list[AircraftGuess]:
    """Naive guesses: straight from each start to the runway, ignoring obstacles and gates."""
    gate = scenario.gates[0] if scenario.gates else None
    out = []
    for cs, t_land in zip(callsigns, landing_times, strict=True):
        ac = scenario.aircraft_by_callsign(cs)
        points = np.vstack([ac.position, scenario.runway_state[:3]])
        t, states = _path_states(points, ac.dynamics, level_turn_radius(ac) / ac.speed / SAMPLES_PER_TURN_TIME)
        out.append(scheduled_guess(scenario, ac, _make_guess(ac, t, states, gate, t_land), gate))
    return out


def scheduled_guess(scenario: Scenario, aircraft: Aircraft, guess: AircraftGuess, gate: Gate | None
                    ) -> AircraftGuess:
    """An airspeed-model aircraft's guess re-timed along its path at the nominal speed schedule of the sequencer
    (:func:`~mal_planner.sequencing.timing.nominal_speeds`, scaled to land at the guess's landing time), with that
    airspeed as its sixth column; other guesses unchanged."""
    if not aircraft.dynamics.variable_airspeed or scenario.procedures is None or len(guess.t) < 2:
        return guess
    steps = np.linalg.norm(np.diff(guess.states[:, :3], axis=0), axis=1)
    along = np.concatenate([[0.0], np.cumsum(steps)])
    speed = nominal_speeds(scenario, aircraft, along[-1] - along)
    t = np.concatenate([[0.0], np.cumsum(steps / (0.5 * (speed[:-1] + speed[1:])))])
    scale = guess.landing_time / t[-1] if t[-1] > 0.0 else 1.0
    states = np.column_stack([guess.states, speed / scale])
    t = t * scale
    return AircraftGuess(guess.callsign, t, states, guess.landing_time, _crossing_time(gate, t, states[:, :3]))


def guess_along(aircraft: Aircraft, t: np.ndarray, states: np.ndarray, gate: Gate | None, landing_time: float
                ) -> AircraftGuess:
    """A guess that follows a given path (an aircraft's current plan, times from the plan's start) from where the
    aircraft is: the offset between the two fades out over one turn time of the aircraft, and the first sample
    carries its attitude."""
    t = np.asarray(t, float)
    states = np.array(states, float)[:, :5]
    fade = np.clip(1.0 - t * aircraft.speed / level_turn_radius(aircraft), 0.0, 1.0)
    states[:, :3] += np.outer(fade, aircraft.state0[:3] - states[0, :3])
    states[:, 4] = np.unwrap(states[:, 4])
    states[:, 4] += 2 * np.pi * np.round((aircraft.state0[4] - states[0, 4]) / (2 * np.pi))  # a whole turn off
    states[0, 3:] = aircraft.state0[3:5]
    return AircraftGuess(aircraft.callsign, t, states, landing_time, _crossing_time(gate, t, states[:, :3]))
