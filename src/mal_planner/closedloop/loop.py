"""The closed loop in one process: the planning service and the flight simulator, in simulated time.

This is what the planner node and the simulator node do over DDS, without the transport, so that campaigns
run hundreds of closed loops on the Dask engine. The service side is the node's: radar tracks (the simulated
aircraft, with noise) at the radar's rate; a plan request built from them by the node's own
:func:`~mal_planner.service.inputs.build_plan_scenario`; the node's :class:`~mal_planner.pipeline.Planner`
(warm-started replans and their fallbacks); a replan when an aircraft strays from its plan (or periodically).

Planning time is charged honestly: a replan requested at time t reaches the aircraft at t + (its CPU time, or
wall-clock time with ``charge="wall"``) x ``planning_time_factor``, while they go on flying the previous plan.
So that the new plan starts where they will be, it starts at t + lead (1.5 times the latest planning time,
charged), from the tracks predicted along the plans they fly: the plan's state then, moved by the deviation
measured now (as model predictive control does with a known delay). The first plan is the exception: it is made
before the simulation starts (the service was running when the traffic appeared), from the true initial states.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from mal_planner.closedloop.disturbances import RadarNoise, WindSpec
from mal_planner.closedloop.simulator import FlightSimulator, SimOptions
from mal_planner.landing.problem import SafetyMargins
from mal_planner.options import PlanOptions
from mal_planner.pipeline import Planner, PlanResult
from mal_planner.scales import Scales
from mal_planner.scenario import Scenario
from mal_planner.service.inputs import build_plan_scenario
from mal_planner.service.track_filter import DeviationFilter
from mal_planner.service.tracks import Track
from mal_planner.trajectory import Reference

log = logging.getLogger("mal_planner.closedloop")

SimulatorFactory = Callable[[Scenario, SimOptions], FlightSimulator]
"""Makes the simulator of a run (FlightSimulator itself is one; so is closedloop.bluesky_sim.BlueSkySimulator)."""

RADAR_PERIOD_S = 1.0
"""Track update period: ADS-B's 1 Hz (a terminal radar turns in 4-5 s)."""
DEVIATION_ACCURACIES = 10.0
"""Replan when a track strays this many path accuracies (turn radius / 60) from its plan (thesis: 0.05 nm, 93 m;
a terminal area at 150 kt and 30 deg: 0.09 nm). How far aircraft stray is set by their own dynamics (turn radius
and time: guidance, lag, gusts), not by the separation: sized to the separation (0.2 of it, 0.6 nm in a terminal
area), the margins of flown plans made the first terminal-area plans infeasible..."""
DEVIATION_PER_NOISE = 6.0
"""... or this many radar-noise sigmas, if more: a deviation the radar can tell from its noise."""
LEAD_PER_LATENCY = 1.5
"""A replan starts this many times the latest planning time ahead of the tracks it is made from."""
REPLAN_INTERVAL_TURN_TIMES = 1.0
"""No deviation or periodic replan sooner than this after a plan arrived (thesis: 7.6 s; terminal area 14 s)."""
PLAN_TIME_LIMIT_S = 60.0
"""Wall-clock limit of one plan (the planner node's ``planning_time_limit_s``): the best result so far then."""
TRACKING_AIRSPACE_MARGIN = 0.5
"""The airspace margin of flown plans, in path accuracies (see :func:`tracking_margins`)."""
TRACKING_AIRSPACE_BULGE = 0.1
"""How far, in path accuracies, a flown plan's path may enter its airspace margin between collocation points: the
other 0.4 are the aircraft's vertical stray (campaigns: up to 0.4). Without the check, a plan level at the ceiling
bulged 0.0021 nm into its 0.0021-nm margin, and its aircraft left the airspace by 2e-5 nm (ten aircraft,
traffic-0017)."""
BANK_RESERVE = 0.1
"""The share of the bank limit that flown plans leave to the guidance's feedback (thesis: 4.5 of 45 deg)."""
ESTABLISHED_TURN_TIMES = 2.0
"""An aircraft within this many turn times of its planned landing (thesis 15 s, one landing spacing) is left out of
replans and lands on the plan it flies: replanned from a drifted state seconds before the threshold, it got plans
that loop back along the airspace's edge (campaign: crossings 260-420 m off the centreline, 400-600 ft high)."""
OVERRUN_TURN_TIMES = 20.0
"""The run ends this long after the first plan's last landing if aircraft are still flying."""


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
    """Replan threshold; None: the larger of DEVIATION_ACCURACIES path accuracies and DEVIATION_PER_NOISE x the
    filtered radar noise."""
    planning_time_factor: float = 1.0
    """Simulated seconds charged per second of planning (1: honest; 0: planning takes no time)."""
    max_time_s: float | None = None
    """End of the run; None: the first plan's last landing plus OVERRUN_TURN_TIMES turn times."""
    replan_limit_turn_times: float = 2.0
    """Wall-clock limit of a replan in turn times (thesis 15 s, a terminal area 28 s; the first plan has the plan
    options' limit): the aircraft fly on meanwhile, and a plan much later than that finds them elsewhere."""
    track_filter_turn_times: float = 0.5
    """Time constant of the service's track filter (:mod:`mal_planner.service.track_filter`) in turn times (thesis
    3.8 s: 30 m of radar noise leave 11 m); 0: raw radar tracks."""
    charge: str = "cpu"
    """What a replan costs in simulated time: "cpu", its CPU time (what it takes on a machine of its own: campaigns
    share the cores, and wall-clock time would charge the other jobs' time too), or "wall", its wall-clock time."""
    tracking_margins: bool = True
    """Plan with safety margins sized to the deviations the replan rule lets pass (see :func:`tracking_margins`);
    False: the open-loop planner's margins (sized to the plan's own accuracy only)."""


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


