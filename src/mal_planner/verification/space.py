"""A flown path in its airspace: the chord error between samples, airspace exits, obstacle entries and gate
crossings."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mal_planner.scenario import Scenario


def chord_error_bound(aircraft, t: np.ndarray) -> float:
    """Largest distance (nm) between the path and the chord between two samples ``t`` apart.

    A constant-speed point mass accelerates at g sqrt((n_v - cos gamma)^2 + n_h^2) at most (a constant wind adds
    none), the airspeed model along its path by g |n_x - sin gamma| more; a curve with acceleration <= a stays
    within dt^2 a / 8 of its chord over a step dt.
    """
    lim = aircraft.limits
    along = 1.0 + max(abs(lim.n_x[0]), abs(lim.n_x[1])) if aircraft.dynamics.variable_airspeed else 0.0
    a_max = aircraft.dynamics.gravity * math.hypot(max(abs(lim.n_v[0] - 1.0), lim.n_v[1] + 1.0),
                                                   max(abs(lim.n_h[0]), abs(lim.n_h[1])), along)
    dt = float(np.max(np.diff(t))) if len(t) > 1 else 0.0
    return dt * dt * a_max / 8.0


@dataclass
class SpaceCheck:
    """The airspace exits and obstacle entries of one flown path, and their reasons (one line each)."""

    airspace_violation_nm: float
    airspace_times: list[float]
    obstacles: list[str]
    obstacle_times: list[float]
    reasons: list[str]


def path_in_space(scenario: Scenario, cs: str, t: np.ndarray, x: np.ndarray, chord: float) -> SpaceCheck:
    """Airspace and obstacles along a sampled path whose chords are within ``chord`` of it."""
    reasons: list[str] = []
    # Airspace, with the chord error to spare (not at the given initial state, which may lie on a bound).
    spare = np.where(t > t[0], chord, 0.0)[:, None]
    below = scenario.airspace[:, 0] - x[:, :3] + spare
    above = x[:, :3] - scenario.airspace[:, 1] + spare
    out_of_space = np.max(np.maximum(below, above), axis=1)
    violation = float(max(np.max(out_of_space), 0.0))
    if violation > 0.0:
        k = int(np.argmax(out_of_space))
        reasons.append(f"{cs}: leaves the airspace by {violation:.3g} nm at t={t[k]:.2f} s")
    # Obstacles, inflated by the chord error: exact containment of every sample and every chord.
    hits, hit_times = [], []
    for ob in scenario.obstacles:
        grown = ob.inflated(chord)
        inside = grown.contains(x[:, :3])
        inside[:-1] |= grown.segment_hits(x[:-1, :3], x[1:, :3])
        if np.any(inside):
            hits.append(ob.name)
            hit_times += t[inside].tolist()
            reasons.append(f"{cs}: enters obstacle {ob.name!r} at t={t[inside][0]:.2f} s")
    return SpaceCheck(violation, t[out_of_space > 0.0].tolist(), hits, hit_times, reasons)


def flown_path_infringements(scenario: Scenario, aircraft, t: np.ndarray, x: np.ndarray) -> list[str]:
    """Airspace exits and obstacle entries of a flown track (samples ``t``, states ``x``), one line each: the
    checks :func:`verify` makes on a re-integrated plan, for tracks flown in closed loop."""
    return path_in_space(scenario, aircraft.callsign, t, x, chord_error_bound(aircraft, t)).reasons


def gate_crossings(gate, t: np.ndarray, states: np.ndarray) -> list[dict]:
    """Every crossing of the gate plane, linearly interpolated between dense samples."""
    d = gate.signed_distance(states[:, :3])
    events = []
    for k in np.flatnonzero((d[:-1] > 0) & (d[1:] <= 0) | (d[:-1] < 0) & (d[1:] >= 0)):
        w = d[k] / (d[k] - d[k + 1]) if d[k] != d[k + 1] else 0.0
        point = states[k] + w * (states[k + 1] - states[k])
        events.append({
            "gate": gate.name,
            "time_s": float(t[k] + w * (t[k + 1] - t[k])),
            "position": point[:3].tolist(),
            "in_hole": bool(gate.in_hole(point[:3])),
            "direction_ok": bool(d[k] > 0),
            "gamma": float(point[3]),
            "heading": float(point[4]),
        })
    return events
