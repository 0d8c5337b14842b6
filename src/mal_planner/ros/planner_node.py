"""The planner node: radar tracks in, conflict-free landing plans out (paths, LandingPlan, markers).

    python -m mal_planner.ros.planner_node --scenario scenarios/thesis.yaml --params config/planner.params.yaml

Threads: the node "planner" is spun on the main thread; its topic and timer callbacks only convert
messages and schedule work; plans run on a worker thread (a request while planning is coalesced into one
follow-up plan); the services are reentrant (the transport runs them beside the other callbacks), so a
service call that waits for its plan never blocks the radar callbacks.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import signal
import sys
import threading
import time
from collections import Counter, deque
from concurrent.futures import Future
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from mal_planner.campaign.outcome import classify
from mal_planner.dynamics import bank_angle
from mal_planner.errors import outcome_code
from mal_planner.options import PlanOptions
from mal_planner.pipeline import PlanResult
from mal_planner.ros.convert import (
    aircraft_state_to_planner,
    byte_field,
    frame_origin_fields,
    geodetic_path_fields,
    path_msg,
    time_to_msg,
    wind_to_planner,
)
from mal_planner.ros.markers import marker_array
from mal_planner.ros.node_params import NodeParams, declare_parameters, describe, read_params_file, update_params
from mal_planner.ros.plan_process import LOG_FORMAT, PlanProcess
from mal_planner.ros.transport import QOS_DEFAULT, QOS_LATCHED, QoSProfile, create_node
from mal_planner.scales import Scales
from mal_planner.scenario import Scenario, ScenarioError, load_scenario
from mal_planner.service.inputs import NoFlyZoneError, PlanInputs, apply_no_fly_zone, build_plan_scenario
from mal_planner.service.tracks import AHEAD_TOLERANCE_S, CALLSIGN_RE, Track, TrackStore, check_track
from mal_planner.trajectory import Trajectory
from mal_planner.units import METRES_PER_NM, nm_per_s_to_kt

NODE_NAME = "planner"
STATE_TYPE = "mal_msgs/msg/AircraftState"
STATUS_FILE = "planner_status.json"
TICK_S = 0.2
RADAR_STATUS_PERIOD_S = 1.0  # the radar status on diagnostics, as diagnostic_updater's default rate
RADAR_DEPTH = 1000
"""History of the radar subscriptions: a burst of new callsigns waits here while their topics are made."""
JUMP_CONFIRM = 3
"""Consistent jumps in a row after which a track is taken as re-initialised (else it would stay frozen)."""
REPO = Path(__file__).resolve().parents[3]
# mal_msgs/AircraftPlan status constants and diagnostic_msgs/DiagnosticStatus levels
OPTIMAL, INITIAL_GUESS, FAILED = 0, 1, 2
DIAG_OK, DIAG_WARN, DIAG_ERROR = 0, 1, 2

log = logging.getLogger("mal_planner.ros.planner")


@dataclass
class PlanJob:
    """Work for the worker: radar-based (``explicit`` None, coalesced) or with explicit states."""

    reasons: list[str]
    explicit: dict[str, Track] | None = None
    waiters: list[Future[PlanOutcome]] = field(default_factory=list)


@dataclass
class PlanOutcome:
    success: bool
    message: str
    plan_msg: Any = None
    path_msgs: list[Any] = field(default_factory=list)
    result: PlanResult | None = None
    failure_class: str | None = None
    """None, or why the plan failed or is not verified (mal_planner.errors.OUTCOMES)."""

    @property
    def error_code(self) -> int:
        return outcome_code(self.failure_class).error_code


@dataclass(frozen=True)
class CurrentPlan:
    """The last published plan (radar deviation checks compare against it)."""

    plan_start: float
    trajectories: dict[str, Trajectory]
    landing_abs: dict[str, float]
    """Landing times [s, radar clock] per callsign."""
    considered: frozenset[str]
    """Callsigns tracked when it was planned (a new one triggers a replan)."""
    from_radar: bool


def _dedupe(traj: Trajectory) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Samples with strictly increasing times (a phase boundary appears twice in optimizer output)."""
    keep = np.concatenate([[True], np.diff(traj.t) > 1e-9])
    bank = None if traj.controls is None else bank_angle(traj.controls[keep, 0], traj.controls[keep, 1])
    return traj.t[keep], traj.states[keep], bank


def _aircraft_verified(result: PlanResult, callsign: str) -> bool:
    rep = result.verification
    if rep is None:
        return False
    return rep.aircraft_verified(callsign)


