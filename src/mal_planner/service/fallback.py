"""An instruction for an aircraft without a valid plan: a hold, checked against everyone's instructions first.

A new aircraft, one left out of a plan or one whose plan was withdrawn still needs an instruction: as arrival
managers and controllers do, it holds until it is planned. The hold is a racetrack's limit, an orbit around a
fix on the ground of :data:`HOLD_RADII` of the aircraft's own turn radii at its largest ground speed (airspeed plus
the wind): at 30 deg of bank the bank of the orbit is at most 21 deg, inside ICAO's 25 deg for holds (a terminal
area's 208 kt aircraft in a 20 kt wind: 1.98 nm). Drawn for the scenario's tightest turn instead, a fast aircraft
could not fly it and strayed up to 3 nm from where the service predicted it. It is entered from where the aircraft
is: at once or after a straight leg, right or left turns, at its level or (with a vertical minimum) stacked a
vertical minimum above or below, tighter where the standard one does not fit. The first candidate that keeps the
tracking margin (:attr:`FallbackRules.margin`) from everyone's predicted paths over the look-ahead, stays inside the
airspace and out of the no-fly zones over a whole orbit, is given; when none does, the least bad: out of the no-fly
zones first, then clear of a predicted loss of separation, then inside the airspace's box, then the most separation
(the safety net then watches it).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from mal_planner.scales import Scales, level_turn_radius
from mal_planner.scenario import Scenario
from mal_planner.service.conflicts import Minima, Picture, closest_to_others
from mal_planner.service.manoeuvres import holding_pattern
from mal_planner.service.tracks import Track
from mal_planner.trajectory import Reference

HOLD_RADII = 1.5
"""Hold and vector turn radius in the aircraft's turn radii at the bank limit (the bank of a turn in still air:
atan(tan(limit) / 1.5)); a hold's at its largest ground speed, airspeed plus wind."""
LOOK_AHEAD_TURN_TIMES = 8.0
"""How far ahead instructions are checked and conflicts predicted (a terminal area 110 s, the thesis 60 s: an STCA
looks about two minutes ahead)."""
STEP_TURN_TIMES = 0.25
"""The prediction's time step (a terminal area 3.4 s)."""
TIGHTER_HOLD_RADII = (1.25, 1.1)
"""Tighter holds tried where the standard one does not fit (banks at the largest ground speed of 25 and 28 deg at a
30 deg limit)."""
HOLD_TURN_TIMES = 100.0
"""A hold is drawn this long (a terminal area 23 min) and renewed before it ends."""
ENTRY_LEGS_TURN_TIMES = (0.0, 2.0, 4.0, 8.0)
"""Straight legs tried before the orbit: the hold's fix at, or ahead of, the aircraft."""


@dataclass(frozen=True)
class Fallback:
    """A service instruction (``kind`` "hold" or "vector") flown like a plan."""

    callsign: str
    kind: str
    reference: Reference
    issued_at: float
    reason: str
    clearance: float
    """The smallest predicted separation from the others when it was given, in minima (inf: alone)."""


@dataclass(frozen=True)
class FallbackRules:
    """The numbers of the fallback, from the scenario's scales and the service's deviation threshold."""

    scales: Scales
    minima: Minima
    margin: float
    """Separation the fallback keeps beyond the minimum, in minima: twice the deviation threshold, as plans keep."""
    edge_nm: float
    """How far inside the airspace the fallback stays: the deviation threshold."""
    radius_per_speed2: float
    """Turn radius at the bank limit over the airspeed squared (1 / (g tan(bank limit))), the scenario's largest: a
    radar track gives an aircraft's speed, not its bank limit."""
    wind: tuple[float, float] = (0.0, 0.0)
    """The wind the service knows (nm/s): holds and vectors are drawn as flown in it."""

    @classmethod
    def of(cls, scenario: Scenario, deviation_nm: float) -> FallbackRules:
        minima = Minima.of(scenario)
        k = max(level_turn_radius(a) / a.speed**2 for a in scenario.aircraft)
        return cls(Scales.of(scenario), minima, 2.0 * deviation_nm / minima.horizontal_nm, deviation_nm, k,
                   (float(scenario.wind[0]), float(scenario.wind[1])))

    @property
    def step_s(self) -> float:
        return self.scales.seconds(STEP_TURN_TIMES)

    def look_ahead(self, now: float) -> np.ndarray:
        return now + np.arange(0.0, self.scales.seconds(LOOK_AHEAD_TURN_TIMES) + 1e-9, self.step_s)

    def turn_radius(self, speed: float) -> float:
        """A vector's turn radius (through the air mass) at airspeed ``speed``."""
        return HOLD_RADII * self.radius_per_speed2 * speed**2

    def hold_radius(self, speed: float, radii: float = HOLD_RADII) -> float:
        """A hold's radius (on the ground) at airspeed ``speed``: ``radii`` turn radii at the largest ground speed
        (by default the bank of a vector's turn)."""
        return radii * self.radius_per_speed2 * (speed + math.hypot(*self.wind)) ** 2


