"""The landing sequencer of chapter 4: initial trajectories for any number of aircraft.

1. The shortest obstacle-free path of every aircraft from its start to the runway (the planner is run
   ``runs_per_aircraft`` times and the shortest path kept).
2. The landing schedule (:mod:`mal_planner.initializer.schedule`): with fixed landing times the order
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
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np

from mal_planner.initializer.collision import CollisionChecker
from mal_planner.initializer.planners import PathPlanner, PlanningFailed, make_planner, path_length
from mal_planner.initializer.schedule import DEFAULT_MARGIN_S, LandingSchedule, make_schedule
from mal_planner.initializer.smoothing import remove_repeats
from mal_planner.initializer.timing import dubins_path_length, earliest_landing_times
from mal_planner.scenario import Aircraft, Scenario

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

    def position_at(self, t: np.ndarray) -> np.ndarray:
        """Positions (n, 3) at times ``t`` (clipped to [0, landing_time])."""
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.landing_time)
        return np.stack([np.interp(t, self.times, self.waypoints[:, k]) for k in range(3)], axis=-1)

    def sample(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Times 0, dt, ..., landing_time and states (n, 5): x, y, z, flight-path angle, heading.

        The angles are those of the straight segment being flown: asin(dz/ds) and atan2(dy, dx).
        """
        if dt <= 0:
            raise ValueError(f"dt must be > 0, got {dt}")
        n = int(np.floor(self.landing_time / dt + 1e-9))
        t = np.arange(n + 1) * dt
        if self.landing_time - t[-1] > 1e-9:
            t = np.append(t, self.landing_time)
        d = np.diff(self.waypoints, axis=0)
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


def timed_path(path: np.ndarray, speed: float) -> np.ndarray:
    """Time at each vertex at constant ``speed``: cumulative length / speed, 0 at the first vertex."""
    seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(seg)]) / speed


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


