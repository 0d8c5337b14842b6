"""The landing sequencer of chapter 4: initial trajectories for any number of aircraft.

1. The shortest obstacle-free path of every aircraft from its start to the runway (the planner is run
   ``runs_per_aircraft`` times and the shortest path kept).
2. The landing schedule (:mod:`mal_planner.sequencing.schedule`): with fixed landing times the order
   follows them; otherwise first come, first served by the turn-aware earliest landing time, spaced by
   the minimum landing spacing. (The thesis orders by path length and spaces later aircraft 15-30 s after
   the previous one; that is a heuristic that breaks fixed times in another order and ignores turns.)
3. Every aircraft whose shortest path is too short for its scheduled time flies through a waypoint (on a
   lattice of ``lattice_resolution`` nm, in the airspace, outside obstacles, on its start's side of every
   gate) so that its path is about as long as its scheduled time needs (the turns it must fly are
   subtracted: they make the flown path longer than the polyline). Waypoints are drawn first on the
   ellipse of the wanted length around the start and the runway (where a straight two-leg path has
   that length), then anywhere; the thesis's rule that the first leg be more than half the path is
   preferred in the first half of the draws only, since it leaves no waypoint when a wall is close to
   the runway. When no waypoint meets the window, the closest candidate is kept (a warning is logged).
4. Times follow from the constant speed: t = cumulative length / speed, t = 0 at the start; the
   scheduled landing time is what the optimizer is given.

In a wind (``wind:``) every length that stands for a time is the *air distance* (the time flown x the airspeed,
:meth:`~mal_planner.dynamics.DynamicsModel.air_distance`): each straight segment is flown at the ground speed
of the wind triangle along it, and the paths are stretched to the air distance of their scheduled time. The
waypoint ellipse and the straight-leg proxies of the traffic screening stay geometric (they only rank draws).
"""

from __future__ import annotations

import itertools
import logging
import math
import time
import zlib
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace

import numpy as np

from mal_planner.deadline import NO_DEADLINE, Deadline
from mal_planner.dynamics import DynamicsModel
from mal_planner.errors import TimeLimitReached
from mal_planner.initializer.approach import Approach, approach_for
from mal_planner.initializer.collision import CollisionChecker
from mal_planner.initializer.frame import RunwayFrame
from mal_planner.initializer.planners import (
    InitializerTimeout,
    PathPlanner,
    PlanningFailed,
    make_planner,
    path_length,
)
from mal_planner.initializer.smoothing import SmoothedSearch, greedy_shortcut, remove_repeats, smooth_path
from mal_planner.scales import Scales
from mal_planner.scenario import Aircraft, Scenario
from mal_planner.sequencing.schedule import DEFAULT_MARGIN_TURN_TIMES, LandingSchedule, make_schedule
from mal_planner.sequencing.timing import dubins_path_length, earliest_landing_times

log = logging.getLogger("mal_planner.initializer")