def fits_airspace(scenario: Scenario, points: np.ndarray, edge_nm: float) -> bool:
    """The path through ``points`` inside the airspace by ``edge_nm`` and clear of every no-fly zone (walls too:
    each chord is tested) by it."""
    lo, hi = scenario.airspace[:, 0] + edge_nm, scenario.airspace[:, 1] - edge_nm
    if np.any(points < lo) or np.any(points > hi):
        return False
    return not any(np.any(ob.inflated(edge_nm).segment_hits(points[:-1], points[1:])) for ob in scenario.obstacles)


def _levels(scenario: Scenario, z: float, rules: FallbackRules) -> Iterator[float]:
    """The aircraft's level (inside the airspace), then one vertical minimum above and below where there is one."""
    lo, hi = scenario.airspace[2, 0] + rules.edge_nm, scenario.airspace[2, 1] - rules.edge_nm
    own = min(max(z, lo), hi)
    yield own
    v = rules.minima.vertical_nm
    if v is not None:
        for level in (own + v * (1.0 + rules.margin), own - v * (1.0 + rules.margin)):
            if lo <= level <= hi:
                yield level


def hold_candidates(track: Track, scenario: Scenario, rules: FallbackRules, now: float) -> Iterator[Reference]:
    """The holds to try, in order of preference (the least change first): at the aircraft's level before another,
    the fix at the aircraft before one ahead, the standard radius before a tighter one (:data:`TIGHTER_HOLD_RADII`,
    for a corner of the airspace), right turns before left."""
    for level in _levels(scenario, float(track.state[2]), rules):
        for legs in ENTRY_LEGS_TURN_TIMES:
            for radii in (HOLD_RADII, *TIGHTER_HOLD_RADII):
                for right in (True, False):
                    yield holding_pattern(track.state, track.speed, rules.hold_radius(track.speed, radii),
                                          right=right, straight_s=rules.scales.seconds(legs), level=level, t0=now,
                                          duration_s=rules.scales.seconds(HOLD_TURN_TIMES), step_s=rules.step_s,
                                          wind=rules.wind)


def choose_hold(track: Track, others: Picture, scenario: Scenario, rules: FallbackRules, now: float, reason: str
                ) -> Fallback:
    """The hold for ``track``'s aircraft (see the module docstring); ``others``: everyone else's predicted paths on
    :meth:`FallbackRules.look_ahead` times. The first candidate inside the airspace (by its edge margin) and clear of
    the others by the margin; else the least bad (:func:`_badness`)."""
    orbit_s = 2.0 * math.pi * rules.hold_radius(track.speed) / (track.speed - math.hypot(*rules.wind))
    times = np.arange(now, now + rules.scales.seconds(max(ENTRY_LEGS_TURN_TIMES)) + orbit_s, rules.step_s)
    scored = []
    for ref in hold_candidates(track, scenario, rules, now):
        points = ref.positions(times)
        clearance, _ = closest_to_others(ref.positions(others.times), others, rules.minima, track.callsign)
        if clearance >= 1.0 + rules.margin and fits_airspace(scenario, points, rules.edge_nm):
            return Fallback(track.callsign, "hold", ref, now, reason, clearance)
        scored.append((_badness(scenario, points, clearance, rules.edge_nm), clearance, ref))
    _, clearance, ref = min(scored, key=lambda s: s[0])
    return Fallback(track.callsign, "hold", ref, now, reason, clearance)


def _badness(scenario: Scenario, points: np.ndarray, clearance: float, edge_nm: float
             ) -> tuple[int, bool, float, bool, float]:
    """How bad a hold through ``points`` is when none is good: entering a no-fly zone (a restricted area may be a
    mountain or a military range), then a predicted loss of separation, then how far it leaves the airspace's box (a
    line on a chart), then not keeping the edge margin, then the least separation."""
    hits, outside = _infringement(scenario, points)
    return hits, clearance < 1.0, outside, not fits_airspace(scenario, points, edge_nm), -clearance


def _infringement(scenario: Scenario, points: np.ndarray) -> tuple[int, float]:
    """How much the path through ``points`` infringes: the chords in a no-fly zone (none: it may touch the margin
    only), then how far it goes outside the airspace's box (0: inside). A no-fly zone is never entered to stay
    inside the box: a box's edge is a line on a chart, a restricted area may be a mountain or a military range."""
    lo, hi = scenario.airspace[:, 0], scenario.airspace[:, 1]
    hits = sum(int(np.count_nonzero(ob.segment_hits(points[:-1], points[1:]))) for ob in scenario.obstacles)
    return hits, float(max(np.max(lo - points), np.max(points - hi), 0.0))
