"""The planner node: radar tracks in, conflict-free landing plans out (paths, LandingPlan, markers).

    python -m mal_planner.ros.planner_node --scenario scenarios/thesis.yaml --params config/planner.params.yaml

A thin adapter over the service core (:class:`~mal_planner.service.core.PlanningService`), which decides what to
plan, when, from what, and what to hand out: this node converts messages, keeps the clock and publishes. Threads:
the node is spun on the main thread; its topic and timer callbacks only convert messages and schedule work; plans
run on a plan thread, in a planning process (:mod:`mal_planner.ros.plan_process`); the services are reentrant (the
transport runs them beside the other callbacks), so a service call that waits for its plan never blocks the radar.
"""

from __future__ import annotations

import logging
import math
import os
import signal
import sys
import threading
import time
from concurrent.futures import Future
from pathlib import Path
from typing import Any

from mal_planner.errors import Outcome, classify, one_line
from mal_planner.ros.convert import NoFlyZoneError, aircraft_state_to_planner, no_fly_zone_update, wind_to_planner
from mal_planner.ros.node_outputs import STATUS_FILE, NodeOutputs
from mal_planner.ros.node_params import NodeParams, ParamsError, declare_parameters, describe, read_params_file
from mal_planner.ros.plan_jobs import JobQueue, PlanJob, PlanOutcome
from mal_planner.ros.plan_messages import failed_answer, plan_answer, status_text, summary_text
from mal_planner.ros.plan_process import LOG_FORMAT, PlanProcess
from mal_planner.ros.plan_publisher import PlanPublisher
from mal_planner.ros.plan_services import PlanServices
from mal_planner.ros.transport import QOS_DEFAULT, QoSProfile, create_node
from mal_planner.scenario import Scenario, ScenarioError, load_scenario
from mal_planner.service.book import Event, Handout, Instructed, Kept, Stale, Withdrawn
from mal_planner.service.core import PlanningService
from mal_planner.service.request import PlanRequest
from mal_planner.service.tracks import CALLSIGN_RE, Track

NODE_NAME = "planner"
STATE_TYPE = "mal_msgs/msg/AircraftState"
TICK_S = 0.2
RADAR_STATUS_PERIOD_S = 1.0  # the radar status on diagnostics, as diagnostic_updater's default rate
RADAR_DEPTH = 1000
"""History of the radar subscriptions: a burst of new callsigns waits here while their topics are made."""
REPO = Path(__file__).resolve().parents[3]
__all__ = ["STATUS_FILE", "PlannerNode", "main"]

log = logging.getLogger("mal_planner.ros.planner")


