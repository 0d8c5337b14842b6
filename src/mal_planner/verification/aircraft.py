"""The checks of one aircraft's flown plan: how closely it follows the published one, the airspace and obstacles, the
gates, the published controls against the limits, and the runway."""

from __future__ import annotations

import math

import numpy as np

from mal_planner.scenario import Scenario
from mal_planner.trajectory import Trajectory
from mal_planner.verification.procedures import procedure_breaks
from mal_planner.verification.report import AircraftCheck, Tolerances
from mal_planner.verification.space import chord_error_bound, gate_crossings, path_in_space


def check_aircraft(scenario: Scenario, traj: Trajectory, t: np.ndarray, x: np.ndarray, tol: Tolerances, fail,
                   landing_times: dict[str, float] | None) -> AircraftCheck:
    """The checks of ``traj`` flown as ``(t, x)``; ``fail(callsigns, text)`` for each one that fails."""
    cs = traj.callsign
    aircraft = scenario.aircraft_by_callsign(cs)
    pos_dev, ang_dev, accuracy_times = _deviation(traj, t, x, tol, fail)
    chord = chord_error_bound(aircraft, t)
    limit_times: list[float] = list(accuracy_times)
    space = path_in_space(scenario, cs, t, x, chord)
    for text in space.reasons:
        fail((cs,), text)
    limit_times += space.airspace_times
    events, outside_hole = _gates(scenario, aircraft, cs, t, x, chord, tol, fail)
    limit_times += outside_hole
    bank, n_v, bad_times = _controls(traj, aircraft, fail)
    limit_times += bad_times
    runway = _runway(scenario, aircraft, cs, x, tol, fail)
    for broken in procedure_breaks(scenario, aircraft, t, x):
        fail((cs,), broken.text)
        if broken.kept_by_nlp:  # broken between collocation points: refined there
            limit_times.append(broken.time_s)
    if landing_times is not None and cs in landing_times and \
            abs(t[-1] - landing_times[cs]) > tol.landing_time_s:
        fail((cs,), f"{cs}: lands at {t[-1]:.3f} s, not the fixed {landing_times[cs]:.3f} s")
    return AircraftCheck(cs, float(t[-1]), pos_dev, ang_dev, float(np.min(bank)), float(np.max(bank)),
                         float(np.min(n_v)), space.airspace_violation_nm, space.obstacles, space.obstacle_times,
                         events, runway, limit_times,
                         None if x.shape[1] < 6 else float(np.min(x[:, 5])))


def _deviation(traj: Trajectory, t: np.ndarray, x: np.ndarray, tol: Tolerances,
               fail) -> tuple[float, float, list[float]]:
    """Largest position and angle differences between the published and the flown path; when the position
    drifts too far, the times it drifts fastest (where the mesh is least accurate: refined there)."""
    cs = traj.callsign
    solved = traj.state_at(t)
    pos_dev = float(np.max(np.linalg.norm(solved[:, :3] - x[:, :3], axis=1)))
    ang_dev = float(np.max(np.abs(np.remainder(solved[:, 3:5] - x[:, 3:5] + np.pi, 2 * np.pi) - np.pi)))
    if pos_dev > tol.deviation_nm:
        fail((cs,), f"{cs}: re-integrated path deviates {pos_dev:.4g} nm from the plan")
        # Refine where the deviation grows fastest: the mesh is least accurate there.
        growth = np.diff(np.linalg.norm(solved[:, :3] - x[:, :3], axis=1)) / np.maximum(np.diff(t), 1e-9)
        accuracy_times = t[np.argsort(growth)[-3:]].tolist()
    else:
        accuracy_times = []
    if ang_dev > tol.deviation_angle:
        fail((cs,), f"{cs}: re-integrated angles deviate {math.degrees(ang_dev):.3g} deg from the plan")
    return pos_dev, ang_dev, accuracy_times


