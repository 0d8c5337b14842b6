"""What the planner node publishes: paths, the LandingPlan, markers and diagnostics, from the service's events.

All topics are latched (late joiners get the current plan). A plan handed out publishes the path of each of its
aircraft; an aircraft a later plan leaves out keeps the path it flies; a withdrawn plan is an empty Path. Thread-safe
(the plan thread and the executor both publish).
"""

from __future__ import annotations

import logging
import math
import threading
from collections import Counter
from collections.abc import Callable
from typing import Any

from mal_planner.errors import Outcome
from mal_planner.obstacles import Superquadric
from mal_planner.pipeline import PlanResult
from mal_planner.ros.convert import path_msg, time_to_msg
from mal_planner.ros.markers import marker_array
from mal_planner.ros.plan_messages import (
    DIAG_WARN,
    HOLD,
    diagnostic_status,
    empty_path,
    landing_plan_message,
    path_messages,
    plan_diagnostic_values,
    radar_diagnostic_values,
    status_text,
)
from mal_planner.ros.transport import QOS_LATCHED
from mal_planner.scenario import Scenario
from mal_planner.service.book import Handout, Instructed, Kept, Withdrawn
from mal_planner.trajectory import Trajectory

log = logging.getLogger("mal_planner.ros.planner")


class PlanPublisher:
    """The node's plan-side publishers and what they last said."""

    def __init__(self, node: Any, scenario: Scenario, frame_id: str,
                 radar: Callable[[], tuple[Counter[str], int]]) -> None:
        """``radar``: the intake's counts and the number of aircraft tracked (the radar's diagnostic status)."""
        self.node, self.types, self.scenario, self.frame_id = node, node.types, scenario, frame_id
        self.radar = radar
        self.plan_pub = node.create_publisher("mal_msgs/msg/LandingPlan", "landing_plan", QOS_LATCHED)
        self.marker_pub = node.create_publisher("visualization_msgs/msg/MarkerArray", "planner/markers", QOS_LATCHED)
        self.diag_pub = node.create_publisher("diagnostic_msgs/msg/DiagnosticArray", "diagnostics", QOS_LATCHED)
        self._lock = threading.RLock()
        """Plans: what each topic holds (the plan thread and the executor both change it)."""
        self._paths_lock = threading.Lock()
        self._diag_lock = threading.Lock()
        """Kept apart, so that the executor's 1 Hz diagnostics and new aircraft's topics never wait for a plan's
        messages to be built and published."""
        self._paths: dict[str, Any] = {}
        self.published: set[str] = set()
        """Aircraft whose path topic holds a plan."""
        self.plan_msg: Any = None
        """The last LandingPlan published."""
        self.plans = 0
        self.last_result: PlanResult | None = None
        self._kept_first: float | None = None
        self._plan_status = diagnostic_status(self.types, node.get_name(), None, "no plan yet",
                                              {"plans": 0, "status": "NONE"})
        self._rejected_reported = 0

    def path_publisher(self, callsign: str) -> Any:
        with self._paths_lock:
            if callsign not in self._paths:
                self._paths[callsign] = self.node.create_publisher("nav_msgs/msg/Path", f"aircraft/{callsign}/path",
                                                                   QOS_LATCHED)
            return self._paths[callsign]

    # -- plans ---------------------------------------------------------------------------------------------------
    def handout(self, event: Handout, obstacles: tuple[Superquadric, ...]) -> tuple[Any, list[Any]]:
        """Publish a plan handed out: its aircraft's paths, the LandingPlan (left-out aircraft FAILED), markers and
        diagnostics. Returns the LandingPlan and the paths in landing order."""
        result, request = event.result, event.request
        start = result.start_time
        paths = path_messages(self.types, list(event.trajectories.values()), start, self.frame_id)
        plan_msg = landing_plan_message(self.types, result, start, result.order, self.frame_id,
                                        self.scenario.geo_frame, request.inputs.left_out)
        if event.lost:
            log.info("aircraft %s lost while planning: not published", ", ".join(event.lost))
        if event.established:
            log.info("aircraft %s established on final: keep the paths they fly", ", ".join(event.established))
        if event.lost or event.established:
            gone = {*event.lost, *event.established}
            plan_msg.aircraft = [a for a in plan_msg.aircraft if a.callsign not in gone]
        with self._lock:
            self.plans += 1
            self.last_result, self.plan_msg, self._kept_first = result, plan_msg, None
            for cs, msg in paths.items():
                self.path_publisher(cs).publish(msg)
            self.published |= set(paths)
            self.plan_pub.publish(plan_msg)
            self.markers(list(event.trajectories.values()), start, obstacles)
            left = request.inputs.left_out
            extra = {"left_out": "; ".join(f"{cs}: {why}" for cs, why in sorted(left.items()))} if left else None
            self.diagnostics(result, status_text(result), extra=extra)
            return plan_msg, [paths[cs] for cs in result.order if cs in paths]

    def instructed(self, event: Instructed) -> None:
        """The service's own instructions (holds, the safety net's vectors): each one's path on its aircraft's path
        topic, and its entry in the latched LandingPlan marked STATUS_HOLD with the reason."""
        with self._lock:
            for fb in event.fallbacks:
                ref = fb.reference
                self.path_publisher(fb.callsign).publish(
                    path_msg(self.types, fb.callsign, ref.start, ref.t - ref.start, ref.table[:, :5], None,
                             self.frame_id))
                self.published.add(fb.callsign)
                log.warning("%s: %s (%s)", fb.callsign, fb.kind, fb.reason)
            if self.plan_msg is None:
                return
            held = {fb.callsign: fb for fb in event.fallbacks}
            entry = self.types.msg("mal_msgs/msg/AircraftPlan")
            kept = [a for a in self.plan_msg.aircraft if a.callsign not in held]
            self.plan_msg.aircraft = kept + [
                entry(callsign=cs, order=0, gate_time=math.nan, landing_time=math.nan, status=HOLD, verified=False,
                      reason=f"{fb.kind}: {fb.reason}", target_time=math.nan, delay=math.nan)
                for cs, fb in sorted(held.items())]
            self.plan_pub.publish(self.plan_msg)

    def kept(self, event: Kept, failure: str) -> None:
        """A replan failed: landing_plan says its plan is kept (the failure, since when)."""
        with self._lock:
            if self.plan_msg is None:
                return
            if self._kept_first is None:
                self._kept_first = event.since
                self.plan_msg.kept_since = time_to_msg(self.types, event.since)
            self.plan_msg.kept_failure = failure
            self.plan_pub.publish(self.plan_msg)

    def failed(self, reason: str, outcome: Outcome, kept: Kept | None, result: PlanResult | None) -> str:
        """A radar plan failed: FAILED diagnostics (with the kept plan's stamp, age and aircraft) and landing_plan
        marked as kept; returns the reason as the caller is told (the kept plan's age, or that there is none)."""
        extra: dict[str, Any] = {"failure": reason, "failure_class": outcome, "error_code": outcome.code.error_code}
        if kept is not None and kept.plan_start is not None:
            reason += f"; keeping the last plan ({kept.age_s:.1f} s old)"
            extra |= {"kept_plan_stamp": f"{kept.plan_start:.3f}", "kept_plan_age_s": f"{kept.age_s:.1f}",
                      "kept_plan_aircraft": ",".join(kept.callsigns)}
            self.kept(kept, reason)
        else:
            reason += "; no plan yet"
        log.error("%s", reason)
        self.diagnostics(result, f"FAILED: {reason}", failed=True, extra=extra)
        return reason

    def withdraw(self, event: Withdrawn, stamp: float, current: list[Trajectory], current_start: float,
                 obstacles: tuple[Superquadric, ...]) -> None:
        """An empty Path for each withdrawn aircraft, their entries dropped from the latched LandingPlan and the
        markers, a diagnostic saying so; the other aircraft keep their plans."""
        with self._lock:
            gone = sorted(set(event.callsigns) & self.published)
            if not gone:
                return
            for cs in gone:
                self.path_publisher(cs).publish(empty_path(self.types, stamp, self.frame_id))
            self.published -= set(gone)
            if self.plan_msg is not None:
                self.plan_msg.aircraft = [a for a in self.plan_msg.aircraft if a.callsign not in gone]
                self.plan_pub.publish(self.plan_msg)
            self.markers(current, current_start, obstacles)
            message = f"plan of {', '.join(gone)} withdrawn: {event.why}"
            log.warning("%s", message)
            self.diagnostics(self.last_result, message, extra={"withdrawn": ",".join(gone)})

    def markers(self, trajectories: list[Trajectory], stamp: float, obstacles: tuple[Superquadric, ...]) -> None:
        self.marker_pub.publish(marker_array(self.types, obstacles, self.scenario.gates, trajectories, stamp,
                                             self.frame_id))

    # -- diagnostics ---------------------------------------------------------------------------------------------
    def diagnostics(self, result: PlanResult | None, message: str, failed: bool = False,
                    extra: dict[str, Any] | None = None) -> None:
        """The plan's status (kept: the 1 Hz diagnostics repeat it beside the radar status)."""
        level, values = plan_diagnostic_values(result, self.plans, failed)
        values |= extra or {}
        with self._diag_lock:
            self._plan_status = diagnostic_status(self.types, self.node.get_name(), level, message, values)
        self.publish_diagnostics()

    def publish_diagnostics(self) -> None:
        """One DiagnosticArray: the plan's status first, then the radar's (as a diagnostic_updater would); the
        radar status WARNs while messages are being rejected."""
        T = self.types
        with self._diag_lock:
            counts, tracked = self.radar()
            values, message = radar_diagnostic_values(counts, tracked)
            fresh = counts["rejected"] - self._rejected_reported
            self._rejected_reported = counts["rejected"]
            statuses = [self._plan_status, diagnostic_status(T, self.node.get_name(), DIAG_WARN if fresh else None,
                                                             message, values, name="radar")]
            header = T.msg("std_msgs/msg/Header")(stamp=time_to_msg(T, self.node.now()), frame_id="")
            self.diag_pub.publish(T.msg("diagnostic_msgs/msg/DiagnosticArray")(header=header, status=statuses))
