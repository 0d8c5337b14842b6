"""The scenario's own scales: every tolerance, margin, mesh density and screening distance derives from them.

A plan in the thesis's 6-nm box and one in a 45-nm terminal area are the same problem at different sizes:
what matters is how many turn radii an aircraft flies and how many turn times a phase lasts. Two
characteristic values of a scenario fix that:

* the **length** ``L``: the smallest level-turn radius at the bank limit, R = V^2 / (g min(tan mu_max, n_h max))
  (thesis: V = 0.04 nm/s, 45 deg: 0.302 nm; a terminal area at 150 kt and 30 deg: 0.58 nm);
* the **time** ``T = L / V`` of that aircraft: the time it takes to turn one radian (thesis: 7.55 s;
  terminal area: 13.7 s).

Both come from the airspeed V, also in a wind (``wind:``): turns are flown through the air mass, which only
drifts them, so the radius and the rate of a turn do not depend on the wind.

The NLP is scaled by them (positions in L, times in T), and the numbers that were tuned in the thesis's
units are multiples of them: the table in the README ("Real terminal-area scale") lists each constant, its
former value and its rule. :attr:`Scales.accuracy_nm` is the path accuracy the planner works to: the
verification's largest deviation between the published and the flown path, and the unit of the optimizer's
safety margins.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from mal_planner.scenario import Aircraft, Scenario

ACCURACY_PER_RADIUS = 1.0 / 60.0
"""Path accuracy per turn radius: 0.005 nm (about 9 m) in the thesis, whose tolerances were tuned there."""


def level_turn_radius(aircraft: Aircraft) -> float:
    """Radius (nm) of a level turn at the bank limit (capped by the horizontal load-factor limit)."""
    lim = aircraft.limits
    n_h = min(math.tan(lim.bank_angle_max) * max(min(1.0, lim.n_v[1]), 1e-9), lim.n_h[1], -lim.n_h[0])
    return aircraft.speed**2 / (aircraft.dynamics.gravity * n_h)


@dataclass(frozen=True)
class Scales:
    """Characteristic length and time of one scenario (see the module docstring)."""

    length_nm: float
    """L: the smallest level-turn radius at the bank limit of any aircraft."""
    time_s: float
    """T: L / V of that aircraft, the time to turn one radian."""
    separation_nm: float

    @classmethod
    def of(cls, scenario: Scenario) -> Scales:
        radius, speed = min((level_turn_radius(ac), ac.speed) for ac in scenario.aircraft)
        return cls(radius, radius / speed, scenario.separation_nm)

    @property
    def accuracy_nm(self) -> float:
        """The path accuracy the planner works to: L / 60 (thesis: 0.005 nm)."""
        return self.length_nm * ACCURACY_PER_RADIUS

    def lengths(self, radii: float) -> float:
        """``radii`` turn radii in nm."""
        return radii * self.length_nm

    def seconds(self, turn_times: float) -> float:
        """``turn_times`` turn times in s."""
        return turn_times * self.time_s
