"""The planning service without ROS: what the planner node runs and what the closed-loop simulation flies.

:class:`PlanningService` holds the radar intake, the replan policy, the plan book and the inputs of the plans, on
one clock (the radar's). Its caller only moves data and time: it feeds tracks (:meth:`~PlanningService.take_track`),
asks on its own schedule whether to plan (:meth:`~PlanningService.poll`), makes the request
(:meth:`~PlanningService.request`) and runs it with a :class:`~mal_planner.pipeline.Planner` however it likes
(in a child process, in simulated time), reports how it ended (:meth:`~PlanningService.finish`) and acts on the
events: plans handed out, kept, stale or withdrawn (:mod:`mal_planner.service.book`). Thread-safe.
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Mapping
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from mal_planner.obstacles import Superquadric
from mal_planner.options import PlanOptions, scenario_for
from mal_planner.scales import Scales
from mal_planner.scenario import Scenario
from mal_planner.service.book import Event, PlanBook
from mal_planner.service.guard import Guard
from mal_planner.service.inputs import apply_zone, build_plan_scenario
from mal_planner.service.intake import TrackIntake, Verdict
from mal_planner.service.policy import ReplanPolicy, wind_change_reason
from mal_planner.service.request import PlanRequest
from mal_planner.service.rules import (
    LEAD_PER_LATENCY,
    ServiceRules,
    established_window_s,
    replan_time_limit,
    service_plan_options,
)
from mal_planner.service.subsets import joining_traffic, traffic_for
from mal_planner.service.tracks import Track
from mal_planner.trajectory import Reference
from mal_planner.units import nm_per_s_to_kt

if TYPE_CHECKING:
    from mal_planner.pipeline import PlanResult

log = logging.getLogger("mal_planner.service")

ESCALATION_FACTOR = 8.0
"""A replan's time limit doubles after each failure in a row, up to this factor (a terminal area 224 s, the thesis
120 s)."""




class PlanningService:
    """The service's rules over one scenario (see the module docstring)."""

    def __init__(self, scenario: Scenario, rules: ServiceRules, options: PlanOptions | None = None, *,
                 flown: bool = False) -> None:
        """``scenario``: what the service knows of the airspace and the aircraft; ``flown``: the plans are flown
        by aircraft the service watches (plans then keep the margins of flown plans)."""
        self._lock = threading.RLock()
        self.scenario = scenario
        self.rules = rules
        self.flown = flown
        self.obstacles = scenario.obstacles
        self.wind: tuple[float, float] = scenario.wind
        self._given_options = options or PlanOptions()
        self.options = service_plan_options(self._given_options, scenario, rules, flown=flown)
        self.book = PlanBook(rules, self._estimate, search_s=Scales.of(scenario).time_s,
                             follow_nm=0.5 * scenario.separation_nm, established_s=established_window_s(scenario))
        self.intake = TrackIntake(scenario, rules, plan_of=self.book.instruction)
        self.guard = Guard.of(self._guarded(), rules.deviation_nm)
        self.book.on_handout = self.intake.filter.replanned
        self.policy = ReplanPolicy(rules, established_window_s(scenario))
        self.latency_s = 0.0
        """The latest plan's planning time (a replan starts LEAD_PER_LATENCY times this ahead)."""
        self.epoch: float | None = None
        """The scenario's times (fixed landing times) count from here: the first track or the first plan."""
        self.asked = False
        """A plan was asked for since the last one ended (by the policy or a caller)."""
        self.planned = False
        self.in_flight: PlanRequest | None = None
        self.failures_in_a_row = 0
        """Plans that failed (or were refused) since the last one handed out: the next replan gets more time."""
        self.local_failed = False
        """The last plan that ended was of some aircraft among the others' plans, and it failed: a whole one next."""

    def _estimate(self, callsign: str, plan: Reference, t: float) -> np.ndarray | None:
        return self.intake.filter.estimate(callsign, plan, t)

    # -- radar --------------------------------------------------------------------------------------------------
    def take_track(self, track: Track, frame_id: str, source: str, clock: float, stamp_now: float | None = None
                   ) -> Verdict:
        with self._lock:
            verdict = self.intake.take(track, frame_id, source, clock, stamp_now)
            if verdict.accepted and self.epoch is None:
                self.epoch = track.stamp
            return verdict

    def lose_tracks(self) -> list[Event]:
        """Forget aircraft not seen for the track timeout; withdraw their plans."""
        with self._lock:
            gone = self.intake.lose_tracks()
            for cs in gone:
                log.info("aircraft %s not seen for %g s: dropped", cs, self.rules.track_timeout_s)
            if not gone:
                return []
            withdrawn = self.book.withdraw(gone, f"track lost (not seen for {self.rules.track_timeout_s:g} s)")
            return [withdrawn] if withdrawn.callsigns else []

    # -- decisions ----------------------------------------------------------------------------------------------
    @property
    def busy(self) -> bool:
        return self.asked or self.in_flight is not None or bool(self.book.upcoming)

    def poll(self, now: float) -> str | None:
        """Why the service should plan now (the policy), or None; a reason counts as asked until :meth:`finish`."""
        with self._lock:
            first = self.intake.first_seen
            reason = self.policy.decide(now, self.intake.estimates(), self.book.flying, busy=self.busy,
                                        planned=self.planned, last_arrival=self.book.last_arrival,
                                        first_track_at=None if first is None else first[1])
            if reason is not None:
                self.asked = True
            return reason

    def ask(self) -> None:
        """A caller (a service call) asks for a plan of the radar picture: the policy waits for it."""
        with self._lock:
            self.asked = True

    def request(self, reason: str, now: float, *, tracks: Mapping[str, Track] | None = None, lead: bool = True,
                what_if: bool = False) -> PlanRequest | str:
        """The plan to make now for ``reason``, or why there is none (one line; the caller then reports
        :meth:`refused`). From the radar's filtered tracks, predicted along the plans being flown to when the plan is
        expected to reach the aircraft: now, plus :data:`LEAD_PER_LATENCY` latest planning times with ``lead`` (the
        policy's replans); or from ``tracks`` as they are stamped. A what-if request is answered, never handed
        out."""
        with self._lock:  # a consistent picture; the scenario is built outside the lock (it takes a while)
            given = tracks is not None
            current = dict(tracks) if given else self.intake.estimates()  # type: ignore[arg-type]
            minimum = 1 if given else self.rules.min_aircraft
            if len(current) < minimum:
                return f"{len(current)} aircraft tracked (min_aircraft {self.rules.min_aircraft}): nothing to plan"
            base, options = self.base_scenario(), self.options
            if self.planned or what_if:
                options = replace(options, time_limit_s=self._replan_limit(options, what_if))
            if given:  # explicit states (a what-if, the closed loop's truth at its start): as they are stamped
                plan_start = max(t.stamp for t in current.values())
            else:  # the radar's: predicted to when the plan is expected to reach the aircraft
                lead_s = LEAD_PER_LATENCY * self._expected_latency(options.time_limit_s) if lead else 0.0
                plan_start = max(now, *(t.stamp for t in current.values())) + lead_s
                current = self.book.predicted(current, plan_start)
            if self.epoch is None and not what_if:
                self.epoch = plan_start
            shift = 0.0 if self.epoch is None else max(0.0, plan_start - self.epoch)
            if not what_if:
                self.planned = True
            straying = self._local(self.policy.straying, reason, given or what_if)
            joining = self._local(self.policy.joining, reason, given or what_if)
            instructions, flying = self.book.instructions(), dict(self.book.flying)
        inputs = build_plan_scenario(base, current, plan_start, shift)
        for cs, why in inputs.left_out.items():
            log.warning("aircraft %s left out of the plan: %s", cs, why)
        if not inputs.scenario.aircraft:
            return "no aircraft to plan (all left out)"
        traffic = None
        if straying is not None and not inputs.left_out:
            traffic = traffic_for(straying, inputs.scenario, instructions, flying, plan_start)
        elif joining is not None and not inputs.left_out:
            traffic = joining_traffic(joining, inputs.scenario, flying, plan_start)
        if traffic is not None:
            mine = tuple(a for a in inputs.scenario.aircraft if a.callsign in traffic.callsigns)
            inputs = replace(inputs, scenario=replace(inputs.scenario, aircraft=mine))
            log.info("%s: %s among %d aircraft that keep their instructions",
                     "plan of the aircraft without one" if traffic.joining else "replan of what changed",
                     ", ".join(traffic.callsigns), len(traffic.fixed))
        req = PlanRequest(reason, now, plan_start, inputs, options, what_if, given, traffic)
        if not what_if:
            with self._lock:
                self.in_flight, self.asked = req, False
        return req

    def _local(self, decided: tuple[str, set[str]] | None, reason: str, explicit: bool) -> set[str] | None:
        """The aircraft a plan of some among the others serves (:attr:`ServiceRules.replan_what_changed`): those the
        policy ``decided`` for ``reason`` (:attr:`ReplanPolicy.straying`, :attr:`ReplanPolicy.joining`), unless such
        a plan failed last (then a whole one) or the states are explicit."""
        if not self.rules.replan_what_changed or explicit or self.local_failed or decided is None:
            return None
        return decided[1] if decided[0] == reason else None

    def _replan_limit(self, options: PlanOptions, what_if: bool) -> float | None:
        """A replan's time limit: the rules' (:func:`replan_time_limit`), doubled after each failure in a row up to
        :data:`ESCALATION_FACTOR` times it: a replan that fails for time would fail alike forever (20 aircraft planned
        afresh take a minute), and the aircraft are safe meanwhile (on their plans, holding, or vectored)."""
        limit = replan_time_limit(options, self.rules)
        if limit is None or what_if:
            return limit
        return limit * min(2.0 ** self.failures_in_a_row, ESCALATION_FACTOR)

    def _expected_latency(self, limit_s: float | None) -> float:
        """The latest planning time, at most this plan's limit (a first plan of many aircraft takes minutes: a replan
        started that far ahead would keep every replan waiting)."""
        return self.latency_s if limit_s is None or not math.isfinite(limit_s) else min(self.latency_s, limit_s)

    def instruct(self, now: float) -> list[Event]:
        """After a radar scan: a hold for each aircraft without a plan, the safety net's vectors where the planner
        has no plan in time (:mod:`mal_planner.service.guard`). Not with a deviation threshold of 0 (radar tracks
        that do not follow the plans, e.g. a recording replayed)."""
        with self._lock:
            tracks = self.intake.estimates()
            if not tracks or not self.planned or self.rules.deviation_nm <= 0:  # 0: tracks that follow no plan
                return []
            tracks = self.book.predicted(tracks, now)  # holds and vectors start where the aircraft are now, not
            # where the last scan saw them (a node's clock runs ahead of its tracks by up to a scan, more if loaded)
            starts = [r.start_time for r, _ in self.book.upcoming]
            coming = {a.callsign for r, _ in self.book.upcoming for a in r.scenario.aircraft}
            if self.in_flight is not None:
                starts.append(self.in_flight.plan_start)
                coming |= {a.callsign for a in self.in_flight.inputs.scenario.aircraft}
            return list(self.guard.instruct(tracks, self.book, now, min(starts, default=None), coming))

    def safety_net_status(self) -> dict[str, Any]:
        """The service's own instructions so far (holds, the net's alerts, uses and vectors) and who flies one now."""
        with self._lock:
            counts = self.guard.counts
            return {"holds": counts["holds"], "vectors": counts["vectors"], "net_alerts": counts["alerts"],
                    "net_uses": counts["uses"],
                    "fallbacks": {cs: fb.kind for cs, fb in sorted(self.book.fallbacks.items())}}

    def refused(self, now: float, latency_s: float | None = None) -> None:
        """A radar request was refused (:meth:`request` said why), or its planning broke down, at ``now``,
        ``latency_s`` after it was asked: the policy backs off as after a failed plan, but the plans flown are not
        marked as kept."""
        with self._lock:
            self.local_failed = self.in_flight is not None and self.in_flight.traffic is not None
            self.asked, self.planned, self.in_flight = False, True, None
            self.failures_in_a_row += 1
            self.book.last_arrival = now
            if latency_s is not None:
                self.latency_s = latency_s

    def finish(self, request: PlanRequest, result: PlanResult | None, failure: str | None, now: float,
               latency_s: float) -> list[Event]:
        """A plan ended at ``now`` after ``latency_s`` (the caller's measure: wall or CPU time, simulated or not):
        ``result`` None or ``failure`` set: it failed (the aircraft keep their plans). A what-if plan changes
        nothing."""
        with self._lock:
            if request.what_if:
                return []
            self.in_flight = None
            self.latency_s = latency_s
            self.local_failed = request.traffic is not None and (result is None or failure is not None)
            if result is None or failure is not None:
                self.failures_in_a_row += 1
                kept = self.book.failed(failure or "no result", now)
                return [kept] if kept is not None else []
            self.failures_in_a_row = self.failures_in_a_row + 1 if result.unplanned else 0  # partial: more time
            return self.book.arrive(request, result, now, set(self.intake.store.snapshot()))

    def due(self, now: float) -> list[Event]:
        """Plans that start by ``now`` handed out (unless stale); kept plans past their expiry withdrawn."""
        with self._lock:
            return self.book.due(now, set(self.intake.store.snapshot()))

    # -- the airspace and the wind --------------------------------------------------------------------------------
    def base_scenario(self) -> Scenario:
        """The scenario plans start from: the file's, with the no-fly zones and the wind given since, and the options'
        wake table and sequencing strategy (:func:`~mal_planner.options.scenario_for`)."""
        with self._lock:
            return scenario_for(self.options, self._guarded())

    def _guarded(self) -> Scenario:
        """The file's scenario with the no-fly zones and the wind given since (what the guard watches)."""
        base = replace(self.scenario, obstacles=self.obstacles)
        return base if self.wind == base.wind else base.with_wind(self.wind)

    def update_zone(self, name: str, zone: Superquadric | None) -> str:
        """Add, replace (``zone``) or remove (None) a no-fly zone; returns what changed (ValueError: no such zone)."""
        with self._lock:
            self.obstacles, what = apply_zone(self.obstacles, name, zone)
            self.guard.update(self._guarded())
            return what

    def update_wind(self, wind: tuple[float, float]) -> tuple[str, str | None]:
        """A new wind (nm/s, local frame): the next plans are made in it. Returns the wind in words ('' when it did
        not change) and the reason to plan now, if it matters (see
        :func:`~mal_planner.service.policy.wind_change_reason`); ValueError when it is not below the slowest
        airspeed."""
        speed = math.hypot(*wind)
        slowest = min((a.speed for a in self.scenario.aircraft), default=math.inf)
        if speed >= slowest:
            raise ValueError(f"{nm_per_s_to_kt(speed):.0f} kt is not below the slowest airspeed "
                             f"({nm_per_s_to_kt(slowest):.0f} kt)")
        with self._lock:
            old, self.wind = self.wind, (float(wind[0]), float(wind[1]))
            if self.wind == old:
                return "", None
            self.guard.update(self._guarded())
            heading = math.degrees(math.atan2(-wind[1], -wind[0])) % 360.0 if speed > 0 else 0.0
            what = f"wind {nm_per_s_to_kt(speed):.1f} kt from heading {heading:.0f} deg ({self.rules.frame_id})"
            return what, wind_change_reason(old, self.wind, self.rules, what) if self.book.flying else None

    def set_options(self, options: PlanOptions) -> None:
        with self._lock:
            self._given_options = options
            self.options = service_plan_options(options, self.scenario, self.rules, flown=self.flown)

    def set_rules(self, rules: ServiceRules) -> None:
        with self._lock:
            self.rules = rules
            self.intake.rules = rules
            self.intake.filter.time_constant_s = rules.filter_time_constant_s
            self.book.rules = rules
            self.policy.rules = rules
            self.guard = Guard.of(self._guarded(), rules.deviation_nm)
            self.options = service_plan_options(self._given_options, self.scenario, rules, flown=self.flown)

    def radar_now(self, clock: float) -> float | None:
        with self._lock:
            return self.intake.radar_now(clock)


__all__ = ["PlanRequest", "PlanningService"]
