"""The traffic a plan of some aircraft is made among: paths that stay as they are (a replan of what changed).

A replan of what changed (:meth:`mal_planner.pipeline.among.plan_among`) replans a few aircraft and leaves the
others on what they fly: their paths are :class:`FixedPath` objects, kept clear of and verified against, never
changed. The aircraft replanned start from their own current plans, given the same way.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mal_planner.scenario.model import Aircraft


@dataclass(frozen=True, eq=False)
class FixedPath:
    """One aircraft's path from a plan's start: its current plan, hold or vector (planner units: nm, s, rad)."""

    aircraft: Aircraft
    """The aircraft as the service knows it (its speed, wake category, dynamics)."""
    t: np.ndarray
    """(n,) times in s from the plan's start, increasing."""
    states: np.ndarray
    """(n, 5) x, y, z, flight-path angle, heading (and the airspeed: the aircraft's model's states); the path
    between samples is their straight chord (as flown)."""
    landing_time: float | None
    """When it lands on this path (s from the plan's start); None: it does not land on it (a hold, a vector)."""

    def __post_init__(self) -> None:
        width = self.aircraft.dynamics.n_states
        if len(self.t) < 2 or np.any(np.diff(self.t) <= 0) or self.states.shape != (len(self.t), width):
            raise ValueError(f"{self.callsign}: a fixed path needs at least two states at increasing times")

    @property
    def callsign(self) -> str:
        return self.aircraft.callsign

    @property
    def positions(self) -> np.ndarray:
        return self.states[:, :3]

    @classmethod
    def cut(cls, aircraft: Aircraft, t: np.ndarray, states: np.ndarray, start: float, lands: bool) -> FixedPath | None:
        """The part of a path (times ``t`` on any clock) from ``start`` on, with times from ``start``: None when
        it ends by then. ``lands``: the path ends on the runway (a plan), else it does not land (a fallback)."""
        t, states = np.asarray(t, float), np.asarray(states, float)[:, :aircraft.dynamics.n_states]
        if t[-1] <= start:
            return None
        after = t > start
        first = np.array([np.interp(start, t, column) for column in states.T])
        times = np.concatenate([[start], t[after]]) - start
        path = np.vstack([first, states[after]])
        return cls(aircraft, times, path, float(times[-1]) if lands else None)


@dataclass(frozen=True, eq=False)
class Traffic:
    """What a plan of some aircraft is made among."""

    replanned: tuple[FixedPath, ...]
    """The current plans of the aircraft to replan (their initial guesses and landing times)."""
    fixed: tuple[FixedPath, ...]
    """The paths of the others, which stay as they are."""
    joining: tuple[str, ...] = ()
    """Aircraft that fly no plan, planned to land after everyone in ``fixed`` (no current plan to start from)."""

    @property
    def callsigns(self) -> tuple[str, ...]:
        return (*(p.callsign for p in self.replanned), *self.joining)
