"""The runway frame: the initializer works in it, so that a turned or shifted copy of a scenario gets the same
initial guess.

The scenario format has axis-aligned airspaces, obstacles and gate planes, so the worlds that can be copies of
each other differ by quarter turns about the vertical and by shifts. :class:`RunwayFrame` undoes both: it
turns the world by the multiple of 90 deg that brings the runway heading nearest to -90 deg (the thesis's
runway, landing towards -y) and moves the runway threshold to the origin. Quarter turns are signed axis
permutations, applied exactly (no sine or cosine), so two copies meet in the same numbers up to the
round-off of the shift. The wind turns with the world (:meth:`RunwayFrame.vector`); what comes back to the world
are positions and times only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from mal_planner.obstacles import Gate, Superquadric
from mal_planner.scenario import Aircraft, Scenario

CANONICAL_HEADING = -0.5 * math.pi
"""The runway heading of the frame (rad): the thesis's, landing towards -y."""


@dataclass(frozen=True)
class RunwayFrame:
    """World -> frame: turn by ``quarter_turns`` x 90 deg counter-clockwise about z, after moving ``origin``
    (the runway threshold) to 0."""

    quarter_turns: int
    origin: tuple[float, float, float]

    @classmethod
    def of(cls, scenario: Scenario) -> RunwayFrame:
        heading = float(scenario.runway_state[4])
        turns = -round((heading - CANONICAL_HEADING) / (0.5 * math.pi)) % 4
        return cls(int(turns), tuple(float(v) for v in scenario.runway_state[:3]))

    # --------------------------------------------------------------- the turn as a signed permutation
    def _axes(self) -> tuple[tuple[int, float], tuple[int, float]]:
        """For new x and new y: (the old axis it comes from, the sign)."""
        return {0: ((0, 1.0), (1, 1.0)), 1: ((1, -1.0), (0, 1.0)), 2: ((0, -1.0), (1, -1.0)),
                3: ((1, 1.0), (0, -1.0))}[self.quarter_turns]

    def _source(self, axis: int) -> tuple[int, float]:
        return (2, 1.0) if axis == 2 else self._axes()[axis]

    def points(self, points: np.ndarray) -> np.ndarray:
        """World points (..., 3) in the frame."""
        p = np.asarray(points, float) - np.asarray(self.origin)
        return np.stack([s * p[..., a] for a, s in (self._source(k) for k in range(3))], axis=-1)

    def to_world(self, points: np.ndarray) -> np.ndarray:
        """Frame points (..., 3) in the world."""
        p = np.asarray(points, float)
        out = np.empty_like(p)
        for k in range(3):
            a, s = self._source(k)
            out[..., a] = s * p[..., k]
        return out + np.asarray(self.origin)

    def heading(self, heading: float) -> float:
        """A world heading in the frame, in (-pi, pi]."""
        return math.remainder(float(heading) + self.quarter_turns * 0.5 * math.pi, 2.0 * math.pi)

    def _box(self, box: np.ndarray) -> np.ndarray:
        """A (3, 2) [min, max] box in the frame."""
        shifted = np.asarray(box, float) - np.asarray(self.origin)[:, None]
        out = np.empty((3, 2))
        for k in range(3):
            a, s = self._source(k)
            out[k] = sorted(s * shifted[a])
        return out

    def _superquadric(self, ob: Superquadric) -> Superquadric:
        axes = [self._source(k)[0] for k in range(3)]
        return Superquadric(ob.name, tuple(float(v) for v in self.points(np.asarray(ob.center))),
                            tuple(float(ob.semi_axes[a]) for a in axes), ob.p)

    def _gate(self, gate: Gate) -> Gate:
        new_axis = next(k for k in range(3) if self._source(k)[0] == gate.axis)
        sign = self._source(new_axis)[1]
        others = [k for k in range(3) if k != new_axis]
        old_bounds = dict(zip(gate.other_axes, gate.bounds, strict=True))
        bounds = []
        for k in others:
            a, s = self._source(k)
            lo, hi = (np.asarray(old_bounds[a]) - self.origin[a]) * s
            bounds.append((float(min(lo, hi)), float(max(lo, hi))))
        return Gate(gate.name, new_axis, float(sign * (gate.position - self.origin[gate.axis])),
                    int(sign * gate.direction), (bounds[0], bounds[1]), gate.flight_path_angle,
                    self.heading(gate.heading))

    def vector(self, vector: tuple[float, float]) -> tuple[float, float]:
        """A horizontal world vector (e.g. the wind) in the frame (turned, not shifted)."""
        (ax, sx), (ay, sy) = self._axes()
        return float(sx * vector[ax]), float(sy * vector[ay])

    def _aircraft(self, ac: Aircraft) -> Aircraft:
        state = np.concatenate([self.points(ac.state0[:3]), [ac.state0[3], self.heading(ac.state0[4])]])
        if not ac.dynamics.has_wind:
            return replace(ac, state0=state)
        return replace(ac, state0=state, dynamics=ac.dynamics.with_wind(*self.vector(tuple(ac.dynamics.wind))))

    def scenario(self, scenario: Scenario) -> Scenario:
        """``scenario`` seen in the frame (its ``config`` still describes the world)."""
        runway = scenario.runway_state
        return replace(
            scenario,
            aircraft=tuple(self._aircraft(ac) for ac in scenario.aircraft),
            runway_state=np.concatenate([self.points(runway[:3]), [runway[3], self.heading(runway[4])]]),
            airspace=self._box(scenario.airspace),
            obstacles=tuple(self._superquadric(ob) for ob in scenario.obstacles),
            gates=tuple(self._gate(g) for g in scenario.gates),
            wind=self.vector(scenario.wind),
        )
