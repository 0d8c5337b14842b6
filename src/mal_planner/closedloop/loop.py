"""The closed loop in one process: the planning service and the flight simulator, in simulated time.

This is what the planner node and the simulator node do over DDS, without the transport, so that campaigns
run hundreds of closed loops on the Dask engine. The service is the node's own
:class:`~mal_planner.service.core.PlanningService` (radar intake and track filter, replan policy, plan book, plan
inputs), with the rules of :meth:`~mal_planner.service.rules.ServiceRules.closed_loop`; the planner is the node's
:class:`~mal_planner.pipeline.Planner` (warm-started replans and their fallbacks). Radar tracks are the simulated
aircraft with noise, at the radar's rate.

Planning time is charged honestly: a replan requested at time t reaches the aircraft at t + (its CPU time, or
wall-clock time with ``charge="wall"``) x ``planning_time_factor``, while they go on flying the previous plan.
The service makes it start ahead, from the tracks predicted along the plans they fly (see
:meth:`~mal_planner.service.core.PlanningService.request`). The first plan is the exception: it is made before the
simulation starts (the service was running when the traffic appeared), from the true initial states.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from mal_planner.closedloop.disturbances import RadarNoise, WindSpec
from mal_planner.closedloop.simulator import FlightSimulator, SimOptions
from mal_planner.options import SERVICE_TIME_LIMIT_S, PlanOptions
from mal_planner.pipeline import Planner, PlanResult
from mal_planner.pipeline.among import plan_or_replan
from mal_planner.scales import Scales
from mal_planner.scenario import Scenario
from mal_planner.service.book import Event, Handout, Instructed, Kept, Stale, Withdrawn
from mal_planner.service.core import PlanningService
from mal_planner.service.request import PlanRequest
from mal_planner.service.rules import TRACK_FILTER_TURN_TIMES, ServiceRules
from mal_planner.service.tracks import Track

log = logging.getLogger("mal_planner.closedloop")

SimulatorFactory = Callable[[Scenario, SimOptions], FlightSimulator]
"""Makes the simulator of a run (FlightSimulator itself is one; so is closedloop.bluesky_sim.BlueSkySimulator)."""

RADAR_PERIOD_S = 1.0
"""Track update period: ADS-B's 1 Hz (a terminal radar turns in 4-5 s)."""
PLAN_TIME_LIMIT_S = SERVICE_TIME_LIMIT_S
"""Wall-clock limit of one plan: the planner node's (``planning_time_limit_s``), the best result so far then."""
OVERRUN_TURN_TIMES = 20.0
"""The run ends this long after the first plan's last landing if aircraft are still flying."""
HOLD_OVERRUN_TURN_TIMES = 200.0
"""... and at most this long after that, however late the plans of aircraft that held come (a terminal area 46 min)."""
PROGRESS_PERIOD_S = 10.0
"""A progress line every this many wall-clock seconds of a run (simulated time, airborne, landed, replans)."""


@dataclass(frozen=True)
class ClosedLoopOptions:
    sim: SimOptions = SimOptions()
    plan: PlanOptions = field(default_factory=lambda: PlanOptions(time_limit_s=PLAN_TIME_LIMIT_S))
    planner_knows_wind: bool = True
    """The planner gets the mean wind (as a forecast or an estimate); False: it plans in still air."""
    radar_noise_m: float = 0.0
    """Radar position noise, sigma per axis in metres."""
    radar_period_s: float = RADAR_PERIOD_S
    replan_period_s: float = 0.0
    """Replan this often regardless of deviations (0: only on deviations)."""
    deviation_nm: float | None = None
    """Replan threshold; None: the service rules' (:meth:`ServiceRules.closed_loop`)."""
    planning_time_factor: float = 1.0
    """Simulated seconds charged per second of planning (1: honest; 0: planning takes no time)."""
    max_time_s: float | None = None
    """End of the run; None: the first plan's last landing plus OVERRUN_TURN_TIMES turn times."""
    replan_limit_turn_times: float = 2.0
    """Wall-clock limit of a replan in turn times (thesis 15 s, a terminal area 28 s; the first plan has the plan
    options' limit): the aircraft fly on meanwhile, and a plan much later than that finds them elsewhere."""
    track_filter_turn_times: float = TRACK_FILTER_TURN_TIMES
    """Time constant of the service's track filter (:mod:`mal_planner.service.track_filter`) in turn times (thesis
    3.8 s: 30 m of radar noise leave 11 m); 0: raw radar tracks."""
    charge: str = "cpu"
    """What a replan costs in simulated time: "cpu", its CPU time (what it takes on a machine of its own: campaigns
    share the cores, and wall-clock time would charge the other jobs' time too), or "wall", its wall-clock time."""
    tracking_margins: bool = True
    """Plan with safety margins sized to the deviations the replan rule lets pass
    (:func:`~mal_planner.service.rules.tracking_margins`); False: the open-loop planner's margins."""
    progress: bool = False
    """Log a progress line every :data:`PROGRESS_PERIOD_S` wall-clock seconds."""
    extra_plan_delay_s: float = 0.0
    """A slow planner: every replan reaches the aircraft this much later (tests of the fallback)."""
    fail_every: int = 0
    """A failing planner: every this many-th replan fails (2: every other one; 0: none) (tests of the fallback)."""
    replan_what_changed: bool = False
    """An aircraft that strays is replanned with those it can affect, the others keep their instructions
    (:attr:`~mal_planner.service.rules.ServiceRules.replan_what_changed`)."""