@dataclass
class ClosedLoopRun:
    """The raw record of one run: the simulator (flown tracks, landings) and the service's plans."""

    scenario: Scenario
    options: ClosedLoopOptions
    sim: FlightSimulator
    replans: list[Replan]
    first: Replan
    wall_s: float


def planning_scenario(scenario: Scenario, wind: WindSpec, knows_wind: bool) -> Scenario:
    """The scenario the service plans in: the mean wind if it knows it, else still air."""
    return scenario.with_wind(tuple(wind.mean) if knows_wind else (0.0, 0.0))


def tracking_margins(margins: SafetyMargins, scales: Scales, threshold_nm: float, bank_limit_rad: float
                     ) -> SafetyMargins:
    """The optimizer's margins for plans that are flown: an aircraft may stray up to the replan threshold before
    the service replans, so the separation keeps twice that much more (two aircraft, each that far towards the other).
    Obstacles keep the open-loop margins: inflated by the threshold, the holes of the walls would leave no room (a
    0.09-nm hole against 0.05 nm). The airspace keeps :data:`TRACKING_AIRSPACE_MARGIN` path accuracies: plans ride
    the floor and the ceiling, where the flown path strays vertically by the load-factor lag (campaigns: up to 0.4
    accuracies); the runway lies on the floor, so the threshold is crossed that high (thesis 4.6 m, a terminal area
    29 ft: inside the touchdown window's 0-100 ft). Plans keep :data:`BANK_RESERVE` of the bank limit for the guidance's
    feedback: a plan that turns at the limit onto the threshold leaves none to take out an error there.
    ``bank_limit_rad``: the smallest bank limit of the scenario's aircraft."""
    return replace(margins, separation=max(margins.separation, 2.0 * threshold_nm / scales.accuracy_nm),
                   airspace=max(margins.airspace, TRACKING_AIRSPACE_MARGIN),
                   airspace_bulge=TRACKING_AIRSPACE_BULGE if margins.airspace_bulge is None else
                   min(margins.airspace_bulge, TRACKING_AIRSPACE_BULGE),
                   bank_rad=max(margins.bank_rad, BANK_RESERVE * bank_limit_rad))


