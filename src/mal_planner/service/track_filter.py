"""The service's track filter: radar positions smoothed against the plans being flown.

Raw radar positions carry their noise into everything the service decides: a replan started from a track 30 m off
(sigma) starts its aircraft up to 100 m from where it is, and near a wall's hole that is the difference between
the hole and the wall. Surveillance processing smooths tracks before controllers (and planners) see them. An
aircraft flying a plan departs from it slowly (gusts, along-track drift), so the filter smooths the *deviation*
from the plan, not the position: an exponential filter with time constant tau, whose estimate is the plan's position
plus the smoothed deviation. Each update weighs the new deviation by a = 1 - exp(-dt / tau), dt the time since the
aircraft's previous radar track (a radar's period, or whatever gap the tracks have). White noise of sigma at a
steady period leaves sigma sqrt(a / (2 - a)) in the estimate; a change of the true deviation shows after about tau.
"""

from __future__ import annotations

import math

import numpy as np

from mal_planner.trajectory import Reference


def filter_gain(dt_s: float, time_constant_s: float) -> float:
    """The weight of a new deviation ``dt_s`` after the previous track (1: no smoothing)."""
    return 1.0 - math.exp(-dt_s / time_constant_s) if time_constant_s > 0 and dt_s > 0 else 1.0


def noise_factor(period_s: float, time_constant_s: float) -> float:
    """The estimate's noise over the radar's, for tracks every ``period_s`` (steady state on white noise)."""
    a = filter_gain(period_s, time_constant_s)
    return math.sqrt(a / (2.0 - a))


class DeviationFilter:
    """Per aircraft, the smoothed position deviation (nm) from the plan it flies."""

    def __init__(self, time_constant_s: float) -> None:
        self.time_constant_s = time_constant_s
        self.deviation: dict[str, np.ndarray] = {}

    def update(self, callsign: str, measured: np.ndarray, plan: Reference, t: float, dt_s: float) -> np.ndarray:
        """Take one radar position at ``t``, ``dt_s`` after the aircraft's previous track; return the position
        estimate (the plan's plus the smoothed deviation)."""
        expected = plan.position(t)
        dev = np.asarray(measured, float)[:3] - expected
        old = self.deviation.get(callsign)
        gain = filter_gain(dt_s, self.time_constant_s)
        self.deviation[callsign] = new = dev if old is None else old + gain * (dev - old)
        return expected + new

    def estimate(self, callsign: str, plan: Reference, t: float) -> np.ndarray | None:
        """The position estimate at ``t`` without a new measurement (None before the first)."""
        dev = self.deviation.get(callsign)
        return None if dev is None else plan.position(t) + dev

    def replanned(self, callsign: str, old: Reference | None, new: Reference, t: float) -> None:
        """The aircraft got a new plan at ``t``: the same estimate, now as a deviation from the new plan."""
        dev = self.deviation.get(callsign)
        if old is None or dev is None:  # a plan made from its track (the first, or a new aircraft's): on it
            self.deviation[callsign] = np.zeros(3)
            return
        self.deviation[callsign] = old.position(t) + dev - new.position(t)

    def forget(self, callsign: str) -> None:
        self.deviation.pop(callsign, None)
