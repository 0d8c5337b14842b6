"""Polylines flown at constant airspeed: air distances, times at the vertices, gate crossings.

In a wind every length that stands for a time is the *air distance* (the time flown x the airspeed,
:meth:`~mal_planner.dynamics.DynamicsModel.air_distance`): each straight segment is flown at the ground speed of
the wind triangle along it.
"""

from __future__ import annotations

import numpy as np

from mal_planner.dynamics import DynamicsModel
from mal_planner.initializer.base import path_length
from mal_planner.scenario import Scenario


def air_lengths(dynamics: DynamicsModel, path: np.ndarray) -> np.ndarray:
    """Air distance (nm) of each segment of the polyline ``path`` (K, 3) (its length in still air); a repeated
    vertex gives 0."""
    return dynamics.air_distance(np.diff(np.asarray(path, float), axis=0))


def air_path_length(dynamics: DynamicsModel, path: np.ndarray) -> float:
    """:func:`path_length` in the air: the time to fly ``path`` at the airspeed (its length in still air)."""
    if not dynamics.has_wind:
        return path_length(path)
    return float(np.sum(air_lengths(dynamics, path))) if len(path) > 1 else 0.0


def timed_path(path: np.ndarray, speed: float | DynamicsModel) -> np.ndarray:
    """Time at each vertex at the constant airspeed ``speed`` (or the aircraft's ``dynamics``, whose wind sets the
    ground speed on each segment): cumulative air distance / airspeed, 0 at the first vertex."""
    if isinstance(speed, DynamicsModel):
        return np.concatenate([[0.0], np.cumsum(air_lengths(speed, path))]) / speed.speed
    seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(seg)]) / speed


def timed_guess(path: np.ndarray, speed: float | DynamicsModel, landing_time: float, samples: int = 200
                ) -> tuple[np.ndarray, np.ndarray]:
    """Times and positions of a path flown as the optimizer's guess flies it: stretched in time to land at
    ``landing_time`` (see :mod:`mal_planner.landing.guess`), ``samples`` points evenly in time."""
    times = timed_path(path, speed)
    t = np.linspace(0.0, landing_time, samples)
    scaled = times * (landing_time / times[-1]) if times[-1] > 0 else times
    return t, np.column_stack([np.interp(t, scaled, path[:, k]) for k in range(3)])


def gate_crossing_times(scenario: Scenario, path: np.ndarray, times: np.ndarray) -> dict[str, float | None]:
    """First time the path crosses each gate's plane in its direction of travel (linear interpolation)."""
    out: dict[str, float | None] = {}
    for gate in scenario.gates:
        s = gate.signed_distance(path)
        hit = np.flatnonzero((s[:-1] > 0.0) & (s[1:] <= 0.0))
        if hit.size == 0:
            out[gate.name] = None
            continue
        i = int(hit[0])
        f = s[i] / (s[i] - s[i + 1])
        out[gate.name] = float(times[i] + f * (times[i + 1] - times[i]))
    return out
