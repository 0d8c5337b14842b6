"""The paths of the service's own instructions: a holding pattern and a vector, as time-stamped references.

An aircraft without a valid plan still needs an instruction a controller would give (issue 32): hold at a fix or
fly a heading and a level. Both are flown like any plan (the same :class:`~mal_planner.trajectory.Reference`, the
same guidance), so they are drawn here as the aircraft flies them at its airspeed in the wind the service knows:

* a heading (straight) or a turn at a fixed rate is flown through the air mass, so it drifts with the wind, as an
  aircraft told "fly heading 270" does;
* a hold's orbit is fixed to the ground, as a holding fix is: the aircraft corrects for the wind, so its ground
  speed along the circle is w.t + sqrt(V^2 - |w|^2 + (w.t)^2) (the wind triangle; t the circle's tangent), and the
  orbit is timed by it. Timed at the airspeed instead, the reference runs ahead upwind and behind downwind of the
  aircraft, and the traffic picture predicted from it is off by the wind times the look-ahead.

A level change is flown at a fixed gradient from the aircraft's state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mal_planner.trajectory import Reference

LEVEL_CHANGE_DEG = 3.0
"""Climb or descent gradient to a new level: the 3 deg of a standard descent (ICAO PANS-OPS's nominal glide path)."""
ORBIT_STEPS = 72
"""Samples per orbit of a hold (5 deg each: chords 0.4 % of the radius inside the circle)."""


@dataclass(frozen=True)
class Leg:
    """Fly ``duration_s`` at a constant turn rate through the air mass (rad/s; 0: a constant heading)."""

    duration_s: float
    turn_rate: float = 0.0


@dataclass(frozen=True)
class Orbit:
    """Fly ``duration_s`` around a circle of ``radius`` fixed to the ground, entered tangentially where the aircraft
    is, turning right or left."""

    duration_s: float
    radius: float
    right: bool


def level_profile(z0: float, level: float, speed: float, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Heights and flight-path angles from ``z0`` to ``level`` at :data:`LEVEL_CHANGE_DEG`, then level."""
    gamma = math.radians(LEVEL_CHANGE_DEG) * (1.0 if level > z0 else -1.0)
    rate = speed * math.sin(gamma)
    t_level = abs(level - z0) / abs(rate) if level != z0 else 0.0
    z = np.where(t < t_level, z0 + rate * t, level)
    return z, np.where(t < t_level, gamma, 0.0)


def ground_speed(speed: float, wind: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Ground speed along the unit ``direction`` (..., 2) of an aircraft at airspeed ``speed`` correcting for
    ``wind``."""
    along = np.asarray(direction, float) @ wind
    return along + np.sqrt(np.maximum(speed**2 - float(np.dot(wind, wind)) + along**2, 0.0))


def _air_leg(pose: list[float], speed: float, wind: np.ndarray, leg: Leg, step_s: float) -> list[list[float]]:
    """The poses (t, x, y, heading) of ``leg`` flown from ``pose`` through the air mass."""
    t, x, y, heading = pose
    n = max(int(math.ceil(leg.duration_s / step_s)), 1)
    dt = leg.duration_s / n
    out = []
    for _ in range(n):
        if leg.turn_rate == 0.0:
            x += speed * dt * math.cos(heading)
            y += speed * dt * math.sin(heading)
        else:  # exact arc in the air mass: radius V / omega
            r = speed / leg.turn_rate
            new = heading + leg.turn_rate * dt
            x += r * (math.sin(new) - math.sin(heading))
            y -= r * (math.cos(new) - math.cos(heading))
            heading = new
        t += dt
        x, y = x + wind[0] * dt, y + wind[1] * dt
        out.append([t, x, y, heading])
    return out


def _orbit(pose: list[float], speed: float, wind: np.ndarray, orbit: Orbit) -> list[list[float]]:
    """The poses (t, x, y, heading) of ``orbit`` entered from ``pose``: the circle tangent to the ground track there,
    sampled every :data:`ORBIT_STEPS`-th of a turn, each arc timed at the ground speed at its middle."""
    t, x, y, heading = pose
    track = np.array([math.cos(heading), math.sin(heading)]) * speed + wind
    course = math.atan2(track[1], track[0])
    sign = -1.0 if orbit.right else 1.0  # angles anticlockwise from x: a right turn runs clockwise
    cx, cy = x - sign * orbit.radius * math.sin(course), y + sign * orbit.radius * math.cos(course)
    d_theta = sign * 2.0 * math.pi / ORBIT_STEPS
    arc = orbit.radius * abs(d_theta)
    steps = np.arange(1, int(math.ceil(orbit.duration_s * (speed + np.linalg.norm(wind)) / arc)) + 2)
    theta = math.atan2(y - cy, x - cx) + d_theta * steps

    def tangent(angle: np.ndarray) -> np.ndarray:
        return sign * np.column_stack([-np.sin(angle), np.cos(angle)])

    times = t + np.cumsum(arc / ground_speed(speed, wind, tangent(theta - 0.5 * d_theta)))
    n = int(np.searchsorted(times, t + orbit.duration_s)) + 1  # the first sample at or past the end
    theta, times = theta[:n], times[:n]
    air = ground_speed(speed, wind, tangent(theta))[:, None] * tangent(theta) - wind
    return np.column_stack([times, cx + orbit.radius * np.cos(theta), cy + orbit.radius * np.sin(theta),
                            np.arctan2(air[:, 1], air[:, 0])]).tolist()


def fly_legs(state: np.ndarray, speed: float, legs: list[Leg | Orbit], level: float, t0: float, step_s: float,
             wind: tuple[float, float] = (0.0, 0.0)) -> Reference:
    """The reference of an aircraft in ``state`` (x, y, z, gamma, heading) at ``t0`` flying ``legs`` in turn at
    airspeed ``speed`` (nm/s) in ``wind`` (nm/s) while it changes to ``level`` (nm)."""
    w = np.asarray(wind, float)
    poses = [[0.0, float(state[0]), float(state[1]), float(state[4])]]
    for leg in legs:
        more = _orbit(poses[-1], speed, w, leg) if isinstance(leg, Orbit) else _air_leg(poses[-1], speed, w, leg,
                                                                                          step_s)
        poses.extend(more)
    table = np.asarray(poses)
    tt = table[:, 0]
    z, gamma = level_profile(float(state[2]), level, speed, tt)
    heading = float(state[4]) + np.unwrap(table[:, 3] - float(state[4]))
    airspeed = np.full(len(tt), speed)
    return Reference(tt + t0, np.column_stack([table[:, 1], table[:, 2], z, gamma, heading, airspeed]))


def holding_pattern(state: np.ndarray, speed: float, radius: float, *, right: bool, straight_s: float, level: float,
                    t0: float, duration_s: float, step_s: float, wind: tuple[float, float] = (0.0, 0.0)
                    ) -> Reference:
    """A hold: ``straight_s`` on along the heading, then orbits of ``radius`` around a fix on the ground (right or
    left turns) at ``level``, until ``duration_s`` after ``t0``."""
    legs: list[Leg | Orbit] = [Leg(straight_s)] if straight_s > 0 else []
    legs.append(Orbit(max(duration_s - straight_s, step_s), radius, right))
    return fly_legs(state, speed, legs, level, t0, step_s, wind)


def vector(state: np.ndarray, speed: float, radius: float, heading: float, *, level: float, t0: float,
           duration_s: float, step_s: float, wind: tuple[float, float] = (0.0, 0.0)) -> Reference:
    """A vector: turn the short way (at ``radius`` through the air mass) onto ``heading`` and fly it at ``level``
    until ``duration_s`` after ``t0``."""
    change = (heading - float(state[4]) + math.pi) % (2.0 * math.pi) - math.pi
    rate = math.copysign(speed / radius, change) if change != 0.0 else 0.0
    turn_s = abs(change) / abs(rate) if rate else 0.0
    legs: list[Leg | Orbit] = [Leg(turn_s, rate)] if turn_s > 0 else []
    legs.append(Leg(max(duration_s - turn_s, step_s)))
    return fly_legs(state, speed, legs, level, t0, step_s, wind)
