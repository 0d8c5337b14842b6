"""The paths of the service's own instructions: a holding pattern and a vector, as time-stamped references.

An aircraft without a valid plan still needs an instruction a controller would give (issue 32): hold at a fix or
fly a heading and a level. Both are flown like any plan (the same :class:`~mal_planner.trajectory.Reference`, the
same guidance), so they are drawn here as paths at the aircraft's airspeed: a straight leg, a turn at a fixed rate,
and a level change at a fixed gradient, from the aircraft's state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mal_planner.trajectory import Reference

LEVEL_CHANGE_DEG = 3.0
"""Climb or descent gradient to a new level: the 3 deg of a standard descent (ICAO PANS-OPS's nominal glide path)."""


@dataclass(frozen=True)
class Leg:
    """Fly ``duration_s`` at a constant turn rate (rad/s; 0: straight)."""

    duration_s: float
    turn_rate: float = 0.0


def level_profile(z0: float, level: float, speed: float, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Heights and flight-path angles from ``z0`` to ``level`` at :data:`LEVEL_CHANGE_DEG`, then level."""
    gamma = math.radians(LEVEL_CHANGE_DEG) * (1.0 if level > z0 else -1.0)
    rate = speed * math.sin(gamma)
    t_level = abs(level - z0) / abs(rate) if level != z0 else 0.0
    z = np.where(t < t_level, z0 + rate * t, level)
    return z, np.where(t < t_level, gamma, 0.0)


def fly_legs(state: np.ndarray, speed: float, legs: list[Leg], level: float, t0: float, step_s: float
             ) -> Reference:
    """The reference of an aircraft in ``state`` (x, y, z, gamma, heading) at ``t0`` flying ``legs`` in turn at
    ``speed`` (nm/s) while it changes to ``level`` (nm)."""
    x, y, heading = float(state[0]), float(state[1]), float(state[4])
    times, xs, ys, hs = [0.0], [x], [y], [heading]
    t = 0.0
    for leg in legs:
        n = max(int(math.ceil(leg.duration_s / step_s)), 1)
        dt = leg.duration_s / n
        for _ in range(n):
            if leg.turn_rate == 0.0:
                x += speed * dt * math.cos(heading)
                y += speed * dt * math.sin(heading)
            else:  # exact arc: radius V / omega
                r = speed / leg.turn_rate
                new = heading + leg.turn_rate * dt
                x += r * (math.sin(new) - math.sin(heading))
                y -= r * (math.cos(new) - math.cos(heading))
                heading = new
            t += dt
            times.append(t)
            xs.append(x)
            ys.append(y)
            hs.append(heading)
    tt = np.asarray(times)
    z, gamma = level_profile(float(state[2]), level, speed, tt)
    return Reference(tt + t0, np.column_stack([xs, ys, z, gamma, hs]))


def holding_pattern(state: np.ndarray, speed: float, radius: float, *, right: bool, straight_s: float, level: float,
                    t0: float, duration_s: float, step_s: float) -> Reference:
    """A hold: ``straight_s`` on along the heading, then orbits of ``radius`` (right or left turns) at ``level``,
    until ``duration_s`` after ``t0``."""
    rate = (-1.0 if right else 1.0) * speed / radius  # heading counted anticlockwise from x: right turns decrease it
    legs = [Leg(straight_s)] if straight_s > 0 else []
    legs.append(Leg(max(duration_s - straight_s, step_s), rate))
    return fly_legs(state, speed, legs, level, t0, step_s)


def vector(state: np.ndarray, speed: float, radius: float, heading: float, *, level: float, t0: float,
           duration_s: float, step_s: float) -> Reference:
    """A vector: turn the short way (at ``radius``) onto ``heading`` and fly it at ``level`` until ``duration_s``
    after ``t0``."""
    change = (heading - float(state[4]) + math.pi) % (2.0 * math.pi) - math.pi
    rate = math.copysign(speed / radius, change) if change != 0.0 else 0.0
    turn_s = abs(change) / abs(rate) if rate else 0.0
    legs = [Leg(turn_s, rate)] if turn_s > 0 else []
    legs.append(Leg(max(duration_s - turn_s, step_s)))
    return fly_legs(state, speed, legs, level, t0, step_s)