class PlannerNode:
    """Owns the node, the track store, the planner and the worker thread."""

    def __init__(self, scenario: Scenario, *, params_file: str | Path | None = None, output_dir: str | None = None,
                 namespace: str = "", backend: str = "auto") -> None:
        overrides = read_params_file(params_file, NODE_NAME, namespace, log)
        if output_dir is not None:
            overrides["output_dir"] = output_dir
        self.node = create_node(NODE_NAME, namespace, backend=backend, parameter_overrides=overrides)
        self.params: NodeParams = declare_parameters(self.node, str(params_file or "defaults"), log)
        self.types = self.node.types
        self.scenario = scenario
        self.obstacles = scenario.obstacles
        self.wind: tuple[float, float] = scenario.wind
        """The wind plans are made in (nm/s, local frame): the scenario's until a message on ``wind`` says otherwise."""
        self._planning = PlanProcess()  # started now: it loads CasADi while the radar settles
        self._planning_options: PlanOptions | None = None
        self.tracks = TrackStore()
        self.out_dir = Path(self.params.output_dir) if self.params.output_dir else None
        self._lock = threading.Condition()
        self._explicit: deque[PlanJob] = deque()
        self._radar_job: PlanJob | None = None
        self._busy = False
        self._stop = False
        self._current: CurrentPlan | None = None
        self._last_result: PlanResult | None = None
        self._plans = 0
        self._attempts = 0
        self._last_error = ""
        self._epoch: float | None = None
        self._first_rx: float | None = None
        self._initial_requested = False
        self._last_done = -math.inf
        self._bad_inputs: dict[str, float] = {}
        self._path_pubs: dict[str, Any] = {}
        self._state_subs: dict[str, Any] = {}
        self._published_paths: set[str] = set()
        self._new_aircraft: list[str] = []  # seen in a radar callback, their topics are made in the tick
        self._radar: Counter[str] = Counter()  # intake counts for the radar status
        self._rejected_reported = 0
        self._radar_status_at = -math.inf
        # Scheduling (settle time, replan intervals, how far radar time may run ahead) follows the node's clock with
        # use_sim_time (a simulator's /clock, which may run faster than the wall clock), else the monotonic clock.
        self._clock = self.node.now if self.node.uses_sim_time else time.monotonic
        self._newest_rx = self._clock()  # when the newest radar stamp arrived
        self._jumps: dict[str, tuple[Track, int]] = {}  # a refused jump and how many agree with it
        self._diag_lock = threading.Lock()
        self._plan_status: Any = None
        self._pub_lock = threading.RLock()  # the worker publishes plans, the executor withdraws lost aircraft
        self._plan_msg: Any = None  # the last published LandingPlan
        self._kept_at: float | None = None  # node clock at the first failed replan since the published plan
        self._setup_ros()
        self.node.forward_logs(logging.getLogger("mal_planner"))  # the planner's log lines on /rosout
        self.node.add_on_set_parameters_callback(self._on_set_parameters)
        self._worker = threading.Thread(target=self._work, name="planner-worker", daemon=True)
        log.info("planner ready: scenario %s (%d aircraft known, %d obstacles), %s", scenario.source,
                 len(scenario.aircraft), len(scenario.obstacles), describe(self.params))

    # -- set-up -------------------------------------------------------------------------------------
    def _setup_ros(self) -> None:
        node = self.node
        # Deep history: a burst of messages waits while the executor is busy (e.g. making new aircraft's topics).
        self.radar_qos = QoSProfile(depth=RADAR_DEPTH, reliable=self.params.radar_qos != "sensor_data")
        self.plan_pub = node.create_publisher("mal_msgs/msg/LandingPlan", "landing_plan", QOS_LATCHED)
        self.marker_pub = node.create_publisher("visualization_msgs/msg/MarkerArray", "planner/markers", QOS_LATCHED)
        self.diag_pub = node.create_publisher("diagnostic_msgs/msg/DiagnosticArray", "diagnostics", QOS_LATCHED)
        for ac in self.scenario.aircraft:
            self._ensure_aircraft(ac.callsign)
        node.create_subscription(STATE_TYPE, "radar/tracks", lambda m: self._on_state(m, "radar/tracks"),
                                 self.radar_qos)
        node.create_subscription("mal_msgs/msg/NoFlyZone", "airspace/no_fly_zones", self._on_no_fly_zone, QOS_DEFAULT)
        node.create_subscription("geometry_msgs/msg/Vector3Stamped", "wind", self._on_wind, QOS_DEFAULT)
        self._plan_status = self._diag_status(None, "no plan yet", values={"plans": 0, "status": "NONE"})
        node.create_timer(TICK_S, self._tick)
        # Reentrant: a service call waits for its plan without holding up the radar callbacks.
        node.create_service("std_srvs/srv/Trigger", "plan", self._srv_trigger, reentrant=True)
        node.create_service("mal_msgs/srv/PlanLanding", "plan_landing", self._srv_plan_landing, reentrant=True)
        self._publish_markers([], 0.0)

    def _ensure_aircraft(self, callsign: str) -> None:
        """Per-aircraft state subscription and path publisher (executor thread only)."""
        if callsign in self._state_subs:
            return
        topic = f"aircraft/{callsign}/state"
        self._state_subs[callsign] = self.node.create_subscription(
            STATE_TYPE, topic, lambda m: self._on_state(m, topic), self.radar_qos)
        self._path_pubs[callsign] = self.node.create_publisher("nav_msgs/msg/Path", f"aircraft/{callsign}/path",
                                                               QOS_LATCHED)

    def _on_set_parameters(self, params: list[Any]) -> tuple[bool, str]:
        """Parameters set at run time (ros2 param set): checked by node_params, applied at once; a refused
        value leaves every parameter as it was and the reason goes back to the caller."""
        changes = {p.name: p.value for p in params}
        try:
            new = update_params(self.params, changes)
        except ValueError as exc:
            log.error("parameter update refused: %s", exc)
            return False, str(exc)
        with self._lock:
            self.params = new
            self.out_dir = Path(new.output_dir) if new.output_dir else None
        log.info("parameters updated: %s", describe(changes))
        return True, ""

    def _plan_options(self) -> PlanOptions:
        """The parameters' plan options; with ``tracking_margins`` the closed loop's margins for plans that are
        flown (:func:`mal_planner.closedloop.loop.tracking_margins`, sized to ``deviation_threshold_m``)."""
        options = self.params.plan_options()
        if not self.params.tracking_margins:
            return options
        from mal_planner.closedloop.loop import tracking_margins

        bank = min((a.limits.bank_angle_max for a in self.scenario.aircraft),
                   default=self.scenario.config.limits.to_limits().bank_angle_max)
        margins = tracking_margins(options.landing.margins, Scales.of(self.scenario),
                                   self.params.deviation_threshold_m / METRES_PER_NM, bank)
        return replace(options, landing=replace(options.landing, margins=margins))

    def _scenario_speed(self, callsign: str) -> float | None:
        """The scenario's speed of a known aircraft [nm/s] (None for one it does not know)."""
        try:
            return float(self.scenario.aircraft_by_callsign(callsign).speed)
        except KeyError:
            return None

    # -- executor-thread callbacks (cheap) ----------------------------------------------------------
    def _bad(self, key: str, text: str) -> None:
        """Log bad input once per key (topic, callsign, reason) and 5 s (a 10 Hz stream of bad data gives one
        line, not a flood; every refusal is counted on the radar status)."""
        now = time.monotonic()
        if now - self._bad_inputs.get(key, -math.inf) >= 5.0:
            self._bad_inputs[key] = now
            log.error("%s", text)

    def _reject(self, key: str, log_key: str, text: str) -> None:
        self._radar["rejected"] += 1
        self._radar[f"rejected.{key}"] += 1
        self._bad(log_key, text)

    def _on_state(self, msg: Any, topic: str) -> None:
        self._radar["received"] += 1
        try:
            callsign, stamp, state, speed, wake = aircraft_state_to_planner(msg)
            track = Track(callsign, stamp, state, speed, wake)
            newest = self.tracks.latest_stamp()
            ahead = None if newest is None else AHEAD_TOLERANCE_S + self._clock() - self._newest_rx
            reason = check_track(track, str(msg.header.frame_id), self.params.frame_id, self.scenario.airspace,
                                 expected_speed=self._scenario_speed(callsign), newest=newest,
                                 timeout_s=self.params.track_timeout_s, now=self.node.now(), max_ahead_s=ahead,
                                 previous=self.tracks.get(callsign), jump_tol_nm=self.scenario.separation_nm)
        except Exception as exc:  # malformed message
            self._reject("malformed", topic, f"bad AircraftState on {topic}: {exc} (ignored)")
            return
        if reason is not None and reason.key == "jump" and self._jump_confirmed(track):
            log.warning("track of %s re-initialised: %d jumps in a row agree (%s)", callsign, JUMP_CONFIRM, reason)
            reason = None
        if reason is not None:
            self._reject(reason.key, f"{topic}:{callsign}:{reason.key}",
                         f"bad AircraftState on {topic} for {callsign!r} at t={stamp:.3f}: {reason} (ignored)")
            return
        self._jumps.pop(callsign, None)
        stored = self.tracks.update(track)
        if stored == "conflict":
            self._reject("conflict", f"{topic}:{callsign}:conflict", f"bad AircraftState on {topic} for "
                         f"{callsign!r} at t={stamp:.3f}: another state with the same stamp (ignored)")
        if stored != "stored":
            self._radar[stored] += 1  # older, duplicate (the same track on two topics) or conflict
            return
        self._radar["accepted"] += 1
        if newest is None or stamp > newest:
            self._newest_rx = self._clock()
        if callsign not in self._state_subs and callsign not in self._new_aircraft:
            log.info("new aircraft %s on %s (wake %s)", callsign, topic, wake or "?")
            self._new_aircraft.append(callsign)  # its topics are made in the tick, not in this callback
        if self._first_rx is None:
            self._first_rx = self._clock()
            self._epoch = stamp
            log.info("first radar message (%s, t=%.3f); first plan in %.1f s", callsign, stamp,
                     self.params.settle_time_s)
        self._check_deviation(track)

    def _jump_confirmed(self, track: Track) -> bool:
        """A refused jump: True once ``JUMP_CONFIRM`` refused tracks in a row agree with each other (the track
        was re-initialised, not a glitch), so that a bad jump never freezes an aircraft for good."""
        pending = self._jumps.get(track.callsign)
        agree = pending is not None and check_track(
            track, self.params.frame_id, self.params.frame_id, previous=pending[0],
            jump_tol_nm=self.scenario.separation_nm) is None
        count = pending[1] + 1 if agree and pending is not None else 1
        self._jumps[track.callsign] = (track, count)
        return count >= JUMP_CONFIRM

    def _check_deviation(self, track: Track) -> None:
        cur = self._current
        if cur is None or not cur.from_radar or self._busy or self._pending():
            return
        if self._clock() - self._last_done < self.params.min_replan_interval_s:
            return
        traj = cur.trajectories.get(track.callsign)
        if traj is None:
            if track.callsign not in cur.considered:
                self.request(f"new aircraft {track.callsign}")
            return
        thr = self.params.deviation_threshold_m
        dt = track.stamp - cur.plan_start
        if thr <= 0 or dt < 0 or dt > traj.t[-1]:
            return
        dev = float(np.linalg.norm(traj.state_at(dt)[:3] - track.state[:3])) * METRES_PER_NM
        if dev > thr:
            self.request(f"{track.callsign} deviates {dev:.0f} m from the plan")

    def _on_no_fly_zone(self, msg: Any) -> None:
        try:
            with self._lock:
                self.obstacles, what = apply_no_fly_zone(self.obstacles, msg)
        except (NoFlyZoneError, AttributeError, TypeError, ValueError) as exc:
            log.error("bad NoFlyZone on airspace/no_fly_zones: %s (ignored)", exc)
            return
        log.info("%s (%d obstacles)", what, len(self.obstacles))
        cur = self._current
        self._publish_markers(list(cur.trajectories.values()) if cur else [], cur.plan_start if cur else 0.0)
        if len(self.tracks) >= self.params.min_aircraft and self._initial_requested:
            self.request(what)

    def _on_wind(self, msg: Any) -> None:
        """A wind estimate or forecast (m/s, ENU in ``frame_id``): the next plans are made in it; a change that
        would move an aircraft by the deviation threshold within the replan interval asks for a replan now."""
        try:
            wind = wind_to_planner(msg, self.params.frame_id)
            speed = math.hypot(*wind)
            slowest = min((a.speed for a in self.scenario.aircraft), default=math.inf)
            if speed >= slowest:
                raise ValueError(f"{nm_per_s_to_kt(speed):.0f} kt is not below the slowest airspeed "
                                 f"({nm_per_s_to_kt(slowest):.0f} kt)")
        except (AttributeError, TypeError, ValueError) as exc:
            self._bad("wind", f"bad wind on wind: {exc} (ignored)")
            return
        with self._lock:
            change = math.hypot(wind[0] - self.wind[0], wind[1] - self.wind[1])
            self.wind = wind
        if change == 0.0:
            return
        heading = math.degrees(math.atan2(-wind[1], -wind[0])) % 360.0 if speed > 0 else 0.0
        what = f"wind {nm_per_s_to_kt(speed):.1f} kt from heading {heading:.0f} deg ({self.params.frame_id})"
        log.info("%s", what)
        drift_m = change * self.params.min_replan_interval_s * METRES_PER_NM
        thr = self.params.deviation_threshold_m
        if self._current is not None and thr > 0 and drift_m > thr:
            self.request(what)

    def _tick(self) -> None:
        p = self.params
        now = self._clock()
        while self._new_aircraft:
            self._ensure_aircraft(self._new_aircraft.pop(0))
        if now - self._radar_status_at >= RADAR_STATUS_PERIOD_S:
            self._radar_status_at = now
            self._publish_diag_array()
        if p.track_timeout_s > 0 and (latest := self.tracks.latest_stamp()) is not None:
            gone = self.tracks.drop_older_than(latest - p.track_timeout_s)
            for cs in gone:
                log.info("aircraft %s not seen for %.0f s: dropped", cs, p.track_timeout_s)
                self._radar["lost"] += 1
            if gone:
                self._withdraw(gone, f"track lost (not seen for {p.track_timeout_s:g} s)")
        self._expire_kept_plan()
        if (not self._initial_requested and self._first_rx is not None and now - self._first_rx >= p.settle_time_s
                and len(self.tracks) >= p.min_aircraft):
            self._initial_requested = True
            self.request(f"initial plan ({len(self.tracks)} aircraft tracked)")
        if (p.replan_period_s > 0 and self._current is not None and not self._busy and not self._pending()
                and now - self._last_done >= max(p.replan_period_s, p.min_replan_interval_s)):
            self.request("periodic replan")

    # -- scheduling ----------------------------------------------------------------------------------
    def _pending(self) -> bool:
        return self._radar_job is not None or bool(self._explicit)

    def request(self, reason: str, explicit: dict[str, Track] | None = None) -> Future[PlanOutcome]:
        """Schedule a plan (thread-safe); radar-based requests made while planning coalesce into one."""
        future: Future[PlanOutcome] = Future()
        with self._lock:
            if self._stop:
                future.set_result(PlanOutcome(False, "planner is shutting down", failure_class="crash"))
                return future
            if explicit is not None:
                self._explicit.append(PlanJob([reason], explicit, [future]))
            elif self._radar_job is None:
                self._radar_job = PlanJob([reason], None, [future])
            else:
                self._radar_job.reasons.append(reason)
                self._radar_job.waiters.append(future)
            self._lock.notify_all()
        log.info("plan requested: %s%s", reason, " (queued behind the running plan)" if self._busy else "")
        return future

    def _work(self) -> None:
        while True:
            with self._lock:
                while not self._stop and not self._pending():
                    self._lock.wait()
                if self._stop:
                    return
                job = self._explicit.popleft() if self._explicit else self._radar_job
                if job is self._radar_job:
                    self._radar_job = None
                self._busy = True
            assert job is not None
            self._write_status()
            try:
                outcome = self._plan(job)
            except Exception as exc:  # never let the worker die
                log.exception("planning failed")
                outcome = PlanOutcome(False, f"planning failed: {exc}", failure_class="crash")
            with self._lock:
                self._busy = False
                self._last_done = self._clock()
                self._attempts += 1
                self._last_error = "" if outcome.success else outcome.message
            self._write_status()
            for fut in job.waiters:
                if not fut.done():
                    fut.set_result(outcome)

    # -- planning (worker thread) --------------------------------------------------------------------
    def _inputs(self, job: PlanJob) -> PlanInputs | str:
        tracks = job.explicit if job.explicit is not None else self.tracks.snapshot()
        if len(tracks) < (1 if job.explicit is not None else self.params.min_aircraft):
            return f"{len(tracks)} aircraft tracked (min_aircraft {self.params.min_aircraft}): nothing to plan"
        plan_start = max(t.stamp for t in tracks.values())
        shift = max(0.0, plan_start - self._epoch) if self._epoch is not None else 0.0
        with self._lock:
            base = replace(self.scenario, obstacles=self.obstacles)
            if self.wind != base.wind:
                base = base.with_wind(self.wind)
        if self.params.wake_table != "scenario":
            base = replace(base, wake=self.params.wake_table)
        if self.params.sequencing != "scenario":
            base = replace(base, sequencing=replace(base.sequencing, strategy=self.params.sequencing))
        inputs = build_plan_scenario(base, tracks, plan_start, shift)
        for cs, why in inputs.left_out.items():
            log.warning("aircraft %s left out of the plan: %s", cs, why)
        if not inputs.scenario.aircraft:
            return "no aircraft to plan (all left out)"
        return inputs

    def _plan(self, job: PlanJob) -> PlanOutcome:
        t0 = time.perf_counter()
        inputs = self._inputs(job)
        if isinstance(inputs, str):
            log.warning("no plan: %s", inputs)
            return PlanOutcome(False, inputs, failure_class="infeasible_request")
        sc = inputs.scenario
        log.info("planning (%s): %d aircraft [%s] from t=%.3f", "; ".join(job.reasons), len(sc.aircraft),
                 ", ".join(a.callsign for a in sc.aircraft), inputs.plan_start)
        explicit = job.explicit is not None
        options = self._plan_options()
        if not explicit and self._planning_options not in (None, options):
            log.info("planner options changed: the next plan starts from scratch")
        if not explicit:
            self._planning_options = options
        try:
            # In the planning process; the Planner falls back by itself (warm, cold, fresh initializer,
            # optimizer-chosen times). A what-if plan has its own planner: the radar plan's warm start stays intact.
            result = self._planning.plan(sc, options, reuse=not explicit, start_time=inputs.plan_start,
                                         what_if=explicit)
        except Exception as exc:
            log.debug("planning failed", exc_info=True)
            return self._failed(job, inputs, f"planning failed: {' '.join(str(exc).split()) or type(exc).__name__}",
                                failure_class=classify(error=exc).failure_class)
        failure = result.failure if self.params.optimize else None
        if failure is not None and (explicit or self._current is not None):
            # Neither an unoptimized nor an unverified plan replaces the plan that is being followed.
            return self._failed(job, inputs, f"{failure[0].replace('_', ' ')}: {failure[1]}", result,
                                failure_class=failure[0])
        t_plan = time.perf_counter() - t0
        if explicit:  # answered in the response only: the radar plan others follow stays published
            plan_msg = self._landing_plan_msg(result, inputs.plan_start, result.order, inputs.left_out)
            paths = self._path_msgs(result, inputs.plan_start)
            path_msgs = [paths[cs] for cs in result.order]
        else:
            plan_msg, path_msgs = self._publish(result, inputs, job)
        t_pub = time.perf_counter() - t0 - t_plan
        outputs = self._write_outputs(result)
        t_out = time.perf_counter() - t0 - t_plan - t_pub
        summary = self._summary(result)
        timings = ", ".join(f"{k.removesuffix('_s')} {v:.2f} s" for k, v in result.timings.items())
        log.info("%s: %s; %s; planned in %.2f s (%s), published in %.2f s, outputs in %.2f s%s",
                 "what-if plan (answered, not published)" if explicit else f"plan #{self._plans}", summary,
                 self._status_text(result), t_plan, timings, t_pub, t_out, f" -> {self.out_dir}" if outputs else "")
        return PlanOutcome(True, f"{self._status_text(result)}: {summary}", plan_msg, path_msgs, result,
                           failure_class=failure[0] if failure is not None else None)

    def _failed(self, job: PlanJob, inputs: PlanInputs, reason: str, result: PlanResult | None = None,
                failure_class: str | None = "crash") -> PlanOutcome:
        """A failed plan: the last good plan stays published (latched paths and landing_plan); a radar plan
        publishes FAILED diagnostics with the reason and drops the planner's warm-start state, so that the
        next trigger plans from scratch. The response carries the reason and FAILED entries."""
        callsigns = [a.callsign for a in inputs.scenario.aircraft]
        plan = self._landing_plan_msg(None, inputs.plan_start, callsigns, inputs.left_out, reason)
        if job.explicit is None:
            cur = self._current
            extra: dict[str, Any] = {"failure": reason, "failure_class": failure_class,
                                     "error_code": outcome_code(failure_class).error_code}
            if cur is not None:
                age = inputs.plan_start - cur.plan_start
                reason += f"; keeping the last plan ({age:.1f} s old)"
                extra |= {"kept_plan_stamp": f"{cur.plan_start:.3f}", "kept_plan_age_s": f"{age:.1f}",
                          "kept_plan_aircraft": ",".join(sorted(cur.trajectories))}
                self._mark_kept(reason, inputs.plan_start)
            else:
                reason += "; no plan yet"
            log.error("%s", reason)
            self._planning.reset()
            self._publish_diagnostics(result, f"FAILED: {reason}", failed=True, extra=extra)
        else:
            log.error("what-if plan failed: %s", reason)
        paths = list(self._path_msgs(result, inputs.plan_start).values()) if result is not None else []
        return PlanOutcome(False, reason, plan, paths, result, failure_class=failure_class)

    @staticmethod
    def _status_text(result: PlanResult) -> str:
        if result.landing is None:
            return "initializer only"
        verdict = "n/a" if result.verification is None else (
            "verified" if result.verification.verified else "NOT verified")
        return f"{result.landing.status}, {verdict}" if result.optimized else f"optimizer {result.landing.status}"

    @staticmethod
    def _summary(result: PlanResult) -> str:
        land = result.landing_times()
        return "order " + ", ".join(f"{cs} lands at {land[cs]:.1f} s" for cs in result.order)

    def _write_outputs(self, result: PlanResult) -> bool:
        if self.out_dir is None:
            return False
        try:
            from mal_planner.report import write_outputs
        except ImportError:
            log.warning("mal_planner.report is not available: no plan JSON/figures written")
            return False
        try:
            write_outputs(result, self.out_dir, figures="none")
            if self.params.figures != "none":
                from mal_planner.report import start_figures

                self._figures = start_figures(self.out_dir, self.params.figures, getattr(self, "_figures", None))
        except Exception as exc:
            log.error("writing outputs to %s failed: %s", self.out_dir, exc)
            return False
        return True

    # -- messages --------------------------------------------------------------------------------------
    def _landing_plan_msg(self, result: PlanResult | None, plan_start: float, callsigns: list[str],
                          left_out: dict[str, str] | None = None, failure: str = "") -> Any:
        """The LandingPlan of ``result`` (None: a failed plan of ``callsigns``, each FAILED with ``failure``),
        followed by a FAILED entry with its reason for each aircraft left out of it."""
        T = self.types
        frame = self.scenario.geo_frame

        def failed(k: int, cs: str, reason: str) -> Any:
            return T.msg("mal_msgs/msg/AircraftPlan")(callsign=cs, order=k, gate_time=math.nan, landing_time=math.nan,
                                                      status=FAILED, verified=False, reason=reason,
                                                      target_time=math.nan, delay=math.nan,
                                                      **geodetic_path_fields(None, np.zeros((0, 5))))

        entries = []
        if result is None:
            entries = [failed(k, cs, failure) for k, cs in enumerate(callsigns, 1)]
        else:
            land, gates = result.landing_times(), result.gate_times()
            status = OPTIMAL if result.optimized else INITIAL_GUESS
            schedule = getattr(result.initial, "schedule", None)
            targets = {} if schedule is None else schedule.target
            samples = {tr.callsign: _dedupe(tr)[1] for tr in result.trajectories()}
            for k, cs in enumerate(result.order, 1):
                gate, target = gates.get(cs), targets.get(cs)
                target_time = math.nan if target is None else float(target)
                entries.append(T.msg("mal_msgs/msg/AircraftPlan")(
                    callsign=cs, order=k, gate_time=math.nan if gate is None else float(gate),
                    landing_time=float(land[cs]), status=status,
                    verified=result.optimized and _aircraft_verified(result, cs),
                    wake_category=result.scenario.aircraft_by_callsign(cs).wake_category or "",
                    target_time=target_time, delay=float(land[cs]) - target_time,
                    **geodetic_path_fields(frame, samples.get(cs, np.zeros((0, 5))))))
        first = len(entries) + 1
        entries += [failed(k, cs, why) for k, (cs, why) in enumerate(sorted((left_out or {}).items()), first)]
        header = T.msg("std_msgs/msg/Header")(stamp=time_to_msg(T, plan_start), frame_id=self.params.frame_id)
        return T.msg("mal_msgs/msg/LandingPlan")(header=header, aircraft=entries, **frame_origin_fields(frame))

    def _path_msgs(self, result: PlanResult, plan_start: float) -> dict[str, Any]:
        out = {}
        for traj in result.trajectories():
            t, states, bank = _dedupe(traj)
            out[traj.callsign] = path_msg(self.types, traj.callsign, plan_start, t, states, bank, self.params.frame_id)
        return out

    def _publish(self, result: PlanResult, inputs: PlanInputs, job: PlanJob) -> tuple[Any, list[Any]]:
        with self._pub_lock:
            return self._publish_locked(result, inputs, job)

    def _publish_locked(self, result: PlanResult, inputs: PlanInputs, job: PlanJob) -> tuple[Any, list[Any]]:
        plan_start = inputs.plan_start
        paths = self._path_msgs(result, plan_start)
        plan_msg = self._landing_plan_msg(result, plan_start, result.order, inputs.left_out)
        trajectories = {tr.callsign: tr for tr in result.trajectories()}
        lost = set(paths) - set(self.tracks.snapshot()) if job.explicit is None else set()
        if lost:  # tracks that timed out while this plan ran: withdrawn, not published
            log.info("aircraft %s lost while planning: not published", ", ".join(sorted(lost)))
            paths = {cs: m for cs, m in paths.items() if cs not in lost}
            trajectories = {cs: tr for cs, tr in trajectories.items() if cs not in lost}
            plan_msg.aircraft = [a for a in plan_msg.aircraft if a.callsign not in lost]
        land = result.landing_times()
        considered = frozenset(a.callsign for a in inputs.scenario.aircraft) | frozenset(inputs.left_out)
        self._plans += 1
        self._last_result = result
        self._kept_at = None
        self._current = CurrentPlan(plan_start, trajectories, {cs: plan_start + land[cs] for cs in trajectories},
                                    considered - lost, job.explicit is None)
        self._plan_msg = plan_msg
        for cs, msg in paths.items():
            pub = self._path_pubs.get(cs)
            if pub is None:  # explicit states of an aircraft never seen on radar
                pub = self._path_pubs[cs] = self.node.create_publisher("nav_msgs/msg/Path", f"aircraft/{cs}/path",
                                                                       QOS_LATCHED)
            pub.publish(msg)
        for cs in self._published_paths - set(paths):  # no longer planned: clear its path
            self._publish_empty_path(cs, plan_start)
        self._published_paths = set(paths)
        self.plan_pub.publish(plan_msg)
        self._publish_markers(list(trajectories.values()), plan_start)
        left_out = {"left_out": "; ".join(f"{cs}: {why}" for cs, why in sorted(inputs.left_out.items()))}
        self._publish_diagnostics(result, self._status_text(result), extra=left_out if inputs.left_out else None)
        return plan_msg, [paths[cs] for cs in result.order]

    def _mark_kept(self, failure: str, radar_time: float) -> None:
        """The published plan is kept after a failed replan: say so on landing_plan (the failure, since when)."""
        with self._pub_lock:
            if self._plan_msg is None:
                return
            if self._kept_at is None:
                self._kept_at = self._clock()
                self._plan_msg.kept_since = time_to_msg(self.types, radar_time)
            self._plan_msg.kept_failure = failure
            self.plan_pub.publish(self._plan_msg)

    def _expire_kept_plan(self) -> None:
        """Withdraw a plan kept longer than ``kept_plan_expiry_s`` (node clock) after its first failed replan."""
        expiry = self.params.kept_plan_expiry_s
        if self._kept_at is None or expiry <= 0 or self._clock() - self._kept_at < expiry:
            return
        self._kept_at = None
        self._withdraw(sorted(self._published_paths), f"kept plan expired: replans have failed for {expiry:g} s "
                                                      "(kept_plan_expiry_s)")
        with self._pub_lock:
            self._current = None  # nothing is kept any more: the next plan is a first plan

    def _publish_empty_path(self, callsign: str, stamp: float) -> None:
        """An empty nav_msgs/Path on the aircraft's topic: its plan is withdrawn (latched for late joiners)."""
        header = self.types.msg("std_msgs/msg/Header")(stamp=time_to_msg(self.types, stamp),
                                                       frame_id=self.params.frame_id)
        self._path_pubs[callsign].publish(self.types.msg("nav_msgs/msg/Path")(header=header, poses=[]))

    def _withdraw(self, callsigns: list[str], why: str) -> None:
        """Withdraw the plans of ``callsigns``: an empty Path on each topic, their entries dropped from the
        latched landing_plan and the markers, a diagnostic saying so. The other aircraft keep their plans."""
        with self._pub_lock:
            gone = sorted(set(callsigns) & self._published_paths)
            cur = self._current
            if not gone or cur is None:
                return
            stamp = self.tracks.latest_stamp() or cur.plan_start
            for cs in gone:
                self._publish_empty_path(cs, stamp)
            self._published_paths -= set(gone)
            trajectories = {cs: tr for cs, tr in cur.trajectories.items() if cs not in gone}
            self._current = replace(cur, trajectories=trajectories,
                                    landing_abs={cs: t for cs, t in cur.landing_abs.items() if cs not in gone},
                                    considered=cur.considered - set(gone))
            if self._plan_msg is not None:
                self._plan_msg.aircraft = [a for a in self._plan_msg.aircraft if a.callsign not in gone]
                self.plan_pub.publish(self._plan_msg)
            self._publish_markers(list(trajectories.values()), cur.plan_start)
            message = f"plan of {', '.join(gone)} withdrawn: {why}"
            log.warning("%s", message)
            self._publish_diagnostics(self._last_result, message, extra={"withdrawn": ",".join(gone)})

    def _publish_markers(self, trajectories: list[Trajectory], stamp: float) -> None:
        with self._lock:
            obstacles = self.obstacles
        self.marker_pub.publish(marker_array(self.types, obstacles, self.scenario.gates, trajectories, stamp,
                                             self.params.frame_id))

    def _diag_status(self, level: int | None, message: str, values: dict[str, Any], name: str = "landing plan"
                     ) -> Any:
        T = self.types
        kvs = [T.msg("diagnostic_msgs/msg/KeyValue")(key=k, value=str(v)) for k, v in values.items()]
        return T.msg("diagnostic_msgs/msg/DiagnosticStatus")(
            level=byte_field(T, DIAG_OK if level is None else level), name=f"{self.node.get_name()}: {name}",
            message=message, hardware_id="mal_planner", values=kvs)

    def _publish_diagnostics(self, result: PlanResult | None, message: str, failed: bool = False,
                             extra: dict[str, Any] | None = None) -> None:
        """The plan's status (kept: the 1 Hz diagnostics repeat it beside the radar status)."""
        values: dict[str, Any] = {"plans": self._plans, "status": "FAILED" if failed else "OK"}
        level = DIAG_ERROR
        if result is not None:
            lr, rep = result.landing, result.verification
            if not failed:
                level = DIAG_OK if result.optimized and rep is not None and rep.verified else DIAG_WARN
            failure = result.failure
            values |= {"failure_class": failure[0] if failure else "",
                       "error_code": outcome_code(failure[0] if failure else None).error_code}
            values |= {"order": ",".join(result.order), "solver_status": lr.status if lr else "not run",
                       "solve_time_s": f"{lr.solve_time:.3f}" if lr else "nan",
                       "nlp_iterations": lr.nlp_iterations if lr else 0, "verified": bool(rep and rep.verified),
                       "reasons": "; ".join(rep.reasons) if rep else ""}
            values |= {k: f"{v:.3f}" for k, v in result.timings.items()}
        values |= extra or {}
        self._plan_status = self._diag_status(level, message, values)
        self._publish_diag_array()

    def _radar_status(self) -> Any:
        """Radar intake: tracked aircraft, messages received/accepted, rejected by reason, dropped (older than
        the track held), duplicates and lost tracks; WARN while messages are being rejected."""
        c = self._radar
        rejected = {k.removeprefix("rejected."): n for k, n in sorted(c.items()) if k.startswith("rejected.")}
        fresh = c["rejected"] - self._rejected_reported
        self._rejected_reported = c["rejected"]
        values = {"tracked": len(self.tracks), "received": c["received"], "accepted": c["accepted"],
                  "rejected": c["rejected"], "dropped": c["older"], "duplicates": c["duplicate"], "lost": c["lost"]}
        values |= {f"rejected.{k}": n for k, n in rejected.items()}
        message = f"{len(self.tracks)} aircraft tracked"
        if rejected:
            message += "; rejected: " + ", ".join(f"{k} {n}" for k, n in rejected.items())
        return self._diag_status(DIAG_WARN if fresh else DIAG_OK, message, values, name="radar")

    def _publish_diag_array(self) -> None:
        """One DiagnosticArray: the plan's status first, then the radar's (as a diagnostic_updater would)."""
        T = self.types
        with self._diag_lock:
            header = T.msg("std_msgs/msg/Header")(stamp=time_to_msg(T, self.node.now()), frame_id="")
            self.diag_pub.publish(T.msg("diagnostic_msgs/msg/DiagnosticArray")(
                header=header, status=[self._plan_status, self._radar_status()]))

    def _write_status(self) -> None:
        """``planner_status.json`` in the output folder: plan count, busy flag, last plan (for mal-launch)."""
        if self.out_dir is None:
            return
        cur, result = self._current, self._last_result
        status: dict[str, Any] = {"plans": self._plans, "attempts": self._attempts, "last_error": self._last_error,
                                  "planning": self._busy, "pending": self._pending(),
                                  "plan_start": cur.plan_start if cur else None, "aircraft": []}
        if result is not None and cur is not None:
            land = result.landing_times()
            status["aircraft"] = [{"order": k, "callsign": cs, "landing_time_s": land[cs],
                                   "verified": _aircraft_verified(result, cs)}
                                  for k, cs in enumerate(result.order, 1) if cs in cur.trajectories]
        try:
            self.out_dir.mkdir(parents=True, exist_ok=True)
            tmp = self.out_dir / (STATUS_FILE + ".tmp")
            tmp.write_text(json.dumps(status, allow_nan=True) + "\n", encoding="utf-8")
            os.replace(tmp, self.out_dir / STATUS_FILE)
        except OSError as exc:
            log.error("cannot write %s: %s", self.out_dir / STATUS_FILE, exc)

    # -- services (reentrant: on a worker thread of the transport; they may block) --------------------
    def _wait(self, future: Future[PlanOutcome]) -> PlanOutcome:
        try:
            return future.result(timeout=self.params.service_timeout_s)
        except TimeoutError:
            return PlanOutcome(False, f"no plan within {self.params.service_timeout_s:.0f} s", failure_class="timeout")

    def _srv_trigger(self, request: Any, response: Any) -> Any:
        del request
        if not len(self.tracks):
            response.success, response.message = False, "no radar tracks yet"
            return response
        outcome = self._wait(self.request("service plan"))
        response.success, response.message = outcome.success, outcome.message
        return response

    def _srv_plan_landing(self, request: Any, response: Any) -> Any:
        explicit: dict[str, Track] = {}
        for i, msg in enumerate(request.aircraft):
            try:
                callsign, stamp, state, speed, wake = aircraft_state_to_planner(msg)
                track = Track(callsign, stamp, state, speed, wake)
                reason = check_track(track, str(msg.header.frame_id), self.params.frame_id, self.scenario.airspace,
                                     expected_speed=self._scenario_speed(callsign))
            except Exception as exc:
                reason, callsign = str(exc), "?"
            if reason is None and callsign in explicit:
                reason = "duplicate callsign"
            if reason is not None:
                response.success, response.error_code = False, outcome_code("invalid_input").error_code
                response.message = f"aircraft[{i}] ({callsign}): {reason}"
                log.error("plan_landing request rejected: %s", response.message)
                return response
            explicit[callsign] = track
        if explicit:
            future = self.request(f"plan_landing service ({len(explicit)} explicit states)", explicit)
        elif len(self.tracks):
            future = self.request("plan_landing service (radar tracks)")
        else:
            response.success, response.message = False, "no aircraft given and no radar tracks yet"
            response.error_code = outcome_code("invalid_input").error_code
            return response
        outcome = self._wait(future)
        response.success, response.message = outcome.success, outcome.message
        response.error_code = outcome.error_code
        if outcome.plan_msg is not None:
            response.plan = outcome.plan_msg
        response.paths = list(outcome.path_msgs)
        return response

    # -- life cycle -------------------------------------------------------------------------------------
    def spin(self) -> None:
        """Run until :meth:`stop` (e.g. from a signal handler)."""
        self._worker.start()
        self._write_status()
        try:
            self.node.spin()
        finally:
            self.stop()

    def stop(self) -> None:
        with self._lock:
            if self._stop:
                return
            self._stop = True
            jobs = list(self._explicit) + ([self._radar_job] if self._radar_job else [])
            self._explicit.clear()
            self._radar_job = None
            self._lock.notify_all()
        for job in jobs:
            for fut in job.waiters:
                if not fut.done():
                    fut.set_result(PlanOutcome(False, "planner is shutting down", failure_class="crash"))
        self.node.shutdown()
        self._worker.join(timeout=1.0)
        self._planning.close()