class ClosedLoop:
    """One scenario flown in closed loop; :meth:`run` returns a :class:`ClosedLoopRun`."""

    def __init__(self, scenario: Scenario, options: ClosedLoopOptions | None = None,
                 simulator: FlightSimulator | SimulatorFactory | None = None) -> None:
        """``simulator``: the aircraft to fly the plans, a simulator with :class:`FlightSimulator`'s interface or a
        factory called with (scenario, options.sim); None: a :class:`FlightSimulator`."""
        self.options = opts = options or ClosedLoopOptions()
        self.scenario = scenario
        self.base = planning_scenario(scenario, opts.sim.wind, opts.planner_knows_wind)
        self.scales = Scales.of(scenario)
        if simulator is None or isinstance(simulator, FlightSimulator):
            self.sim = simulator or FlightSimulator(scenario, opts.sim)
        else:
            self.sim = simulator(scenario, opts.sim)
        seed = opts.sim.seed
        self.noise = RadarNoise(opts.radar_noise_m, None if seed is None else seed + 1)
        self.published: dict[str, Reference] = {}
        """The plan each aircraft flies now, as the service knows it."""
        self.upcoming: list[tuple[PlanResult, Replan]] = []
        """Plans arrived that start later: handed out when they start."""
        self.last_plan_at = 0.0
        """When the latest plan was handed out (or a replan failed): no deviation replan for a turn time after."""
        self.replans: list[Replan] = []
        self.filter = DeviationFilter(self.scales.seconds(opts.track_filter_turn_times), opts.radar_period_s)
        self.threshold = opts.deviation_nm if opts.deviation_nm is not None else max(
            DEVIATION_ACCURACIES * self.scales.accuracy_nm,
            DEVIATION_PER_NOISE * self.noise.sigma_nm * self.filter.noise_factor())
        plan = opts.plan
        if opts.tracking_margins:
            bank = min(a.limits.bank_angle_max for a in scenario.aircraft)
            margins = tracking_margins(plan.landing.margins, self.scales, self.threshold, bank)
            plan = replace(plan, landing=replace(plan.landing, margins=margins))
        # An aircraft this close to its landing is established on final: replans leave it on the plan it flies.
        plan = replace(plan, landed_within_turn_times=max(plan.landed_within_turn_times, ESTABLISHED_TURN_TIMES))
        self.planner = Planner(plan)
        self.min_interval = self.scales.seconds(REPLAN_INTERVAL_TURN_TIMES)

    # -- the service -------------------------------------------------------------------------------------
    def _tracks(self, truth: bool = False) -> dict[str, Track]:
        return {ac.callsign: Track(ac.callsign, self.sim.t, ac.state.copy() if truth else self.noise.apply(ac.state),
                                   ac.model.speed, ac.wake)
                for ac in self.sim.measurements()}

    def _filtered(self, tracks: dict[str, Track]) -> dict[str, Track]:
        """Radar tracks through the track filter (aircraft flying a plan; others as measured)."""
        out = {}
        for cs, tr in tracks.items():
            ref = self.published.get(cs)
            if ref is None or not ref.start <= tr.stamp <= ref.end:
                out[cs] = tr
                continue
            state = tr.state.copy()
            state[:3] = self.filter.update(cs, tr.state, ref, tr.stamp)
            out[cs] = Track(cs, tr.stamp, state, tr.speed, tr.wake)
        return out

    def _plan(self, tracks: dict[str, Track], reason: str) -> tuple[Replan, PlanResult | None]:
        t = max(tr.stamp for tr in tracks.values())
        start, cpu0 = time.perf_counter(), time.process_time()
        result: PlanResult | None = None
        try:
            inputs = build_plan_scenario(self.base, tracks, t, t)
            if not inputs.scenario.aircraft:
                raise ValueError("no aircraft to plan (" + "; ".join(f"{k}: {v}" for k, v in inputs.left_out.items())
                                 + ")")
            result = self.planner.plan(inputs.scenario, start_time=t)
            failure = result.failure
            ok, message = failure is None, "verified" if failure is None else f"{failure[0]}: {failure[1]}"
        except Exception as exc:  # the service keeps running: the aircraft keep their plans
            ok, message = False, " ".join(str(exc).split()) or type(exc).__name__
        wall, cpu = time.perf_counter() - start, time.process_time() - cpu0
        order = []
        if ok and result is not None:
            times = result.landing_times()
            order = sorted(times, key=times.__getitem__)
        charged = (cpu if self.options.charge == "cpu" else wall) * self.options.planning_time_factor
        record = Replan(t, reason, wall, t, ok, message, sorted(tracks), order, cpu, charged)
        log.info("t=%.1f s: plan (%s) %s in %.2f s (CPU %.2f s)", t, reason, "verified" if ok else f"failed: {message}",
                 wall, cpu)
        return record, (result if ok else None)

    def _predicted(self, tracks: dict[str, Track], lead: float) -> dict[str, Track]:
        """The tracks ``lead`` seconds ahead, along the plans being flown (straight on where there is none)."""
        out = {}
        for cs, tr in tracks.items():
            ref = self.published.get(cs)
            t1 = tr.stamp + lead
            if ref is None or not ref.start <= tr.stamp or t1 > ref.end:
                out[cs] = Track(cs, t1, tr.at(t1), tr.speed, tr.wake)
                continue
            now, then = ref.sample(tr.stamp), ref.sample(t1)
            state = then[:5].copy()
            state[:3] += tr.state[:3] - now[:3]
            state[3:5] += tr.state[3:5] - now[3:5]
            out[cs] = Track(cs, t1, state, tr.speed, tr.wake)
        return out

    def _deliver(self, result: PlanResult, record: Replan, at: float) -> None:
        """A plan has arrived at ``at``: it is handed out when it starts (at once if it started already)."""
        self.upcoming.append((result, record))
        self._take_up(at)

    def _take_up(self, t: float) -> None:
        """Arrived plans that start by ``t`` are handed out, unless stale: the aircraft fly them from ``t`` on, and the
        service checks the tracks against them."""
        for result, record in [u for u in self.upcoming if u[0].start_time <= t]:
            self.upcoming.remove((result, record))
            stale = self._stale(result, record, t)
            if stale is not None:  # the aircraft keep the plans they fly; the next radar update asks again
                record.ok, record.message = False, stale
                log.info("t=%.1f s: plan %s", t, stale)
                self.last_plan_at = -math.inf  # ask again at the next radar update
                continue
            for traj in result.landing.trajectories if result.landing else []:
                ref = Reference(traj.t + result.start_time, traj.states)
                self.filter.replanned(traj.callsign, self.published.get(traj.callsign), ref, t)
                self.published[traj.callsign] = ref
                self.sim.set_plan(traj.callsign, ref, t)
            self.last_plan_at = t

    def _stale(self, result: PlanResult, record: Replan, t: float) -> str | None:
        """Why a plan is not handed out when it starts (None: it is): the tracks then stray more than the replan
        threshold from it (the aircraft flew on elsewhere while it was planned: its planning took longer than the
        lead it was made with, or the prediction along the old plans was off). Handed out, it would ask for the next
        replan at once, from aircraft turning to join it."""
        worst, who = 0.0, ""
        for traj in result.landing.trajectories if result.landing else []:
            flying = self.published.get(traj.callsign)
            here = None if flying is None else self.filter.estimate(traj.callsign, flying, t)
            if here is None or not 0.0 <= t - result.start_time <= float(traj.t[-1]):
                continue
            dev = float(np.linalg.norm(traj.state_at(np.array([t - result.start_time]))[0, :3] - here))
            if dev > worst:
                worst, who = dev, traj.callsign
        if worst <= self.threshold:
            return None
        return (f"stale: {who} {worst:.3f} nm from it when it starts, {t - record.t:.1f} s after the tracks it was "
                f"made from (threshold {self.threshold:.3f} nm); not handed out")

    def _trigger(self, tracks: dict[str, Track], since_last: float) -> str | None:
        if since_last < self.min_interval or self.upcoming:
            return None
        for cs in tracks:
            if cs not in self.published:
                return f"{cs} has no plan"
        worst, who = 0.0, ""
        for cs, tr in tracks.items():
            ref = self.published[cs]
            # Within a replan interval of its landing a new plan would come too late to help (past its end an
            # aircraft is about to cross the threshold): it flies on.
            if ref.start <= tr.stamp <= ref.end - self.min_interval:
                dev = float(np.linalg.norm(ref.position(tr.stamp) - tr.state[:3]))
                if dev > worst:
                    worst, who = dev, cs
        if worst > self.threshold:
            return f"{who} deviates {worst:.3f} nm from its plan"
        if self.options.replan_period_s > 0 and since_last >= self.options.replan_period_s:
            return "periodic replan"
        return None

    # -- the run ---------------------------------------------------------------------------------------------
    def run(self) -> ClosedLoopRun:
        opts = self.options
        wall0 = time.perf_counter()
        first, result = self._plan(self._tracks(truth=True), "initial plan")
        replan_limit = self.scales.seconds(opts.replan_limit_turn_times)
        limit = self.planner.options.time_limit_s
        self.planner.options = replace(self.planner.options,
                                       time_limit_s=replan_limit if limit is None else min(limit, replan_limit))
        if result is not None:
            self._deliver(result, first, 0.0)
        t_max = opts.max_time_s
        if t_max is None:
            last = max(result.landing_times().values()) if result is not None else max(
                float(np.linalg.norm(a.position - self.scenario.runway_state[:3])) / a.speed * 2.0
                for a in self.scenario.aircraft)
            t_max = last + self.scales.seconds(OVERRUN_TURN_TIMES)
        pending: tuple[float, Replan, PlanResult | None] | None = None
        next_radar = opts.radar_period_s
        while not self.sim.done and self.sim.t < t_max:
            starts = [u[0].start_time for u in self.upcoming if u[0].start_time < next_radar]
            if pending is not None and pending[0] <= min(starts, default=next_radar):
                self.sim.advance(pending[0])
                arrived, record, result = pending
                pending = None
                self.last_plan_at = arrived  # a failed replan too: the next one no sooner than a turn time later
                if result is not None:
                    self._deliver(result, record, arrived)
                continue
            if starts:  # a plan that arrived earlier starts: handed out then
                self.sim.advance(min(starts))
                self._take_up(self.sim.t)
                continue
            self.sim.advance(next_radar)
            next_radar += opts.radar_period_s
            tracks = self._filtered(self._tracks())
            if pending is not None:
                continue
            reason = self._trigger(tracks, self.sim.t - self.last_plan_at) if tracks else None
            if reason is None:
                continue
            lead = LEAD_PER_LATENCY * (self.replans[-1] if self.replans else first).charged_s
            t_request = self.sim.t
            record, result = self._plan(self._predicted(tracks, lead) if lead > 0 else tracks, reason)
            record.arrived_at = t_request + record.charged_s
            self.replans.append(record)
            pending = (record.arrived_at, record, result)
        return ClosedLoopRun(self.scenario, opts, self.sim, self.replans, first, time.perf_counter() - wall0)


def run_closed_loop(scenario: Scenario, options: ClosedLoopOptions | None = None,
                    simulator: FlightSimulator | SimulatorFactory | None = None) -> ClosedLoopRun:
    """Fly ``scenario`` in closed loop (see the module docstring) in ``simulator`` (see :class:`ClosedLoop`)."""
    return ClosedLoop(scenario, options, simulator).run()


def percentile(values: list[float], q: float) -> float:
    return float(np.percentile(values, q)) if values else math.nan
