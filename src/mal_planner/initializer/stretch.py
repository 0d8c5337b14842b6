"""Step 3 of the landing sequencer (:mod:`.sequencer`): a path stretched to its scheduled landing time.

An aircraft whose direct path is too short for its scheduled time flies through a sequencing waypoint before its
approach route. Candidates are drawn on a lattice in batches and screened all at once (straight-line lengths,
the gates' sides, obstacles, the traffic); the survivors are planned, two legs each, until one lands within the
window of its scheduled time and keeps clear of the aircraft stretched before; else the closest is kept.
Every length that stands for a time is an air distance (:mod:`.timed_paths`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from mal_planner.dynamics import DynamicsModel
from mal_planner.initializer.approach import Approach
from mal_planner.initializer.base import PlanningFailed
from mal_planner.initializer.collision import CollisionChecker
from mal_planner.initializer.legs import LegPlanner
from mal_planner.initializer.smoothing import remove_repeats
from mal_planner.initializer.timed_paths import air_path_length, timed_path
from mal_planner.scales import Scales
from mal_planner.scenario import Aircraft, Scenario
from mal_planner.sequencing.timing import dubins_path_length, length_for_time

log = logging.getLogger("mal_planner.initializer")

WAYPOINT_BATCH = 256
"""Waypoint candidates drawn and screened at once (the screening is vectorised; planning them is not)."""


class StretchOptions(Protocol):
    """The options of :class:`~mal_planner.initializer.sequencer.Sequencer` that stretching reads (documented
    there), in turn radii and turn times."""

    lattice_radii: float
    max_waypoint_draws: int
    max_waypoint_plans: int
    landing_margin_turn_times: float
    window_turn_times: float
    guess_buffer_radii: float


@dataclass(frozen=True)
class Traffic:
    """The timed paths of the aircraft stretched before on one time grid (every half turn time), NaN where an
    aircraft has landed: a candidate's clearance is then one vectorised distance."""

    grid: np.ndarray
    positions: np.ndarray
    """(aircraft, grid, 3)."""
    landing_time: float
    """The scheduled landing time of the aircraft being stretched: its candidates are flown to land then."""

    @classmethod
    def on_grid(cls, traffic: Sequence[tuple[np.ndarray, np.ndarray]], landing_time: float,
                turn_time: float) -> Traffic:
        grid = np.arange(0.0, landing_time + turn_time, 0.5 * turn_time)
        others = np.full((len(traffic), len(grid), 3), np.nan)
        for k, (t_o, pos_o) in enumerate(traffic):
            flying = grid <= t_o[-1]
            others[k, flying] = np.column_stack([np.interp(grid[flying], t_o, pos_o[:, c]) for c in range(3)])
        return cls(grid, others, landing_time)

    def __len__(self) -> int:
        return len(self.positions)

    def clearance(self, path: np.ndarray, dynamics: DynamicsModel) -> float:
        """The closest approach (nm) of ``path``, flown to land at :attr:`landing_time`, to the traffic."""
        if not len(self):
            return math.inf
        times = timed_path(path, dynamics)
        times = times * (self.landing_time / times[-1]) if times[-1] > 0 else times
        mine = np.column_stack([np.interp(self.grid, times, path[:, c]) for c in range(3)])
        gaps = np.linalg.norm(self.positions - mine[None], axis=2)
        return float(np.nanmin(gaps)) if np.isfinite(gaps).any() else math.inf

    def straight_clearances(self, start: np.ndarray, wps: np.ndarray, goal: np.ndarray, route: np.ndarray,
                            route_cum: np.ndarray) -> np.ndarray:
        """(C,) the closest approach of each candidate's straight legs start -> waypoint -> goal -> route."""
        near = _proxy_positions(start, wps, goal, route, route_cum, self.landing_time, self.grid)
        gaps = np.linalg.norm(self.positions[None] - near[:, None], axis=3)
        return np.nanmin(np.where(np.isfinite(gaps), gaps, np.inf), axis=(1, 2))


@dataclass(frozen=True)
class LengthWindow:
    """Air distances (nm) of a polyline that fly the scheduled time: ``target`` (the scheduled time at the
    airspeed less ``turns``, what the turns add to the polyline's length) within ``lo``..``hi``. A direct path
    down to ``slack`` below ``lo`` needs no detour (the landing margin the schedule added)."""

    target: float
    lo: float
    hi: float
    slack: float
    turns: float

    @classmethod
    def of(cls, scenario: Scenario, ac: Aircraft, scheduled: float, scales: Scales,
           options: StretchOptions) -> LengthWindow:
        v = length_for_time(scenario, ac, scheduled) / scheduled if scheduled > 0.0 else ac.speed  # mean airspeed
        dubins, straight = dubins_path_length(scenario, ac)
        turns = max(dubins - straight, 0.0)
        window, margin = scales.seconds(options.window_turn_times), scales.seconds(options.landing_margin_turn_times)
        target = scheduled * v - turns
        return cls(target, target - window * v, target + window * v, margin * v, turns)

    def miss(self, length: float) -> float:
        """How far (nm) ``length`` is outside the window (0 inside)."""
        return max(self.lo - length, length - self.hi, 0.0)


