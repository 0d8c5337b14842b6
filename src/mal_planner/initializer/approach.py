"""The approach: the fixed end of every initial path, as arrivals fly it (through the hole, then the final).

A path planner alone joins the start to the runway threshold by any free polyline; one that reaches the
threshold from the side, or that a sequencing waypoint makes come back from behind the runway, asks the
optimizer for a turn no aircraft can fly in the room left (campaign traffic at a terminal area's size:
IPOPT's ``Infeasible_Problem_Detected`` from such guesses). Here every path ends on a route that an aircraft
can fly, in turn radii R of that aircraft:

* the **final approach**: the last ``FINAL_RADII`` R straight in along the runway's heading and flight-path
  angle (from the final approach fix F; an aircraft already established on the final inside F flies straight in);
* through a **gate**, for an aircraft still ahead of it: ``GATE_RADII`` R straight along the gate's heading
  before and after the hole (entry E, hole point H, exit X), H the point of the hole's central part that
  makes the straight path start -> H -> F shortest.

The path planner then only joins the start to the first point of the route (E, or F without a gate).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mal_planner.initializer.collision import CollisionChecker
from mal_planner.obstacles import Gate
from mal_planner.scales import level_turn_radius
from mal_planner.scenario import Aircraft, Scenario
from mal_planner.sequencing.schedule import FINAL_RADII

GATE_RADII = 1.0
"""Straight flight before and after a gate's hole, in turn radii (thesis: 0.3 nm)."""
ESTABLISHED_DEG = 15.0
"""An aircraft heading along the runway's course within this (a crab in a crosswind included) ..."""
CENTRELINE_DEG = 5.0
"""... and within this of the extended centreline seen from the threshold (twice an ILS localizer's full-scale
deflection) is established on the final: it flies straight in. 3 nm off it 12 nm out (14 deg) it still turns."""
HOLE_SAMPLES = 9
HOLE_CORE = 0.8
"""The hole points tried lie in this central share of the hole's width (away from the wall's rounded edges)."""


def direction(flight_path_angle: float, heading: float) -> np.ndarray:
    """Unit vector of flight at the given angles (rad)."""
    c = math.cos(flight_path_angle)
    return np.array([c * math.cos(heading), c * math.sin(heading), math.sin(flight_path_angle)])


@dataclass(frozen=True)
class Approach:
    """One aircraft's route to the runway: ``points`` (K, 3), the last one the threshold."""

    points: np.ndarray
    established: bool = False
    """Already on the extended centreline (:func:`established`): straight in, no turn to leave time for."""

    @property
    def first(self) -> np.ndarray:
        return self.points[0]

    @property
    def length(self) -> float:
        return float(np.sum(np.linalg.norm(np.diff(self.points, axis=0), axis=1)))


def _hole_points(gate: Gate) -> np.ndarray:
    """Points across the central part of the hole, on the gate plane at the hole's mid height."""
    (a_lo, a_hi), (b_lo, b_hi) = gate.bounds
    ax_a, ax_b = gate.other_axes
    half = 0.5 * HOLE_CORE * (a_hi - a_lo)
    pts = np.zeros((HOLE_SAMPLES, 3))
    pts[:, gate.axis] = gate.position
    pts[:, ax_a] = 0.5 * (a_lo + a_hi) + np.linspace(-half, half, HOLE_SAMPLES)
    pts[:, ax_b] = 0.5 * (b_lo + b_hi)
    return pts


def _free_point(checker: CollisionChecker, anchor: np.ndarray, step: np.ndarray, length: float) -> np.ndarray | None:
    """``anchor - length * step`` shortened (halved, at most 6 times) until the point and the segment to the
    anchor are free; None if none is."""
    for _ in range(7):
        point = anchor - length * step
        if checker.point_free(point) and checker.segment_free(point, anchor):
            return point
        length *= 0.5
    return None


def established(aircraft: Aircraft, runway: np.ndarray, final_dir: np.ndarray) -> float | None:
    """How far (nm) before the threshold ``aircraft`` flies on the extended centreline, None if it does not: within
    :data:`CENTRELINE_DEG` of it seen from the threshold, heading along the runway's course within
    :data:`ESTABLISHED_DEG`. Such an
    aircraft flies straight in, with no turn to leave time for: scheduled with the turn margin, JAL45 at CDG 14:24,
    1.6 nm out and really landing 41 s later, was given 50 s and flew away from the runway to lose the time; and one
    inside the final approach fix is not routed back out through it (EJU875P at 12:32, 0.8 nm out: 59 s)."""
    course = final_dir[:2] / max(float(np.linalg.norm(final_dir[:2])), 1e-300)
    to_runway = runway[:2] - np.asarray(aircraft.position, float)[:2]
    along = float(np.dot(to_runway, course))
    lateral = abs(float(course[0] * to_runway[1] - course[1] * to_runway[0]))
    off = (float(aircraft.state0[4]) - math.atan2(course[1], course[0]) + math.pi) % (2.0 * math.pi) - math.pi
    aligned = abs(off) <= math.radians(ESTABLISHED_DEG)
    return along if along > 0.0 and lateral <= along * math.tan(math.radians(CENTRELINE_DEG)) and aligned else None


def approach_for(scenario: Scenario, aircraft: Aircraft, checker: CollisionChecker) -> Approach:
    """The route of ``aircraft`` (see the module docstring); parts that are not free are left out."""
    radius = level_turn_radius(aircraft)
    runway = np.asarray(scenario.runway_state[:3], float)
    final_dir = direction(float(scenario.runway_state[3]), float(scenario.runway_state[4]))
    on_final = established(aircraft, runway, final_dir)
    if on_final is not None and on_final <= FINAL_RADII * radius:
        return Approach(np.array([runway]), established=True)
    fix = _free_point(checker, runway, final_dir, FINAL_RADII * radius)
    tail = [runway] if fix is None else [fix, runway]
    gate = scenario.gates[0] if scenario.gates else None
    ahead = 0.0 if gate is None else float(gate.signed_distance(aircraft.position))
    if gate is None or ahead <= 0.0:
        return Approach(np.array(tail), established=on_final is not None)
    step = direction(gate.flight_path_angle, gate.heading)
    along = min(GATE_RADII * radius, 0.5 * ahead)
    start = aircraft.position
    best = None
    for hole in _hole_points(gate):
        entry, exit_ = hole - along * step, hole + along * step
        if not (checker.point_free(entry) and checker.segment_free(entry, exit_)):
            continue
        length = float(np.linalg.norm(entry - start) + np.linalg.norm(tail[0] - exit_))
        if best is None or length < best[0]:
            best = (length, entry, hole, exit_)
    if best is None:
        return Approach(np.array(tail))
    _, entry, hole, exit_ = best
    # The final approach fix is left out where the gate lies inside it (the exit is already past the fix).
    if fix is not None and float(np.dot(exit_ - fix, final_dir)) >= 0.0:
        tail = [runway]
    return Approach(np.array([entry, hole, exit_, *tail]))
