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

Step 3 is :mod:`.stretch`; the planner runs of steps 1 and 3 go through :class:`~.legs.LegPlanner`.

In a wind (``wind:``) every length that stands for a time is the *air distance* (the time flown x the airspeed,
:meth:`~mal_planner.dynamics.DynamicsModel.air_distance`): each straight segment is flown at the ground speed
of the wind triangle along it, and the paths are stretched to the air distance of their scheduled time. The
waypoint ellipse and the straight-leg proxies of the traffic screening stay geometric (they only rank draws).
"""

from __future__ import annotations

import logging
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
from mal_planner.initializer.base import InitializerTimeout, PathPlanner, path_length
from mal_planner.initializer.collision import CollisionChecker
from mal_planner.initializer.frame import RunwayFrame
from mal_planner.initializer.legs import LegPlanner
from mal_planner.initializer.planners import make_planner
from mal_planner.initializer.smoothing import remove_repeats
from mal_planner.initializer.stretch import Stretcher
from mal_planner.initializer.timed_paths import gate_crossing_times, timed_guess, timed_path
from mal_planner.scales import Scales
from mal_planner.scenario import Aircraft, Scenario
from mal_planner.sequencing.schedule import DEFAULT_MARGIN_TURN_TIMES, LandingSchedule, make_schedule
from mal_planner.sequencing.timing import earliest_landing_times

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
        self._legs = LegPlanner(self._planner, self.runs_per_aircraft)
        """The planner as the queries use it, bounded by the current query's deadline."""
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
        self._legs, self._where = LegPlanner(self._planner, self.runs_per_aircraft, deadline or NO_DEADLINE), "start"
        try:
            yield
        except TimeLimitReached as exc:
            if isinstance(exc, InitializerTimeout):
                raise
            raise InitializerTimeout(f"{exc} in the initializer ({self._where})") from None
        finally:
            self._legs.deadline = NO_DEADLINE

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
        checker = self._checker(local, scales)
        route = approach_for(local, ac, checker)
        direct = self._legs.join(checker, self._legs.shortest(checker, ac.position, route.first, rng), route, rng)
        seen = [(t, frame.points(pos)) for t, pos in traffic]
        stretcher = Stretcher(self._legs, self, local, checker, scales)
        path, wp = stretcher.stretch(ac, route, direct, landing_time, rng, seen, force=True)
        return self._trajectory(local, ac, order, path, wp, direct, landing_time).to_world(frame)

    def _plan(self, scenario: Scenario, seed: int | None) -> InitialPlan:
        """:meth:`plan` in the runway frame."""
        base = int(np.random.SeedSequence().entropy) if seed is None else 0
        rngs = {ac.callsign: aircraft_rng(seed, ac.callsign, base) for ac in scenario.aircraft}
        scales = Scales.of(scenario)
        checker = self._checker(scenario, scales)
        t_all = time.perf_counter()
        timings: dict[str, float] = {}
        routes, direct = self._direct_paths(scenario, checker, rngs, timings)
        n = len(scenario.aircraft)
        self._where = f"landing schedule, {n} of {n} planned"
        self._legs.deadline.check()
        margin = scales.seconds(self.landing_margin_turn_times)  # none for an aircraft straight in: no turn to time
        margins = {cs: 0.0 if route.established else margin for cs, route in routes.items()}
        schedule = make_schedule(scenario, earliest_landing_times(scenario, direct), margins)
        log.info("schedule: %s", ", ".join(f"{cs} {schedule.times[cs]:.1f} s" for cs in schedule.order))
        stretcher = Stretcher(self._legs, self, scenario, checker, scales)
        trajectories = self._sequenced(stretcher, schedule, routes, direct, rngs, timings)
        timings["total"] = time.perf_counter() - t_all
        return InitialPlan(tuple(trajectories), self._name, seed, timings, checker.counts.as_dict(), schedule)

    def _checker(self, scenario: Scenario, scales: Scales) -> CollisionChecker:
        return CollisionChecker.from_scenario(scenario, self.checker_margin, scales.lengths(self.gate_band_radii),
                                              scales.lengths(self.gate_margin_radii))

    def _direct_paths(self, scenario: Scenario, checker: CollisionChecker, rngs: dict[str, np.random.Generator],
                      timings: dict[str, float]) -> tuple[dict[str, Approach], dict[str, np.ndarray]]:
        """Step 1, in file order: each aircraft's approach route and its shortest path joined to the route (the
        seconds it took into ``timings``)."""
        routes: dict[str, Approach] = {}
        direct: dict[str, np.ndarray] = {}
        n = len(scenario.aircraft)
        for i, ac in enumerate(scenario.aircraft):
            self._where = f"{self._name} path of aircraft {ac.callsign}, {i} of {n} planned"
            self._legs.deadline.check()
            t0 = time.perf_counter()
            rng = rngs[ac.callsign]
            routes[ac.callsign] = route = approach_for(scenario, ac, checker)
            direct[ac.callsign] = self._legs.join(checker, self._legs.shortest(checker, ac.position, route.first, rng),
                                                  route, rng)
            timings[ac.callsign] = time.perf_counter() - t0
            log.info("%s: shortest path %.3f nm (%d points)", ac.callsign, path_length(direct[ac.callsign]),
                     len(direct[ac.callsign]))
        return routes, direct

    def _sequenced(self, stretcher: Stretcher, schedule: LandingSchedule, routes: dict[str, Approach],
                   direct: dict[str, np.ndarray], rngs: dict[str, np.random.Generator], timings: dict[str, float]
                   ) -> list[InitialTrajectory]:
        """Steps 3 and 4, in landing order: each path stretched to its scheduled time, clear of those before it,
        and timed (the seconds it took added to ``timings``)."""
        scenario = stretcher.scenario
        n = len(scenario.aircraft)
        trajectories: list[InitialTrajectory] = []
        traffic: list[tuple[np.ndarray, np.ndarray]] = []  # the timed paths of the aircraft stretched before
        for k, cs in enumerate(schedule.order, start=1):
            ac = scenario.aircraft_by_callsign(cs)
            self._where = f"sequencing waypoint of aircraft {cs}, {k - 1} of {n} sequenced"
            self._legs.deadline.check()
            t0 = time.perf_counter()
            path, wp = stretcher.stretch(ac, routes[cs], direct[cs], schedule.times[cs], rngs[cs], traffic)
            tr = self._trajectory(scenario, ac, k, path, wp, direct[cs], schedule.times[cs])
            traffic.append(timed_guess(path, ac.dynamics, schedule.times[cs]))
            timings[cs] += time.perf_counter() - t0
            log.info("%s: lands %d%s at %.1f s (path %.3f nm, %.1f s%s)", cs, k,
                     {1: "st", 2: "nd", 3: "rd"}.get(k, "th"), tr.scheduled_time, tr.path_length,
                     tr.landing_time, "" if wp is None else f", waypoint {np.round(wp, 3).tolist()}")
            trajectories.append(tr)
        return trajectories

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


def plan_initial(scenario: Scenario, planner: str | PathPlanner = "multi-rrt", seed: int | None = None,
                 deadline: Deadline | None = None, **options) -> InitialPlan:
    """Convenience: ``Sequencer(planner, **options).plan(scenario, seed, deadline)``."""
    return Sequencer(planner, **options).plan(scenario, seed, deadline)