@dataclass(frozen=True)
class InitialTrajectory:
    """One aircraft's initial path at constant speed (the optimizer's initial guess)."""

    callsign: str
    order: int
    """Landing order, 1 = first."""
    waypoints: np.ndarray
    """(K, 3) path vertices in nm, no repeated consecutive points."""
    times: np.ndarray
    """(K,) time at each vertex in s (0 at the start)."""
    speed: float
    path_length: float
    landing_time: float
    waypoint: np.ndarray | None
    """The sequencing waypoint (None for the first aircraft or when none was needed)."""
    waypoint_index: int | None
    """Index of ``waypoint`` in ``waypoints`` / ``times``."""
    direct_path: np.ndarray
    """The shortest path found before stretching (for plots)."""
    gate_times: dict[str, float | None]
    """Time at which the path crosses each gate's plane (interpolated), or None."""
    scheduled_time: float = float("nan")
    """The landing time of the schedule (what the optimizer is given); ``landing_time`` is the path's."""

    def to_world(self, frame: RunwayFrame) -> InitialTrajectory:
        """This trajectory, planned in ``frame``, in the world."""
        return replace(self, waypoints=frame.to_world(self.waypoints), direct_path=frame.to_world(self.direct_path),
                       waypoint=None if self.waypoint is None else frame.to_world(self.waypoint))

    def position_at(self, t: np.ndarray) -> np.ndarray:
        """Positions (n, 3) at times ``t`` (clipped to [0, landing_time])."""
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.landing_time)
        return np.stack([np.interp(t, self.times, self.waypoints[:, k]) for k in range(3)], axis=-1)

    def sample(self, dt: float, dynamics: DynamicsModel | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Times 0, dt, ..., landing_time and states (n, 5): x, y, z, flight-path angle, heading.

        The angles are those of the straight segment being flown: asin(dz/ds) and atan2(dy, dx); with the
        aircraft's ``dynamics`` in a wind, the air-relative ones that fly it (crabbed).
        """
        if dt <= 0:
            raise ValueError(f"dt must be > 0, got {dt}")
        n = int(np.floor(self.landing_time / dt + 1e-9))
        t = np.arange(n + 1) * dt
        if self.landing_time - t[-1] > 1e-9:
            t = np.append(t, self.landing_time)
        d = np.diff(self.waypoints, axis=0)
        if dynamics is not None and dynamics.has_wind:
            gamma, heading = dynamics.air_angles(d)
        else:
            ds = np.linalg.norm(d, axis=1)
            gamma = np.arcsin(np.clip(d[:, 2] / ds, -1.0, 1.0))
            heading = np.arctan2(d[:, 1], d[:, 0])
        seg = np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(d) - 1)
        return t, np.column_stack([self.position_at(t), gamma[seg], heading[seg]])


@dataclass(frozen=True)
class InitialPlan:
    """Initial trajectories in landing order, with how they were made."""

    trajectories: tuple[InitialTrajectory, ...]
    planner: str
    seed: int | None
    timings: dict[str, float]
    """Seconds per aircraft (by callsign) and ``"total"``."""
    collision_checks: dict[str, int]
    schedule: LandingSchedule | None = None

    def by_callsign(self, callsign: str) -> InitialTrajectory:
        for tr in self.trajectories:
            if tr.callsign == callsign:
                return tr
        raise KeyError(callsign)

    @property
    def landing_order(self) -> list[str]:
        return [tr.callsign for tr in self.trajectories]

    def only(self, callsigns: set[str]) -> InitialPlan:
        """This plan of ``callsigns`` alone."""
        if all(tr.callsign in callsigns for tr in self.trajectories):
            return self
        return replace(self, trajectories=tuple(tr for tr in self.trajectories if tr.callsign in callsigns),
                       schedule=None if self.schedule is None else self.schedule.only(callsigns))


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


def aircraft_rng(seed: int | None, callsign: str, base: int) -> np.random.Generator:
    """The random stream of one aircraft: the same for a callsign wherever it stands in the file.

    ``base`` is drawn once per plan when ``seed`` is None (a random plan)."""
    return np.random.default_rng([base if seed is None else seed, zlib.crc32(callsign.encode())])


@dataclass
class Sequencer:
    """Chapter 4's landing sequencer. ``planner``: a spec for :func:`make_planner` or a planner object.

    It works in the runway frame (:class:`RunwayFrame`) with one random stream per aircraft, so a turned,
    shifted or reordered copy of a scenario gets the same initial paths; its numbers are relative to the
    scenario's turn radius L and turn time T (thesis: L = 0.302 nm, T = 7.55 s; the former absolute values in
    brackets). ``runs_per_aircraft``: planner runs for each aircraft's shortest path; ``lattice_radii``: the
    waypoint lattice (0.01 nm); ``max_waypoint_draws``: lattice draws per aircraft before giving up;
    ``checker_margin`` / ``gate_band_radii`` (0.01 nm) / ``gate_margin_radii`` (0.005 nm): the collision
    checker's options. A ``deadline`` given to :meth:`plan` or :meth:`replan_one` is checked before every aircraft,
    every waypoint candidate and in the planner's loop; when it runs out they raise :class:`InitializerTimeout`
    naming the stage.
    """

    planner: str | PathPlanner = "multi-rrt"
    runs_per_aircraft: int = 3
    lattice_radii: float = 1.0 / 30.0
    max_waypoint_draws: int = 20000
    max_waypoint_plans: int = 400
    """Planner runs (two per full candidate) before settling for the candidate closest to the window."""
    checker_margin: float = 0.0
    gate_band_radii: float = 1.0 / 30.0
    gate_margin_radii: float = 1.0 / 60.0
    planner_options: dict = field(default_factory=dict)
    landing_margin_turn_times: float = DEFAULT_MARGIN_TURN_TIMES
    """Free landing times are scheduled this long after the turn-aware earliest estimate (5 s)."""
    window_turn_times: float = 2.0 / 3.0
    """A stretched path is accepted when its flown time is within this of the scheduled time (5 s)."""
    guess_buffer_radii: float = 1.0
    """A stretched path keeps the separation plus this from the paths stretched before (0.3 nm)."""

    def __post_init__(self) -> None:
        if isinstance(self.planner, str):
            self._planner = make_planner(self.planner, **self.planner_options)
        else:
            self._planner = self.planner
        if self.runs_per_aircraft < 1 or self.lattice_radii <= 0:
            raise ValueError("runs_per_aircraft must be >= 1 and lattice_radii > 0")
        self._deadline = NO_DEADLINE
        self._where = ""
        """The stage the current query is in, for the time limit's message."""

    @property
    def _name(self) -> str:
        return getattr(self._planner, "spec", type(self._planner).__name__)

    def plan(self, scenario: Scenario, seed: int | None = None, deadline: Deadline | None = None) -> InitialPlan:
        """Initial trajectories of all aircraft; raises :class:`PlanningFailed` (:class:`InitializerTimeout` when
        ``deadline`` runs out)."""
        frame = RunwayFrame.of(scenario)
        with self._bounded(deadline):
            plan = self._plan(frame.scenario(scenario), seed)
        return replace(plan, trajectories=tuple(tr.to_world(frame) for tr in plan.trajectories))

    @contextmanager
    def _bounded(self, deadline: Deadline | None) -> Iterator[None]:
        """Run one query under ``deadline``: its time limit reached anywhere inside becomes
        :class:`InitializerTimeout` naming the stage (:attr:`_where`)."""
        self._deadline, self._where = deadline or NO_DEADLINE, "start"
        try:
            yield
        except TimeLimitReached as exc:
            if isinstance(exc, InitializerTimeout):
                raise
            raise InitializerTimeout(f"{exc} in the initializer ({self._where})") from None
        finally:
            self._deadline = NO_DEADLINE

    def replan_one(self, scenario: Scenario, callsign: str, landing_time: float,
                   traffic: Sequence[tuple[np.ndarray, np.ndarray]], seed: int | None = None,
                   order: int = 1, deadline: Deadline | None = None) -> InitialTrajectory:
        """A new initial path of one aircraft for ``landing_time`` that keeps clear of ``traffic`` (the times and
        positions of aircraft planned already, in the world): the sequential optimizer's first recovery when an
        aircraft finds no plan against the plans of those before it."""
        with self._bounded(deadline):
            self._where = f"new {self._name} path of aircraft {callsign}"
            return self._replan_one(scenario, callsign, landing_time, traffic, seed, order)

    def _replan_one(self, scenario: Scenario, callsign: str, landing_time: float,
                    traffic: Sequence[tuple[np.ndarray, np.ndarray]], seed: int | None, order: int
                    ) -> InitialTrajectory:
        """:meth:`replan_one` without the deadline's wrapping."""
        frame = RunwayFrame.of(scenario)
        local = frame.scenario(scenario)
        ac = local.aircraft_by_callsign(callsign)
        rng = aircraft_rng(seed, callsign, int(np.random.SeedSequence().entropy) if seed is None else 0)
        scales = Scales.of(local)
        checker = CollisionChecker.from_scenario(local, self.checker_margin, scales.lengths(self.gate_band_radii),
                                                 scales.lengths(self.gate_margin_radii))
        route = approach_for(local, ac, checker)
        direct = self._join(checker, self._shortest(checker, ac.position, route.first, rng), route, rng)
        seen = [(t, frame.points(pos)) for t, pos in traffic]
        path, wp = self._stretch(local, checker, ac, route, direct, landing_time, rng, scales, seen, force=True)
        return self._trajectory(local, ac, order, path, wp, direct, landing_time).to_world(frame)

    def _plan(self, scenario: Scenario, seed: int | None) -> InitialPlan:
        """:meth:`plan` in the runway frame."""
        base = int(np.random.SeedSequence().entropy) if seed is None else 0
        rngs = {ac.callsign: aircraft_rng(seed, ac.callsign, base) for ac in scenario.aircraft}
        scales = Scales.of(scenario)
        checker = CollisionChecker.from_scenario(scenario, self.checker_margin, scales.lengths(self.gate_band_radii),
                                                 scales.lengths(self.gate_margin_radii))
        t_all = time.perf_counter()
        timings: dict[str, float] = {}
        direct: dict[str, np.ndarray] = {}
        routes: dict[str, Approach] = {}
        n = len(scenario.aircraft)
        for i, ac in enumerate(scenario.aircraft):
            self._where = f"{self._name} path of aircraft {ac.callsign}, {i} of {n} planned"
            self._deadline.check()
            t0 = time.perf_counter()
            rng = rngs[ac.callsign]
            routes[ac.callsign] = route = approach_for(scenario, ac, checker)
            direct[ac.callsign] = self._join(checker, self._shortest(checker, ac.position, route.first, rng), route,
                                             rng)
            timings[ac.callsign] = time.perf_counter() - t0
            log.info("%s: shortest path %.3f nm (%d points)", ac.callsign, path_length(direct[ac.callsign]),
                     len(direct[ac.callsign]))
        self._where = f"landing schedule, {n} of {n} planned"
        self._deadline.check()
        schedule = make_schedule(scenario, earliest_landing_times(scenario, direct),
                                 scales.seconds(self.landing_margin_turn_times))
        log.info("schedule: %s", ", ".join(f"{cs} {schedule.times[cs]:.1f} s" for cs in schedule.order))
        trajectories: list[InitialTrajectory] = []
        traffic: list[tuple[np.ndarray, np.ndarray]] = []  # the timed paths of the aircraft stretched before
        for k, cs in enumerate(schedule.order, start=1):
            ac = scenario.aircraft_by_callsign(cs)
            self._where = f"sequencing waypoint of aircraft {cs}, {k - 1} of {n} sequenced"
            self._deadline.check()
            t0 = time.perf_counter()
            path, wp = self._stretch(scenario, checker, ac, routes[cs], direct[cs], schedule.times[cs], rngs[cs],
                                     scales, traffic)
            tr = self._trajectory(scenario, ac, k, path, wp, direct[cs], schedule.times[cs])
            traffic.append(timed_guess(path, ac.dynamics, schedule.times[cs]))
            timings[cs] += time.perf_counter() - t0
            log.info("%s: lands %d%s at %.1f s (path %.3f nm, %.1f s%s)", cs, k,
                     {1: "st", 2: "nd", 3: "rd"}.get(k, "th"), tr.scheduled_time, tr.path_length,
                     tr.landing_time, "" if wp is None else f", waypoint {np.round(wp, 3).tolist()}")
            trajectories.append(tr)
        timings["total"] = time.perf_counter() - t_all
        return InitialPlan(tuple(trajectories), getattr(self._planner, "spec", type(self._planner).__name__),
                           seed, timings, checker.counts.as_dict(), schedule)

    def _shortest(self, checker: CollisionChecker, start: np.ndarray, goal: np.ndarray,
                  rng: np.random.Generator) -> np.ndarray:
        best: np.ndarray | None = None
        errors = []
        for _ in range(self.runs_per_aircraft):
            try:
                path = self._path(checker, start, goal, rng)
            except PlanningFailed as exc:
                errors.append(str(exc))
                continue
            if best is None or path_length(path) < path_length(best):
                best = path
        if best is None:
            raise PlanningFailed(errors[-1])
        return best

    def _quick_plan(self, checker: CollisionChecker, start: np.ndarray, goal: np.ndarray,
                    rng: np.random.Generator) -> np.ndarray:
        """A candidate leg: the planner's path with the greedy shortcut only (the random shortcuts, about 40 %
        of a terminal area's initializer time, are for the path that is kept; see :meth:`_polish`)."""
        if isinstance(self._planner, SmoothedSearch):
            return greedy_shortcut(checker, self._planner.search(checker, start, goal, rng, self._deadline))
        return self._path(checker, start, goal, rng)

    def _path(self, checker: CollisionChecker, start: np.ndarray, goal: np.ndarray,
              rng: np.random.Generator) -> np.ndarray:
        """The planner's path, its search bounded by the deadline (checked before a planner that takes none)."""
        self._deadline.check()
        if isinstance(self._planner, SmoothedSearch):
            return self._planner.plan(checker, start, goal, rng, self._deadline)
        return self._planner.plan(checker, start, goal, rng)

    def _polish(self, checker: CollisionChecker, path: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The kept path smoothed as the planner smooths its own (a no-op for other planners)."""
        if isinstance(self._planner, SmoothedSearch):
            return smooth_path(checker, path, rng, self._planner.smooth_rounds)
        return path

    def _polished(self, checker: CollisionChecker, leg1: np.ndarray, leg2: np.ndarray, route: Approach,
                  rng: np.random.Generator, path: np.ndarray, lo_len: float, hi_len: float,
                  dynamics: DynamicsModel) -> np.ndarray:
        """The two legs of a kept candidate smoothed (the route after them is kept as it is); the candidate as it
        was if smoothing takes it out of the window (of air distances, see the module docstring)."""
        smooth = remove_repeats(np.vstack([self._polish(checker, leg1, rng),
                                           self._join(checker, self._polish(checker, leg2, rng), route, rng)]))
        return smooth if lo_len <= air_path_length(dynamics, smooth) <= hi_len else path

    def _join(self, checker: CollisionChecker, to_route: np.ndarray, route: Approach,
              rng: np.random.Generator) -> np.ndarray:
        """A path to the route's first point, then the route; a leg of the route that is not free (e.g. from a
        gate's exit to the final approach fix, past a no-fly zone) is planned."""
        parts = [np.asarray(to_route, float)]
        for a, b in itertools.pairwise(route.points):
            parts.append(np.array([b]) if checker.segment_free(a, b) else self._path(checker, a, b, rng)[1:])
        return remove_repeats(np.vstack(parts))

    def _stretch(self, scenario: Scenario, checker: CollisionChecker, ac: Aircraft, route: Approach,
                 direct_path: np.ndarray, scheduled: float, rng: np.random.Generator, scales: Scales,
                 traffic: Sequence[tuple[np.ndarray, np.ndarray]] = (), force: bool = False
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
        v, dyn = ac.speed, ac.dynamics
        need = scenario.separation_nm + scales.lengths(self.guess_buffer_radii)

        # The traffic on one time grid (every half turn time), NaN where an aircraft has landed: a candidate's
        # clearance is then one vectorised distance.
        grid = np.arange(0.0, scheduled + scales.time_s, 0.5 * scales.time_s)
        others = np.full((len(traffic), len(grid), 3), np.nan)
        for k, (t_o, pos_o) in enumerate(traffic):
            flying = grid <= t_o[-1]
            others[k, flying] = np.column_stack([np.interp(grid[flying], t_o, pos_o[:, c]) for c in range(3)])

        def clearance(path: np.ndarray) -> float:
            if not len(traffic):
                return math.inf
            times = timed_path(path, dyn)
            times = times * (scheduled / times[-1]) if times[-1] > 0 else times
            mine = np.column_stack([np.interp(grid, times, path[:, c]) for c in range(3)])
            gaps = np.linalg.norm(others - mine[None], axis=2)
            return float(np.nanmin(gaps)) if np.isfinite(gaps).any() else math.inf
        dubins, straight = dubins_path_length(scenario, ac)
        turns = max(dubins - straight, 0.0)  # what the turns add to the polyline's length
        window, margin = scales.seconds(self.window_turn_times), scales.seconds(self.landing_margin_turn_times)
        target = scheduled * v - turns
        lo_len, hi_len = target - window * v, target + window * v
        direct_len = air_path_length(dyn, direct_path)  # lengths that stand for times are air distances
        direct_clear = clearance(direct_path)
        if direct_len >= lo_len - margin * v and not (force and direct_clear < need):  # no detour needed
            if direct_len > hi_len:
                log.warning("%s: the direct path needs %.1f s, more than the scheduled %.1f s; kept",
                            ac.callsign, (direct_len + turns) / v, scheduled)
            if direct_clear < need:
                log.info("%s: the direct path comes %.2f nm close to an earlier aircraft's", ac.callsign,
                         direct_clear)
            return direct_path, None
        start, goal, tail = ac.position, route.first, air_path_length(dyn, route.points)
        onto = (route.points[1] - goal) if len(route.points) > 1 else np.zeros(3)
        res = scales.lengths(self.lattice_radii)
        lo_i = np.ceil((scenario.airspace[:, 0] + 1e-12) / res).astype(np.int64) + 1
        hi_i = np.floor((scenario.airspace[:, 1] - 1e-12) / res).astype(np.int64) - 1
        side0 = [np.sign(g.signed_distance(start)) for g in scenario.gates]
        tried: set[tuple[int, int, int]] = set()
        planned = 0
        best: tuple | None = None  # (rank, path, waypoint, leg1, leg2)
        route_cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(route.points, axis=0), axis=1))])
        done = False
        for first in range(0, self.max_waypoint_draws, WAYPOINT_BATCH):
            if done or planned >= self.max_waypoint_plans:
                break
            self._deadline.check()
            strict = planned < self.max_waypoint_plans // 2 and first < self.max_waypoint_draws // 2
            keys = _waypoint_keys(rng, WAYPOINT_BATCH, first, start, goal, target - tail, scenario.airspace, res,
                                  lo_i, hi_i)
            keys, index = np.unique(keys, axis=0, return_index=True)
            keys = keys[np.argsort(index)]  # in the order drawn
            fresh = np.array([tuple(k) not in tried for k in keys.tolist()], bool)
            tried.update(tuple(k) for k in keys.tolist())
            wps = keys[fresh].astype(float) * res
            d1 = dyn.air_distance(wps - start)
            d2 = dyn.air_distance(goal - wps) + tail
            ok = (d1 + d2 <= hi_len) & (d1 + d2 >= direct_len - 1e-9)  # the straight-line bounds
            if strict:
                ok &= (d1 > d2) & ((goal - wps) @ onto >= 0.0)
            for g, side in zip(scenario.gates, side0, strict=True):
                ok &= np.sign(g.signed_distance(wps)) == side
            ok[ok] = checker.points_free(wps[ok])
            if strict and len(traffic) and ok.any():  # the straight legs already come too close: not worth planning
                near = _proxy_positions(start, wps[ok], goal, route.points, route_cum, scheduled, grid)
                gaps = np.linalg.norm(others[None] - near[:, None], axis=3)
                ok[ok] = np.nanmin(np.where(np.isfinite(gaps), gaps, np.inf), axis=(1, 2)) >= need
            for wp, d2_wp in zip(wps[ok], d2[ok], strict=True):
                if planned >= self.max_waypoint_plans or (
                        best is not None and best[0][0] == 0.0 and planned >= self.max_waypoint_plans // 4):
                    done = True  # one in the window, only not clear of the traffic: the optimizer separates them
                    break
                self._deadline.check()
                try:
                    planned += 1
                    leg1 = self._quick_plan(checker, start, wp, rng)
                    leg1_len = air_path_length(dyn, leg1)
                    too_long = leg1_len + d2_wp - hi_len  # a lower bound of how far past the window it lands
                    if too_long > 0.0 and best is not None and too_long >= best[0][0]:
                        continue
                    planned += 1
                    leg2 = self._quick_plan(checker, wp, goal, rng)
                    joined = self._join(checker, leg2, route, rng)
                except PlanningFailed:
                    continue
                total = leg1_len + air_path_length(dyn, joined)
                path = remove_repeats(np.vstack([leg1, joined]))
                miss = max(lo_len - total, total - hi_len, 0.0)
                clear = clearance(path) if miss == 0.0 else 0.0
                if miss == 0.0 and clear >= need:
                    log.debug("%s: waypoint after %d draws, %d planned", ac.callsign, len(tried), planned)
                    return self._polished(checker, leg1, leg2, route, rng, path, lo_len, hi_len, dyn), wp
                rank = (miss, -min(clear, need), 0.0)
                if best is None or rank < best[0]:
                    best = (rank, path, wp, leg1, leg2)
        if best is not None:
            if best[0][0] == 0.0:
                best = (best[0], self._polished(checker, best[3], best[4], route, rng, best[1], lo_len, hi_len,
                                                dyn), best[2])
            miss, clear = best[0][0], -best[0][1]
            if miss > 0.0:
                log.warning("%s: no waypoint met the scheduled landing time within %d planner runs; using the "
                            "closest (%.1f s off)", ac.callsign, planned, miss / v)
            else:
                log.info("%s: no waypoint kept %.2f nm from the earlier aircraft within %d planner runs; using the "
                         "clearest (%.2f nm)", ac.callsign, need, planned, clear)
            return best[1], best[2]
        log.warning("%s: no waypoint found for a %.1f s landing (%d tried); the direct path is kept", ac.callsign,
                    scheduled, len(tried))
        return direct_path, None

    def _trajectory(self, scenario: Scenario, ac: Aircraft, order: int, path: np.ndarray,
                    wp: np.ndarray | None, direct_path: np.ndarray, scheduled: float) -> InitialTrajectory:
        path = remove_repeats(path)
        times = timed_path(path, ac.dynamics)
        wp_index = None
        if wp is not None:
            wp_index = int(np.argmin(np.linalg.norm(path - wp, axis=1)))
            path[wp_index] = wp
        return InitialTrajectory(
            callsign=ac.callsign, order=order, waypoints=path, times=times, speed=ac.speed,
            path_length=path_length(path), landing_time=float(times[-1]), waypoint=wp, waypoint_index=wp_index,
            direct_path=direct_path, gate_times=gate_crossing_times(scenario, path, times), scheduled_time=scheduled,
        )


WAYPOINT_BATCH = 256
"""Waypoint candidates drawn and screened at once (the screening is vectorised; planning them is not)."""


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


def plan_initial(scenario: Scenario, planner: str | PathPlanner = "multi-rrt", seed: int | None = None,
                 deadline: Deadline | None = None, **options) -> InitialPlan:
    """Convenience: ``Sequencer(planner, **options).plan(scenario, seed, deadline)``."""
    return Sequencer(planner, **options).plan(scenario, seed, deadline)