@dataclass
class Sequencer:
    """Chapter 4's landing sequencer. ``planner``: a spec for :func:`make_planner` or a planner object.

    ``runs_per_aircraft``: planner runs for each aircraft's shortest path; ``lattice_resolution`` (nm):
    the waypoint lattice; ``max_waypoint_draws``: lattice draws per aircraft before giving up;
    ``checker_margin`` / ``gate_band`` / ``gate_margin``: the collision checker's options.
    """

    planner: str | PathPlanner = "multi-rrt"
    runs_per_aircraft: int = 3
    lattice_resolution: float = 0.01
    max_waypoint_draws: int = 20000
    max_waypoint_plans: int = 400
    """Planner runs (two per full candidate) before settling for the candidate closest to the window."""
    checker_margin: float = 0.0
    gate_band: float = 0.01
    gate_margin: float = 0.005
    planner_options: dict = field(default_factory=dict)
    landing_margin_s: float = DEFAULT_MARGIN_S
    """Free landing times are scheduled this long after the turn-aware earliest estimate."""
    window_s: float = 5.0
    """A stretched path is accepted when its flown time is within this of the scheduled time."""

    def __post_init__(self) -> None:
        if isinstance(self.planner, str):
            self._planner = make_planner(self.planner, **self.planner_options)
        else:
            self._planner = self.planner
        if self.runs_per_aircraft < 1 or self.lattice_resolution <= 0:
            raise ValueError("runs_per_aircraft must be >= 1 and lattice_resolution > 0")

    def plan(self, scenario: Scenario, seed: int | None = None) -> InitialPlan:
        """Initial trajectories of all aircraft; raises :class:`PlanningFailed`."""
        rng = np.random.default_rng(seed)
        checker = CollisionChecker.from_scenario(scenario, self.checker_margin, self.gate_band, self.gate_margin)
        goal = np.asarray(scenario.runway_state[:3], dtype=float)
        t_all = time.perf_counter()
        timings: dict[str, float] = {}
        direct: dict[str, np.ndarray] = {}
        for ac in scenario.aircraft:
            t0 = time.perf_counter()
            direct[ac.callsign] = self._shortest(checker, ac.position, goal, rng)
            timings[ac.callsign] = time.perf_counter() - t0
            log.info("%s: shortest path %.3f nm (%d points)", ac.callsign, path_length(direct[ac.callsign]),
                     len(direct[ac.callsign]))
        schedule = make_schedule(scenario, earliest_landing_times(scenario, direct), self.landing_margin_s)
        log.info("schedule: %s", ", ".join(f"{cs} {schedule.times[cs]:.1f} s" for cs in schedule.order))
        trajectories: list[InitialTrajectory] = []
        for k, cs in enumerate(schedule.order, start=1):
            ac = scenario.aircraft_by_callsign(cs)
            t0 = time.perf_counter()
            path, wp = self._stretch(scenario, checker, ac, direct[cs], schedule.times[cs], rng)
            tr = self._trajectory(scenario, ac, k, path, wp, direct[cs], schedule.times[cs])
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
                path = self._planner.plan(checker, start, goal, rng)
            except PlanningFailed as exc:
                errors.append(str(exc))
                continue
            if best is None or path_length(path) < path_length(best):
                best = path
        if best is None:
            raise PlanningFailed(errors[-1])
        return best

    def _stretch(self, scenario: Scenario, checker: CollisionChecker, ac: Aircraft, direct_path: np.ndarray,
                 scheduled: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray | None]:
        """The direct path if it suits ``scheduled``, else a path through a waypoint that does."""
        v = ac.speed
        dubins, straight = dubins_path_length(scenario, ac)
        turns = max(dubins - straight, 0.0)  # what the turns add to the polyline's length
        target = scheduled * v - turns
        lo_len, hi_len = target - self.window_s * v, target + self.window_s * v
        direct_len = path_length(direct_path)
        if direct_len >= lo_len - self.landing_margin_s * v:  # the schedule's margin needs no detour
            if direct_len > hi_len:
                log.warning("%s: the direct path needs %.1f s, more than the scheduled %.1f s; kept",
                            ac.callsign, (direct_len + turns) / v, scheduled)
            return direct_path, None
        start, goal = ac.position, np.asarray(scenario.runway_state[:3], dtype=float)
        res = self.lattice_resolution
        lo_i = np.ceil((scenario.airspace[:, 0] + 1e-12) / res).astype(np.int64) + 1
        hi_i = np.floor((scenario.airspace[:, 1] - 1e-12) / res).astype(np.int64) - 1
        side0 = [np.sign(g.signed_distance(start)) for g in scenario.gates]
        tried: set[tuple[int, int, int]] = set()
        planned = 0
        best: tuple[float, np.ndarray, np.ndarray] | None = None  # (miss of the window, path, waypoint)
        for draw in range(self.max_waypoint_draws):
            if planned >= self.max_waypoint_plans:
                break
            strict = planned < self.max_waypoint_plans // 2  # the thesis's "first leg > half" rule, then not
            point = _ellipse_point(start, goal, target, scenario.airspace, rng) if draw % 4 else None
            if point is None:
                key = tuple(int(i) for i in rng.integers(lo_i, hi_i + 1))
            else:
                key = tuple(int(i) for i in np.clip(np.round(point / res), lo_i, hi_i))
            if key in tried:
                continue
            tried.add(key)
            wp = np.asarray(key, dtype=float) * res
            d1, d2 = np.linalg.norm(wp - start), np.linalg.norm(goal - wp)
            if d1 + d2 > hi_len or d1 + d2 < direct_len - 1e-9:  # the straight-line bound already fails
                continue
            if strict and d1 <= d2:
                continue
            if any(np.sign(g.signed_distance(wp)) != s for g, s in zip(scenario.gates, side0, strict=True)):
                continue
            if not checker.point_free(wp):
                continue
            try:
                planned += 1
                leg1 = self._planner.plan(checker, start, wp, rng)
                leg1_len = path_length(leg1)
                too_long = leg1_len + d2 - hi_len  # a lower bound of how far past the window it lands
                if too_long > 0.0 and best is not None and too_long >= best[0]:
                    continue
                planned += 1
                leg2 = self._planner.plan(checker, wp, goal, rng)
            except PlanningFailed:
                continue
            total = leg1_len + path_length(leg2)
            if lo_len <= total <= hi_len:
                log.debug("%s: waypoint after %d draws, %d planned", ac.callsign, len(tried), planned)
                return remove_repeats(np.vstack([leg1, leg2])), wp
            miss = max(lo_len - total, total - hi_len, 0.0)
            if best is None or miss < best[0]:
                best = (miss, np.vstack([leg1, leg2]), wp)
        if best is not None:
            log.warning("%s: no waypoint met the scheduled landing time within %d planner runs; using the closest "
                        "(%.1f s off)", ac.callsign, planned, best[0] / v)
            return remove_repeats(best[1]), best[2]
        log.warning("%s: no waypoint found for a %.1f s landing (%d tried); the direct path is kept", ac.callsign,
                    scheduled, len(tried))
        return direct_path, None

    def _trajectory(self, scenario: Scenario, ac: Aircraft, order: int, path: np.ndarray,
                    wp: np.ndarray | None, direct_path: np.ndarray, scheduled: float) -> InitialTrajectory:
        path = remove_repeats(path)
        times = timed_path(path, ac.speed)
        wp_index = None
        if wp is not None:
            wp_index = int(np.argmin(np.linalg.norm(path - wp, axis=1)))
            path[wp_index] = wp
        return InitialTrajectory(
            callsign=ac.callsign, order=order, waypoints=path, times=times, speed=ac.speed,
            path_length=path_length(path), landing_time=float(times[-1]), waypoint=wp, waypoint_index=wp_index,
            direct_path=direct_path, gate_times=gate_crossing_times(scenario, path, times), scheduled_time=scheduled,
        )


def _ellipse_point(start: np.ndarray, goal: np.ndarray, length: float, airspace: np.ndarray,
                   rng: np.random.Generator) -> np.ndarray | None:
    """A random point P with |P - start| + |goal - P| = ``length`` (horizontally), or None if none exists.

    Its altitude is drawn between the two ends' altitudes (clipped to the airspace).
    """
    s2, g2 = start[:2], goal[:2]
    half_focal = 0.5 * float(np.linalg.norm(g2 - s2))
    a = 0.5 * length
    if a <= half_focal or half_focal == 0.0:
        return None
    b = float(np.sqrt(a * a - half_focal * half_focal))
    u = (g2 - s2) / (2.0 * half_focal)
    w = np.array([-u[1], u[0]])
    theta = rng.uniform(0.0, 2.0 * np.pi)
    xy = 0.5 * (s2 + g2) + a * np.cos(theta) * u + b * np.sin(theta) * w
    z = rng.uniform(min(start[2], goal[2]), max(start[2], goal[2]))
    point = np.array([xy[0], xy[1], z])
    if np.any(point < airspace[:, 0]) or np.any(point > airspace[:, 1]):
        return None
    return point


def plan_initial(scenario: Scenario, planner: str | PathPlanner = "multi-rrt", seed: int | None = None,
                 **options) -> InitialPlan:
    """Convenience: ``Sequencer(planner, **options).plan(scenario, seed)``."""
    return Sequencer(planner, **options).plan(scenario, seed)