def _default_path(name: str) -> str | None:
    for cand in (Path(name), REPO / name):
        if cand.exists():
            return str(cand)
    return None


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="mal-planner-node", description=__doc__.split("\n")[0])
    p.add_argument("--scenario", default=None, help="scenario YAML (default scenarios/thesis.yaml)")
    p.add_argument("--params", default=None, help="ROS 2 params YAML (default config/planner.params.yaml)")
    p.add_argument("--out", default=None, help="output folder (overrides the output_dir parameter)")
    p.add_argument("--namespace", default="", help="node namespace")
    p.add_argument("--backend", default="auto", choices=("auto", "rclpy", "cyclone"), help="ROS backend")
    p.add_argument("--log-level", default="INFO", help="Python log level (default INFO)")
    p.add_argument("--allow-duplicate", action="store_true",
                   help="start even when another planner answers under the same name (both will publish plans)")
    return p.parse_args(argv)


DUPLICATE_PROBE_S = 1.0
"""How long a starting planner looks for another under its name: discovery on one host takes tens of ms; across
a network a planner discovered later than this is not seen."""


def other_planner(namespace: str, backend: str) -> str | None:
    """The full name of another planner that answers under ours (``<namespace>/planner``), or None.

    Its parameter service must answer, not only be discovered: a planner killed moments ago stays in the DDS
    graph until its lease expires (10 s), and a respawned planner must not refuse to start because of it."""
    from mal_planner.ros.transport._common import normalize_namespace

    full = f"{normalize_namespace(namespace).rstrip('/')}/{NODE_NAME}"
    probe = create_node(f"{NODE_NAME}_probe_{os.getpid()}", namespace, backend=backend,
                        start_parameter_services=False)
    try:
        client = probe.create_client("rcl_interfaces/srv/GetParameters", f"{full}/get_parameters")
        if not client.wait_for_service(DUPLICATE_PROBE_S):
            return None
        request = probe.types.srv("rcl_interfaces/srv/GetParameters").Request(names=["frame_id"])
        try:
            client.call(request, timeout_sec=2.0 * DUPLICATE_PROBE_S)
        except TimeoutError:
            return None
        return full
    finally:
        probe.shutdown()