class PlannerNode:
    """Owns the node, the service core, the planning process and the plan thread."""

    def __init__(self, scenario: Scenario, *, overrides: dict[str, Any] | None = None, namespace: str = "",
                 backend: str = "auto") -> None:
        """``overrides``: the checked values of the params file (:func:`read_params_file`)."""
        self.node = create_node(NODE_NAME, namespace, backend=backend, parameter_overrides=overrides or {})
        self.params: NodeParams = declare_parameters(self.node)
        self.types = self.node.types
        self.scenario = scenario
        self.service = PlanningService(scenario, self.params.rules(scenario), self.params.plan_options())
        self._planning = PlanProcess()  # started now: it loads CasADi while the radar settles
        self.jobs = JobQueue()
        self.outputs = NodeOutputs(self.params.output_dir, self.params.figures)
        # Scheduling follows the node's clock with use_sim_time (a simulator's /clock, which may run faster than the
        # wall clock), else the monotonic clock; the service works on the radar's clock, estimated from both.
        self._clock = self.node.now if self.node.uses_sim_time else time.monotonic
        self._attempts, self._last_error = 0, ""
        self._state_subs: dict[str, Any] = {}
        self._new_aircraft: list[str] = []  # seen in a radar callback, their topics are made in the tick
        self._radar_status_at = -math.inf
        self.publisher = PlanPublisher(self.node, scenario, self.params.frame_id,
                                       lambda: (self.service.intake.counts, len(self.service.intake)))
        self._setup_ros()
        self.node.forward_logs(logging.getLogger("mal_planner"))  # the planner's log lines on /rosout
        self.node.add_on_set_parameters_callback(self._on_set_parameters)
        self._worker = threading.Thread(target=self._work, name="planner-worker", daemon=True)
        log.info("planner ready: scenario %s (%d aircraft known, %d obstacles), %s", scenario.source,
                 len(scenario.aircraft), len(scenario.obstacles), describe(self.params))

    # -- set-up ---------------------------------------------------------------------------------------------------
    def _setup_ros(self) -> None:
        node = self.node
        # Deep history: a burst of messages waits while the executor is busy (e.g. making new aircraft's topics).
        self.radar_qos = QoSProfile(depth=RADAR_DEPTH, reliable=self.params.radar_qos != "sensor_data")
        for ac in self.scenario.aircraft:
            self._ensure_aircraft(ac.callsign)
        node.create_subscription(STATE_TYPE, "radar/tracks", lambda m: self._on_state(m, "radar/tracks"),
                                 self.radar_qos)
        node.create_subscription("mal_msgs/msg/NoFlyZone", "airspace/no_fly_zones", self._on_no_fly_zone, QOS_DEFAULT)
        node.create_subscription("geometry_msgs/msg/Vector3Stamped", "wind", self._on_wind, QOS_DEFAULT)
        node.create_timer(TICK_S, self._tick)
        # Reentrant: a service call waits for its plan without holding up the radar callbacks.
        services = PlanServices(self)
        node.create_service("std_srvs/srv/Trigger", "plan", services.trigger, reentrant=True)
        node.create_service("mal_msgs/srv/PlanLanding", "plan_landing", services.plan_landing, reentrant=True)
        self.publisher.markers([], 0.0, self.service.obstacles)

    def _ensure_aircraft(self, callsign: str) -> None:
        """Per-aircraft state subscription and path publisher (executor thread only)."""
        if callsign in self._state_subs:
            return
        topic = f"aircraft/{callsign}/state"
        self._state_subs[callsign] = self.node.create_subscription(
            STATE_TYPE, topic, lambda m: self._on_state(m, topic), self.radar_qos)
        self.publisher.path_publisher(callsign)

    def _on_set_parameters(self, params: list[Any]) -> tuple[bool, str]:
        """Parameters set at run time (ros2 param set): checked against the option table and applied at once; a
        refused value leaves every parameter as it was and the reason goes back to the caller."""
        changes = {p.name: p.value for p in params}
        try:
            new = self.params.updated(changes)
        except ValueError as exc:
            log.error("parameter update refused: %s", exc)
            return False, str(exc)
        self.params = new
        self.service.set_rules(new.rules(self.scenario))
        self.service.set_options(new.plan_options())
        self.outputs.set_folder(new.output_dir, new.figures)
        self.publisher.frame_id = new.frame_id
        log.info("parameters updated: %s", describe(changes))
        return True, ""

    def _radar_now(self) -> float | None:
        return self.service.radar_now(self._clock())

    def _now(self) -> float:
        """The radar's time now (0 before the first track: a what-if plan's states carry their own stamps)."""
        now = self._radar_now()
        return 0.0 if now is None else now

    # -- executor-thread callbacks (cheap) ------------------------------------------------------------------------
    def _on_state(self, msg: Any, topic: str) -> None:
        try:
            track = Track(*aircraft_state_to_planner(msg))
            frame_id = str(msg.header.frame_id)
        except Exception as exc:  # malformed message
            self.service.intake.counts["received"] += 1
            self.service.intake.reject("malformed", topic, f"bad AircraftState on {topic}: {exc} (ignored)")
            return
        verdict = self.service.take_track(track, frame_id, topic, self._clock(), self.node.now())
        if verdict.new and track.callsign not in self._state_subs:
            self._new_aircraft.append(track.callsign)  # its topics are made in the tick, not in this callback

    def _on_no_fly_zone(self, msg: Any) -> None:
        try:
            name, zone = no_fly_zone_update(msg)
            what = self.service.update_zone(name, zone)
        except (NoFlyZoneError, AttributeError, TypeError, ValueError) as exc:
            log.error("bad NoFlyZone on airspace/no_fly_zones: %s (ignored)", exc)
            return
        log.info("%s (%d obstacles)", what, len(self.service.obstacles))
        current = self.service.book.current
        self.publisher.markers(list(current.trajectories.values()) if current else [],
                               current.result.start_time if current else 0.0, self.service.obstacles)
        if self.service.planned:
            self.request(what)

    def _on_wind(self, msg: Any) -> None:
        """A wind estimate or forecast (m/s, ENU in ``frame_id``): see :meth:`PlanningService.update_wind`."""
        try:
            what, reason = self.service.update_wind(wind_to_planner(msg, self.params.frame_id))
        except (AttributeError, TypeError, ValueError) as exc:
            self.service.intake.log_bad("wind", f"bad wind on wind: {exc} (ignored)")
            return
        if what:
            log.info("%s", what)
        if reason is not None:
            self.request(reason)

    def _tick(self) -> None:
        while self._new_aircraft:
            self._ensure_aircraft(self._new_aircraft.pop(0))
        if self._clock() - self._radar_status_at >= RADAR_STATUS_PERIOD_S:
            self._radar_status_at = self._clock()
            self.publisher.publish_diagnostics()
        now = self._radar_now()
        if now is None:
            return
        self._apply(self.service.lose_tracks() + self.service.due(now), now)
        self._apply(self.service.instruct(now), now)
        if not self.jobs.pending and (reason := self.service.poll(now)) is not None:
            self.request(reason)

    # -- scheduling -------------------------------------------------------------------------------------------------
    def request(self, reason: str, explicit: dict[str, Track] | None = None, lead: bool = True
                ) -> Future[PlanOutcome]:
        """Schedule a plan (thread-safe); radar plans asked for while one waits coalesce into one."""
        if explicit is None:
            self.service.ask()
        future = self.jobs.put(reason, explicit, lead)
        log.info("plan requested: %s%s", reason, " (queued behind the running plan)" if self.jobs.busy else "")
        return future

    def _work(self) -> None:
        while (job := self.jobs.take()) is not None:
            self._write_status()
            try:
                outcome = self._plan(job)
            except Exception as exc:  # never let the plan thread die, nor the service wait for this plan
                log.exception("planning failed")
                if not job.what_if:
                    self.service.refused(self._now())
                outcome = PlanOutcome(False, f"planning failed: {exc}", failure=Outcome.CRASH)
            self._attempts += 1
            self._last_error = "" if outcome.success else outcome.message
            self.jobs.done(job, outcome)
            self._write_status()

    # -- planning (plan thread) -----------------------------------------------------------------------------------
    def _plan(self, job: PlanJob) -> PlanOutcome:
        request = self.service.request("; ".join(job.reasons), self._now(), tracks=job.explicit, lead=job.lead,
                                       what_if=job.what_if)
        if isinstance(request, str):
            if not job.what_if:
                self.service.refused(self._now())
            log.warning("no plan: %s", request)
            return PlanOutcome(False, request, failure=Outcome.INFEASIBLE_REQUEST)
        sc = request.scenario
        log.info("planning (%s): %d aircraft [%s] from t=%.3f", request.reason, len(sc.aircraft),
                 ", ".join(a.callsign for a in sc.aircraft), request.plan_start)
        t0, clock0 = time.perf_counter(), self._clock()
        try:
            result = self._planning.plan(sc, request.options, reuse=not job.what_if, start_time=request.plan_start,
                                         what_if=job.what_if, traffic=request.traffic)
        except Exception as exc:
            log.debug("planning failed", exc_info=True)
            return self._failed(request, f"planning failed: {one_line(str(exc)) or type(exc).__name__}",
                                classify(error=exc).outcome, self._clock() - clock0)
        if (failure := result.failure) is not None:  # neither an unoptimized nor an unverified plan is handed out
            return self._failed(request, f"{failure.outcome.replace('_', ' ')}: {failure.reason}", failure.outcome,
                                self._clock() - clock0, result)
        return self._delivered(request, result, time.perf_counter() - t0, self._clock() - clock0)

    def _delivered(self, request: PlanRequest, result: Any, wall_s: float, latency_s: float) -> PlanOutcome:
        """A plan made: a what-if one answered, a radar one to the service (handed out now or when it starts)."""
        handed = None
        if not request.what_if:
            handed = self._apply(self.service.finish(request, result, None, self._now(), latency_s), self._now())
        plan_msg, path_msgs = handed or plan_answer(self.types, request, result, self.params.frame_id,
                                                    self.scenario.geo_frame)
        what = ("what-if plan (answered, not published)" if request.what_if else f"plan #{self.publisher.plans}"
                if handed is not None else f"plan made (handed out when it starts, t={result.start_time:.3f})")
        wrote = self.outputs.write_plan(result)
        timings = ", ".join(f"{k.removesuffix('_s')} {v:.2f} s" for k, v in result.timings.items())
        log.info("%s: %s; %s; planned in %.2f s (%s)%s", what, summary_text(result), status_text(result), wall_s,
                 timings, f" -> {self.outputs.out_dir}" if wrote else "")
        return PlanOutcome(True, f"{status_text(result)}: {summary_text(result)}", plan_msg, path_msgs, result)

    def _failed(self, request: PlanRequest, reason: str, outcome: Outcome, latency_s: float,
                result: Any = None) -> PlanOutcome:
        """A failed plan: the plans being flown stay published (marked as kept); a radar plan publishes FAILED
        diagnostics with the reason. The response carries the reason and FAILED entries."""
        if request.what_if:
            log.error("what-if plan failed: %s", reason)
        else:
            events = self.service.finish(request, None, reason, self._now(), latency_s)
            reason = self.publisher.failed(reason, outcome, next((e for e in events if isinstance(e, Kept)), None),
                                           result)
        plan, paths = failed_answer(self.types, request, reason, result, self.params.frame_id, self.scenario.geo_frame)
        return PlanOutcome(False, reason, plan, paths, result, failure=outcome)

    def _apply(self, events: list[Event], now: float) -> tuple[Any, list[Any]] | None:
        """Publish what the service decided; the LandingPlan and paths of a plan handed out (None: none)."""
        handed = None
        for event in events:
            if isinstance(event, Handout):
                handed = self.publisher.handout(event, self.service.obstacles)
            elif isinstance(event, Withdrawn):
                current = self.service.book.current
                self.publisher.withdraw(event, now,
                                        list(current.trajectories.values()) if current else [],
                                        current.result.start_time if current else 0.0, self.service.obstacles)
            elif isinstance(event, Instructed):
                self.publisher.instructed(event)
            elif isinstance(event, Stale):
                log.warning("plan %s", event.reason)
        if events:
            self._write_status()
        return handed

    def _write_status(self) -> None:
        current = self.service.book.current
        self.outputs.write_status({"plans": self.publisher.plans, "attempts": self._attempts,
                                   "last_error": self._last_error, "planning": self.jobs.busy,
                                   "pending": self.jobs.pending, **self.service.safety_net_status()},
                                  current.result.start_time if current else None,
                                  current.result if current else None, set(self.service.book.flying))

    # -- life cycle -------------------------------------------------------------------------------------------------
    def spin(self) -> None:
        """Run until :meth:`stop` (e.g. from a signal handler)."""
        self._worker.start()
        self._write_status()
        try:
            self.node.spin()
        finally:
            self.stop()

    def stop(self) -> None:
        if self.jobs.stopped:
            return
        self.jobs.stop()
        self.node.shutdown()
        if self._worker.is_alive():
            self._worker.join(timeout=1.0)
        self._planning.close()