@dataclass(frozen=True)
class Stretcher:
    """Stretches the paths of one plan's aircraft: ``legs`` plans them in ``checker``'s airspace; ``options`` (the
    sequencer's) are in turn radii and turn times of ``scales``."""

    legs: LegPlanner
    options: StretchOptions
    scenario: Scenario
    checker: CollisionChecker
    scales: Scales

    def stretch(self, ac: Aircraft, route: Approach, direct_path: np.ndarray, scheduled: float,
                rng: np.random.Generator, traffic: Sequence[tuple[np.ndarray, np.ndarray]] = (), force: bool = False
                ) -> tuple[np.ndarray, np.ndarray | None]:
        """The direct path if it suits ``scheduled``, else a path through a waypoint (before the route) that
        does. Waypoints that reach the route against its direction (an aircraft would have to turn back onto
        it) are taken only in the second half of the draws, as are those breaking the thesis's rule.

        Paths are also kept apart from the ``traffic`` (the timed paths of the aircraft stretched before): a
        path that comes within the separation plus ``guess_buffer_radii`` of one of them is taken only when no
        clear one is found, the clearest first. The thesis's sequencer leaves separation to the optimizer; at
        a terminal area's size, a detour that crosses the stream (an aircraft held back 4 minutes flew across
        the path of one converging on the same gate) left no feasible plan for the optimizer. ``force``: look
        for a waypoint even where the direct path would do (it did not clear the traffic).
        """
        dyn = ac.dynamics
        need = self.scenario.separation_nm + self.scales.lengths(self.options.guess_buffer_radii)
        others = Traffic.on_grid(traffic, scheduled, self.scales.time_s)
        window = LengthWindow.of(self.scenario, ac, scheduled, self.scales, self.options)
        direct_len = air_path_length(dyn, direct_path)  # lengths that stand for times are air distances
        direct_clear = others.clearance(direct_path, dyn)
        if direct_len >= window.lo - window.slack and not (force and direct_clear < need):  # no detour needed
            if direct_len > window.hi:
                log.warning("%s: the direct path needs %.1f s, more than the scheduled %.1f s; kept",
                            ac.callsign, (direct_len + window.turns) / ac.speed, scheduled)
            if direct_clear < need:
                log.info("%s: the direct path comes %.2f nm close to an earlier aircraft's", ac.callsign,
                         direct_clear)
            return direct_path, None
        search = WaypointSearch(self, ac, route, rng, window, others, need, direct_len)
        found = search.run()
        if found is None:
            log.warning("%s: no waypoint found for a %.1f s landing (%d tried); the direct path is kept",
                        ac.callsign, scheduled, len(search.lattice.tried))
            return direct_path, None
        return found


@dataclass
class WaypointLattice:
    """Waypoint candidates on a lattice of ``res`` nm strictly inside ``airspace``; each point is tried once."""

    airspace: np.ndarray
    res: float
    lo_i: np.ndarray = field(init=False)
    hi_i: np.ndarray = field(init=False)
    tried: set[tuple[int, int, int]] = field(default_factory=set)

    def __post_init__(self) -> None:
        self.lo_i = np.ceil((self.airspace[:, 0] + 1e-12) / self.res).astype(np.int64) + 1
        self.hi_i = np.floor((self.airspace[:, 1] - 1e-12) / self.res).astype(np.int64) - 1

    def draw(self, rng: np.random.Generator, first: int, start: np.ndarray, goal: np.ndarray,
             length: float) -> np.ndarray:
        """The waypoints (n, 3) of the batch of draws ``first``, ``first`` + 1, ... not tried before, in the order
        drawn (see :func:`_waypoint_keys`)."""
        keys = _waypoint_keys(rng, WAYPOINT_BATCH, first, start, goal, length, self.airspace, self.res, self.lo_i,
                              self.hi_i)
        keys, index = np.unique(keys, axis=0, return_index=True)
        keys = keys[np.argsort(index)]  # in the order drawn
        fresh = np.array([tuple(k) not in self.tried for k in keys.tolist()], bool)
        self.tried.update(tuple(k) for k in keys.tolist())
        return keys[fresh].astype(float) * self.res


@dataclass(frozen=True)
class _Candidate:
    """A planned path through ``wp`` (legs ``leg1`` and ``leg2``) that missed the window or the traffic."""

    rank: tuple[float, float]
    """(miss, -clearance up to the need): the smallest is the closest to what was wanted."""
    path: np.ndarray
    wp: np.ndarray
    leg1: np.ndarray
    leg2: np.ndarray

    @property
    def miss(self) -> float:
        return self.rank[0]