@dataclass
class Replan:
    """One plan request of the service."""

    t: float
    """Simulated time of the tracks it started from."""
    reason: str
    wall_s: float
    arrived_at: float
    ok: bool
    message: str
    aircraft: list[str]
    landing_order: list[str]
    cpu_s: float = math.nan
    """The planning's CPU time (the process's, every thread)."""
    charged_s: float = math.nan
    """The planning time charged in simulated time (see ``ClosedLoopOptions.charge``)."""
    kept: int = 0
    """A replan of what changed: how many aircraft kept their instructions (0: a whole replan)."""


@dataclass
class ClosedLoopRun:
    """The raw record of one run: the simulator (flown tracks, landings) and the service's plans."""

    scenario: Scenario
    options: ClosedLoopOptions
    sim: FlightSimulator
    replans: list[Replan]
    first: Replan
    wall_s: float
    instructions: list[tuple[float, str, str]] = field(default_factory=list)
    """What each aircraft was told to fly and when: (time, callsign, "plan" / "hold" / "vector" / "none")."""
    guard: dict[str, int] = field(default_factory=dict)
    """The service's holds, vectors, safety-net alerts and uses (:class:`~mal_planner.service.guard.Guard`)."""


@dataclass
class _Pending:
    """A plan under way: it reaches the aircraft at ``at``."""

    at: float
    record: Replan
    request: PlanRequest | None
    result: PlanResult | None
    failure: str | None


def planning_scenario(scenario: Scenario, wind: WindSpec, knows_wind: bool) -> Scenario:
    """The scenario the service plans in: the mean wind if it knows it, else still air."""
    return scenario.with_wind(tuple(wind.mean) if knows_wind else (0.0, 0.0))