def _default_path(name: str) -> str | None:
    for cand in (Path(name), REPO / name):
        if cand.exists():
            return str(cand)
    return None


def main(argv: list[str] | None = None) -> int:
    """Run the node until SIGINT/SIGTERM (then it ends by that signal, after a clean shutdown: exit -2/-15 as
    a supervisor sees it); 2 when the scenario or the params file cannot be used or another planner answers under
    its name (one line, before anything starts)."""
    from mal_planner.ros.node_cli import other_planner, parse_args, setup_logging

    args = parse_args(argv, __doc__.split("\n")[0])
    setup_logging(args.log_level, LOG_FORMAT)
    scenario_path = args.scenario or _default_path("scenarios/thesis.yaml") or "scenarios/thesis.yaml"
    params_file = args.params if args.params is not None else _default_path("config/planner.params.yaml")
    try:
        scenario = load_scenario(scenario_path)
        overrides = read_params_file(params_file, NODE_NAME, args.namespace, log)
    except (ScenarioError, ParamsError) as exc:
        log.error("cannot start: %s", exc)
        return 2
    if args.out is not None:
        overrides["output_dir"] = args.out
    if not all(CALLSIGN_RE.match(a.callsign) for a in scenario.aircraft):
        log.error("scenario %s: callsigns must be ROS name-safe", scenario_path)
        return 2
    if not args.allow_duplicate and (other := other_planner(NODE_NAME, args.namespace, args.backend)) is not None:
        log.error("another planner answers as %s on ROS_DOMAIN_ID %s: two would both publish plans; stop it, use "
                  "another --namespace or ROS_DOMAIN_ID, or pass --allow-duplicate", other,
                  os.environ.get("ROS_DOMAIN_ID", "0"))
        return 2
    planner = PlannerNode(scenario, overrides=overrides, namespace=args.namespace, backend=args.backend)
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