class WaypointSearch:
    """One aircraft's search for a sequencing waypoint (:meth:`Stretcher.stretch`); :meth:`run` once."""

    def __init__(self, stretcher: Stretcher, ac: Aircraft, route: Approach, rng: np.random.Generator,
                 window: LengthWindow, traffic: Traffic, need: float, direct_len: float) -> None:
        self.legs, self.options, self.checker = stretcher.legs, stretcher.options, stretcher.checker
        self.ac, self.route, self.rng, self.window, self.traffic = ac, route, rng, window, traffic
        self.need, self.direct_len = need, direct_len
        self.start, self.goal = ac.position, route.first
        self.tail = air_path_length(ac.dynamics, route.points)
        self.onto = (route.points[1] - self.goal) if len(route.points) > 1 else np.zeros(3)
        res = stretcher.scales.lengths(self.options.lattice_radii)
        self.lattice = WaypointLattice(stretcher.scenario.airspace, res)
        self.gates = stretcher.scenario.gates
        self.sides = [np.sign(g.signed_distance(self.start)) for g in self.gates]
        self.route_cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(route.points, axis=0), axis=1))])
        self.planned = 0
        self.best: _Candidate | None = None

    def run(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(path, waypoint): the first in the window and clear of the traffic, else the closest; None if no
        candidate could be planned."""
        plans, draws = self.options.max_waypoint_plans, self.options.max_waypoint_draws
        for first in range(0, draws, WAYPOINT_BATCH):
            if self.planned >= plans:
                break
            self.legs.deadline.check()
            strict = self.planned < plans // 2 and first < draws // 2
            wps = self.lattice.draw(self.rng, first, self.start, self.goal, self.window.target - self.tail)
            for wp, d2_wp in zip(*self._screened(wps, strict), strict=True):
                if self._enough():
                    return self._closest()
                self.legs.deadline.check()
                found = self._plan_through(wp, d2_wp)
                if found is not None:
                    return found
        return self._closest()

    def _enough(self) -> bool:
        """No more planner runs: the budget is spent, or a quarter of it is and a candidate is in the window, only
        not clear of the traffic (the optimizer separates them)."""
        plans = self.options.max_waypoint_plans
        return self.planned >= plans or (self.best is not None and self.best.miss == 0.0 and self.planned >= plans // 4)

    def _screened(self, wps: np.ndarray, strict: bool) -> tuple[np.ndarray, np.ndarray]:
        """The candidates worth planning and their air distance to the end of the route in a straight line.
        ``strict``: the first leg longer than the rest (the thesis's rule), the route reached along its direction
        and the straight legs clear of the traffic."""
        dyn = self.ac.dynamics
        d1 = dyn.air_distance(wps - self.start)
        d2 = dyn.air_distance(self.goal - wps) + self.tail
        ok = (d1 + d2 <= self.window.hi) & (d1 + d2 >= self.direct_len - 1e-9)  # the straight-line bounds
        if strict:
            ok &= (d1 > d2) & ((self.goal - wps) @ self.onto >= 0.0)
        for g, side in zip(self.gates, self.sides, strict=True):
            ok &= np.sign(g.signed_distance(wps)) == side
        ok[ok] = self.checker.points_free(wps[ok])
        if strict and len(self.traffic) and ok.any():  # the straight legs already come too close: not worth planning
            ok[ok] = self.traffic.straight_clearances(self.start, wps[ok], self.goal, self.route.points,
                                                      self.route_cum) >= self.need
        return wps[ok], d2[ok]

    def _plan_through(self, wp: np.ndarray, d2_wp: float) -> tuple[np.ndarray, np.ndarray] | None:
        """The path through ``wp`` (polished) if it lands in the window clear of the traffic; else None, and the
        candidate is kept if it is the closest yet."""
        dyn, checker, rng = self.ac.dynamics, self.checker, self.rng
        try:
            self.planned += 1
            leg1 = self.legs.quick(checker, self.start, wp, rng)
            leg1_len = air_path_length(dyn, leg1)
            too_long = leg1_len + d2_wp - self.window.hi  # a lower bound of how far past the window it lands
            if too_long > 0.0 and self.best is not None and too_long >= self.best.miss:
                return None
            self.planned += 1
            leg2 = self.legs.quick(checker, wp, self.goal, rng)
            joined = self.legs.join(checker, leg2, self.route, rng)
        except PlanningFailed:
            return None
        total = leg1_len + air_path_length(dyn, joined)
        path = remove_repeats(np.vstack([leg1, joined]))
        miss = self.window.miss(total)
        clear = self.traffic.clearance(path, dyn) if miss == 0.0 else 0.0
        if miss == 0.0 and clear >= self.need:
            log.debug("%s: waypoint after %d draws, %d planned", self.ac.callsign, len(self.lattice.tried),
                      self.planned)
            return self._polished(leg1, leg2, path), wp
        candidate = _Candidate((miss, -min(clear, self.need)), path, wp, leg1, leg2)
        if self.best is None or candidate.rank < self.best.rank:
            self.best = candidate
        return None

    def _closest(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The best candidate kept (polished when it is in the window), with a log line on what it misses."""
        best = self.best
        if best is None:
            return None
        miss, clear = best.miss, -best.rank[1]
        path = self._polished(best.leg1, best.leg2, best.path) if miss == 0.0 else best.path
        if miss > 0.0:
            log.warning("%s: no waypoint met the scheduled landing time within %d planner runs; using the "
                        "closest (%.1f s off)", self.ac.callsign, self.planned, miss / self.ac.speed)
        else:
            log.info("%s: no waypoint kept %.2f nm from the earlier aircraft within %d planner runs; using the "
                     "clearest (%.2f nm)", self.ac.callsign, self.need, self.planned, clear)
        return path, best.wp

    def _polished(self, leg1: np.ndarray, leg2: np.ndarray, path: np.ndarray) -> np.ndarray:
        """The two legs of a kept candidate smoothed (the route after them is kept as it is); the candidate as it
        was if smoothing takes it out of the window (of air distances, see the module docstring)."""
        legs, checker, rng = self.legs, self.checker, self.rng
        smooth = remove_repeats(np.vstack([legs.polish(checker, leg1, rng),
                                           legs.join(checker, legs.polish(checker, leg2, rng), self.route, rng)]))
        return smooth if self.window.lo <= air_path_length(self.ac.dynamics, smooth) <= self.window.hi else path


def _waypoint_keys(rng: np.random.Generator, n: int, first: int, start: np.ndarray, goal: np.ndarray,
                   length: float, airspace: np.ndarray, res: float, lo_i: np.ndarray, hi_i: np.ndarray) -> np.ndarray:
    """``n`` lattice keys (n, 3) of candidate waypoints: three in four on the ellipse of points P with |P - start| +
    |goal - P| = ``length`` horizontally (where a two-leg path has that length; altitude between the ends'), the
    others, and those whose ellipse point leaves the airspace, anywhere in it."""
    draw = first + np.arange(n)
    keys = rng.integers(lo_i, hi_i + 1, size=(n, 3))
    s2, g2 = start[:2], goal[:2]
    half_focal = 0.5 * float(np.linalg.norm(g2 - s2))
    a = 0.5 * length
    if a > half_focal > 0.0:
        b = math.sqrt(a * a - half_focal * half_focal)
        u = (g2 - s2) / (2.0 * half_focal)
        w = np.array([-u[1], u[0]])
        theta = rng.uniform(0.0, 2.0 * np.pi, n)
        xy = 0.5 * (s2 + g2) + np.outer(a * np.cos(theta), u) + np.outer(b * np.sin(theta), w)
        z = rng.uniform(min(start[2], goal[2]), max(start[2], goal[2]), n)
        points = np.column_stack([xy, z])
        inside = np.all((points >= airspace[:, 0]) & (points <= airspace[:, 1]), axis=1) & (draw % 4 != 0)
        keys[inside] = np.clip(np.round(points[inside] / res), lo_i, hi_i).astype(np.int64)
    return keys


def _proxy_positions(start: np.ndarray, wps: np.ndarray, goal: np.ndarray, route: np.ndarray, route_cum: np.ndarray,
                     landing_time: float, grid: np.ndarray) -> np.ndarray:
    """(C, G, 3) positions on ``grid`` of the straight paths start -> waypoint -> goal -> route, flown to land at
    ``landing_time`` (the candidates' clearance before any of them is planned)."""
    d1 = np.linalg.norm(wps - start, axis=1)[:, None]
    d2 = np.linalg.norm(goal - wps, axis=1)[:, None]
    total = d1 + d2 + route_cum[-1]
    s = np.clip(grid[None, :] / landing_time, 0.0, 1.0) * total  # (C, G) arc length flown
    first = start + (wps - start)[:, None, :] * (s / np.maximum(d1, 1e-12))[..., None]
    second = wps[:, None, :] + (goal - wps)[:, None, :] * ((s - d1) / np.maximum(d2, 1e-12))[..., None]
    rest = np.clip(s - d1 - d2, 0.0, route_cum[-1])
    third = np.stack([np.interp(rest, route_cum, route[:, c]) for c in range(3)], axis=-1)
    return np.where((s <= d1)[..., None], first, np.where((s <= d1 + d2)[..., None], second, third))