class ClosedLoop:
    """One scenario flown in closed loop; :meth:`run` returns a :class:`ClosedLoopRun`."""

    def __init__(self, scenario: Scenario, options: ClosedLoopOptions | None = None,
                 simulator: FlightSimulator | SimulatorFactory | None = None) -> None:
        """``simulator``: the aircraft to fly the plans, a simulator with :class:`FlightSimulator`'s interface or a
        factory called with (scenario, options.sim); None: a :class:`FlightSimulator`."""
        self.options = opts = options or ClosedLoopOptions()
        self.scenario = scenario
        self.scales = Scales.of(scenario)
        if simulator is None or isinstance(simulator, FlightSimulator):
            self.sim = simulator or FlightSimulator(scenario, opts.sim)
        else:
            self.sim = simulator(scenario, opts.sim)
        seed = opts.sim.seed
        self.noise = RadarNoise(opts.radar_noise_m, None if seed is None else seed + 1)
        self.rules = ServiceRules.closed_loop(
            scenario, noise_sigma_nm=self.noise.sigma_nm, radar_period_s=opts.radar_period_s,
            deviation_nm=opts.deviation_nm, period_s=opts.replan_period_s,
            filter_turn_times=opts.track_filter_turn_times, replan_limit_turn_times=opts.replan_limit_turn_times,
            replan_what_changed=opts.replan_what_changed)
        base = planning_scenario(scenario, opts.sim.wind, opts.planner_knows_wind)
        self.service = PlanningService(base, self.rules, opts.plan, flown=opts.tracking_margins)
        self.planner = Planner(self.service.options)
        self.replans: list[Replan] = []
        self.instructions: list[tuple[float, str, str]] = []
        self._records: dict[int, Replan] = {}

    @property
    def threshold(self) -> float:
        """The deviation threshold (nm): replan beyond it; the margins of flown plans are sized to it."""
        return self.rules.deviation_nm

    @property
    def base(self) -> Scenario:
        """The scenario the service plans in."""
        return self.service.base_scenario()

    # -- the service's side ----------------------------------------------------------------------------------------
    def _tracks(self, truth: bool = False) -> dict[str, Track]:
        tracks = {}
        for ac in self.sim.measurements():
            state = self.sim.radar_state(ac)
            tracks[ac.callsign] = Track(ac.callsign, self.sim.t, state if truth else self.noise.apply(state),
                                        self.sim.radar_speed(ac), ac.wake)
        return tracks

    def _radar_scan(self) -> None:
        """The radar's tracks of every aircraft flying, into the service; tracks of aircraft that landed dropped."""
        t = self.sim.t
        for track in self._tracks().values():
            self.service.take_track(track, self.rules.frame_id, "radar", t, t)
        self._apply(self.service.lose_tracks())

    def _plan(self, request: PlanRequest | str, reason: str, tracked: list[str]) -> _Pending:
        """Run one request (or record a refused one) now; it reaches the aircraft after its charged time."""
        t_request = self.sim.t
        start, cpu0 = time.perf_counter(), time.process_time()
        result, failure = None, None
        injected = self.options.fail_every > 0 and (len(self.replans) + 1) % self.options.fail_every == 0
        if isinstance(request, str):
            failure = request
        elif injected and reason != "initial plan":
            failure = f"failed on purpose (every {self.options.fail_every}th replan fails: fail_every)"
        else:
            try:
                self.planner.options = request.options
                result = plan_or_replan(self.planner, request.scenario, request.plan_start, request.traffic)
                failure = None if result.failure is None else f"{result.failure.outcome}: {result.failure.reason}"
            except Exception as exc:  # the service keeps running: the aircraft keep their plans
                failure = " ".join(str(exc).split()) or type(exc).__name__
                log.warning("t=%.1f s: planning raised %s: %s", t_request, type(exc).__name__, failure, exc_info=True)
        wall, cpu = time.perf_counter() - start, time.process_time() - cpu0
        order = []
        if failure is None and result is not None:
            times = result.landing_times()
            order = sorted(times, key=times.__getitem__)
        charged = (cpu if self.options.charge == "cpu" else wall) * self.options.planning_time_factor
        if reason != "initial plan":
            charged += self.options.extra_plan_delay_s
        t = request.plan_start if not isinstance(request, str) else t_request
        kept = 0 if isinstance(request, str) or request.traffic is None else len(request.traffic.fixed)
        record = Replan(t, reason, wall, t_request + charged, failure is None, failure or "verified", tracked, order,
                        cpu, charged, kept)
        if not isinstance(request, str):
            self._records[id(request)] = record
        log.info("t=%.1f s: plan (%s) %s in %.2f s (CPU %.2f s)", t, reason,
                 "verified" if failure is None else f"failed: {failure}", wall, cpu)
        return _Pending(record.arrived_at, record, None if isinstance(request, str) else request, result, failure)

    def _arrive(self, pending: _Pending) -> None:
        """A plan (or a failure) reaches the service: it hands plans out as they start."""
        now = pending.at
        if pending.request is None:
            self.service.refused(now, pending.record.charged_s)
            return
        self._apply(self.service.finish(pending.request, pending.result, pending.failure, now,
                                        pending.record.charged_s))

    def _apply(self, events: list[Event]) -> None:
        """What the service decided, done to the simulated aircraft."""
        for event in events:
            if isinstance(event, Handout):
                if event.established:
                    log.info("t=%.1f s: %s established on final: keep their plans", event.at,
                             ", ".join(event.established))
                for cs in event.trajectories:
                    self.sim.set_plan(cs, self.service.book.flying[cs], event.at)
                    self.instructions.append((event.at, cs, "plan"))
            elif isinstance(event, Instructed):
                for fb in event.fallbacks:
                    self.sim.set_plan(fb.callsign, fb.reference, fb.issued_at)
                    self.instructions.append((fb.issued_at, fb.callsign, fb.kind))
            elif isinstance(event, Stale):
                record = self._records.get(id(event.request))
                if record is not None:
                    record.ok, record.message = False, event.reason
                log.info("t=%.1f s: plan %s", self.sim.t, event.reason)
            elif isinstance(event, Withdrawn):
                for cs in event.callsigns:
                    self.sim.set_plan(cs, None, self.sim.t)
                    self.instructions.append((self.sim.t, cs, "none"))
            elif isinstance(event, Kept):
                log.debug("t=%.1f s: replan failed, the aircraft keep their plans", self.sim.t)

    # -- the run ---------------------------------------------------------------------------------------------------
    def _first_plan(self) -> Replan:
        truth = self._tracks(truth=True)
        request = self.service.request("initial plan", self.sim.t, tracks=truth, lead=False)
        pending = self._plan(request, "initial plan", sorted(truth))
        if pending.request is None:
            self.service.refused(0.0, pending.record.charged_s)
        else:  # delivered at once: the service was running when the traffic appeared
            self._apply(self.service.finish(pending.request, pending.result, pending.failure, 0.0,
                                            pending.record.charged_s))
        return pending.record

    def _end_time(self, first: Replan) -> float:
        if self.options.max_time_s is not None:
            return self.options.max_time_s
        current = self.service.book.current
        if current is not None:
            last = max(current.result.landing_times().values())
        else:
            last = max(float(np.linalg.norm(a.position - self.scenario.runway_state[:3])) / a.speed * 2.0
                       for a in self.scenario.aircraft)
        return last + self.scales.seconds(OVERRUN_TURN_TIMES)

    def _last_planned_landing(self) -> float:
        return max((ref.end for ref in self.service.book.flying.values()), default=-math.inf)

    def run(self) -> ClosedLoopRun:
        opts = self.options
        wall0 = time.perf_counter()
        first = self._first_plan()
        t_max = self._end_time(first)
        pending: _Pending | None = None
        next_radar, next_progress = opts.radar_period_s, wall0 + PROGRESS_PERIOD_S
        hard_max = t_max + self.scales.seconds(HOLD_OVERRUN_TURN_TIMES)
        while not self.sim.done and self.sim.t < t_max:
            if self.options.max_time_s is None:  # aircraft planned late (after holding) land later
                t_max = min(max(t_max, self._last_planned_landing() + self.scales.seconds(OVERRUN_TURN_TIMES)),
                            hard_max)
            starts = [r.start_time for r, _ in self.service.book.upcoming if r.start_time < next_radar]
            if pending is not None and pending.at <= min(starts, default=next_radar):
                self.sim.advance(pending.at)
                self._arrive(pending)
                pending = None
                continue
            if starts:  # a plan that arrived earlier starts: handed out then
                self.sim.advance(min(starts))
                self._apply(self.service.due(self.sim.t))
                continue
            self.sim.advance(next_radar)
            next_radar += opts.radar_period_s
            self._radar_scan()
            if opts.progress and time.perf_counter() >= next_progress:
                next_progress = time.perf_counter() + PROGRESS_PERIOD_S
                log.info("%s", self.progress_line())
            self._apply(self.service.instruct(self.sim.t))
            reason = self.service.poll(self.sim.t)
            if reason is not None:
                tracked = sorted(self.service.intake.estimates())
                pending = self._plan(self.service.request(reason, self.sim.t), reason, tracked)
                self.replans.append(pending.record)
        return ClosedLoopRun(self.scenario, opts, self.sim, self.replans, first, time.perf_counter() - wall0,
                             self.instructions, dict(self.service.guard.counts))

    def progress_line(self) -> str:
        """Simulated time, aircraft airborne and landed, plans made: one line for a long run's log."""
        flying = len(self.sim.measurements())
        landed = len(self.sim.aircraft) - flying
        return (f"closed loop {self.scenario.name}: t = {self.sim.t:.0f} s simulated, {flying} airborne, "
                f"{landed} landed, {len(self.replans)} replans")


def run_closed_loop(scenario: Scenario, options: ClosedLoopOptions | None = None,
                    simulator: FlightSimulator | SimulatorFactory | None = None) -> ClosedLoopRun:
    """Fly ``scenario`` in closed loop (see the module docstring) in ``simulator`` (see :class:`ClosedLoop`)."""
    return ClosedLoop(scenario, options, simulator).run()


def percentile(values: list[float], q: float) -> float:
    return float(np.percentile(values, q)) if values else math.nan