def _gates(scenario: Scenario, aircraft, cs: str, t: np.ndarray, x: np.ndarray, chord: float, tol: Tolerances,
           fail) -> tuple[list[dict], list[float]]:
    """Every plane crossing must be in the hole, in the right direction, with the set attitude. Returns the
    crossings and the times of those outside the hole."""
    events: list[dict] = []
    outside: list[float] = []
    for gate in scenario.gates:
        crossings = gate_crossings(gate, t, x)
        if not crossings and gate.signed_distance(aircraft.state0[:3]) > 0:
            fail((cs,), f"{cs}: never passes gate {gate.name!r}")
        # The gate's heading is a ground track: in a wind the flown (air) heading is crabbed.
        gate_heading = aircraft.heading_for_track(gate.heading, gate.flight_path_angle)
        for ev in crossings:
            ev["track"] = aircraft.dynamics.ground_track(ev["gamma"], ev["heading"])
            ev["gamma_error"] = _angle_error(ev["gamma"], gate.flight_path_angle)
            ev["heading_error"] = _angle_error(ev["heading"], gate_heading)
            if not gate.in_hole(np.array(ev["position"]), -chord):
                fail((cs,), f"{cs}: crosses the plane of {gate.name!r} outside the hole at "
                               f"{np.round(ev['position'], 4).tolist()}")
                outside.append(ev["time_s"])
            if not ev["direction_ok"]:
                fail((cs,), f"{cs}: crosses {gate.name!r} backwards at t={ev['time_s']:.2f} s")
            if ev["gamma_error"] > tol.attitude or ev["heading_error"] > tol.attitude:
                g_err, h_err = math.degrees(ev["gamma_error"]), math.degrees(ev["heading_error"])
                fail((cs,), f"{cs}: attitude at {gate.name!r} off by {g_err:.3g} / {h_err:.3g} deg")
        events.extend(crossings)
    return events, outside


def _controls(traj: Trajectory, aircraft, fail) -> tuple[np.ndarray, np.ndarray, list[float]]:
    """Load factors and bank angle, exactly as published (linear between samples: the limits are convex).
    Returns the bank angles (deg), n_v and the times a limit is broken."""
    cs = traj.callsign
    n_h, n_v = traj.controls[:, 0], traj.controls[:, 1]
    lim = aircraft.limits
    bank = np.degrees(np.arctan2(n_h, n_v))
    cap = np.tan(lim.bank_angle_max) * n_v
    bad = (np.abs(n_h) > cap) | (n_h < lim.n_h[0]) | (n_h > lim.n_h[1]) | (n_v < lim.n_v[0]) | (n_v > lim.n_v[1])
    if np.any(np.abs(n_h) > cap):
        fail((cs,), f"{cs}: bank angle reaches {np.max(np.abs(bank)):.3f} deg (limit "
                    f"{math.degrees(lim.bank_angle_max):.1f}) at t={traj.t[np.argmax(np.abs(bank))]:.2f} s")
    if np.any(bad & ~(np.abs(n_h) > cap)):
        k = int(np.flatnonzero(bad)[0])
        fail((cs,), f"{cs}: load factors ({n_h[k]:.4g}, {n_v[k]:.4g}) outside n_h {list(lim.n_h)}, "
                    f"n_v {list(lim.n_v)} at t={traj.t[k]:.2f} s")
    return bank, n_v, traj.t[bad].tolist()


def _runway(scenario: Scenario, aircraft, cs: str, x: np.ndarray, tol: Tolerances, fail) -> dict:
    """How far the flown path ends from the runway threshold's position and attitude."""
    final = x[-1]
    rw = scenario.runway_state
    runway = {
        "position_error_nm": float(np.linalg.norm(final[:3] - rw[:3])),
        "gamma_error": _angle_error(final[3], rw[3]),
        "heading_error": _angle_error(final[4], scenario.runway_heading(aircraft)),  # crabbed in a wind
        "track_error": _angle_error(aircraft.dynamics.ground_track(final[3], final[4]), rw[4]),
    }
    if runway["position_error_nm"] > tol.position_nm + tol.deviation_nm:
        fail((cs,), f"{cs}: ends {runway['position_error_nm']:.4g} nm from the runway")
    if runway["gamma_error"] > tol.attitude or runway["heading_error"] > tol.attitude:
        fail((cs,), f"{cs}: runway attitude off by {math.degrees(runway['gamma_error']):.3g} / "
                       f"{math.degrees(runway['heading_error']):.3g} deg")
    return runway


def _angle_error(a: float, b: float) -> float:
    return abs(math.remainder(a - b, 2 * math.pi))