def setup_logging(level: str = "INFO") -> None:
    logging.basicConfig(level=getattr(logging, level.upper(), logging.INFO), stream=sys.stderr, format=LOG_FORMAT)


def main(argv: list[str] | None = None) -> int:
    """Run the node until SIGINT/SIGTERM (then it ends by that signal, after a clean shutdown: exit -2/-15 as
    a supervisor sees it); 2 when the scenario cannot be loaded or another planner answers under its name."""
    args = parse_args(argv)
    setup_logging(args.log_level)
    scenario_path = args.scenario or _default_path("scenarios/thesis.yaml") or "scenarios/thesis.yaml"
    params_file = args.params if args.params is not None else _default_path("config/planner.params.yaml")
    try:
        scenario = load_scenario(scenario_path)
    except ScenarioError as exc:
        log.error("cannot load the scenario: %s", exc)
        return 2
    if not all(CALLSIGN_RE.match(a.callsign) for a in scenario.aircraft):
        log.error("scenario %s: callsigns must be ROS name-safe", scenario_path)
        return 2
    if not args.allow_duplicate and (other := other_planner(args.namespace, args.backend)) is not None:
        log.error("another planner answers as %s on ROS_DOMAIN_ID %s: two would both publish plans; stop it, use "
                  "another --namespace or ROS_DOMAIN_ID, or pass --allow-duplicate", other,
                  os.environ.get("ROS_DOMAIN_ID", "0"))
        return 2
    planner = PlannerNode(scenario, params_file=params_file, output_dir=args.out, namespace=args.namespace,
                          backend=args.backend)

    stopped_by: list[int] = []

    def on_signal(signum: int, _frame: Any) -> None:
        log.info("%s: shutting down", signal.Signals(signum).name)
        stopped_by.append(signum)
        planner.node.shutdown()

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    planner.spin()
    logging.shutdown()
    if stopped_by:  # cleaned up; now end by the signal, so that a supervisor sees how we ended (exit -15)
        signal.signal(stopped_by[0], signal.SIG_DFL)
        os.kill(os.getpid(), stopped_by[0])
    if planner._worker.is_alive():  # a solve in C code cannot be interrupted: do not wait for it
        os._exit(0)
    return 0


if __name__ == "__main__":
    sys.exit(main())
