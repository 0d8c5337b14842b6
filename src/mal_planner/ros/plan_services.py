"""The planner node's services: ``plan`` (std_srvs/Trigger: a plan of the radar picture) and ``plan_landing``
(mal_msgs/PlanLanding: a what-if plan of explicit states, or of the radar picture). Reentrant: each call waits on a
worker thread of the transport for its plan, without holding up the radar callbacks.
"""

from __future__ import annotations

import logging
from concurrent.futures import Future
from typing import Any, Protocol

from mal_planner.errors import Outcome
from mal_planner.ros.convert import aircraft_state_to_planner
from mal_planner.ros.node_params import NodeParams
from mal_planner.ros.plan_jobs import PlanOutcome
from mal_planner.service.core import PlanningService
from mal_planner.service.tracks import Track

log = logging.getLogger("mal_planner.ros.planner")


class Planner(Protocol):
    """What the services use of the planner node."""

    params: NodeParams
    service: PlanningService

    def request(self, reason: str, explicit: dict[str, Track] | None = None, lead: bool = True
                ) -> Future[PlanOutcome]: ...


class PlanServices:
    """The service handlers of one planner node."""

    def __init__(self, planner: Planner) -> None:
        self.planner = planner

    def wait(self, future: Future[PlanOutcome]) -> PlanOutcome:
        try:
            return future.result(timeout=self.planner.params.service_timeout_s)
        except TimeoutError:
            limit = self.planner.params.service_timeout_s
            return PlanOutcome(False, f"no plan within {limit:.0f} s", failure=Outcome.TIMEOUT)

    def trigger(self, request: Any, response: Any) -> Any:
        del request
        if not len(self.planner.service.intake):
            response.success, response.message = False, "no radar tracks yet"
            return response
        outcome = self.wait(self.planner.request("service plan", lead=False))
        response.success, response.message = outcome.success, outcome.message
        return response

    def plan_landing(self, request: Any, response: Any) -> Any:
        explicit, problem = self.explicit_states(request.aircraft)
        if problem is not None:
            response.success, response.message = False, problem
            response.error_code = Outcome.INVALID_INPUT.code.error_code
            log.error("plan_landing request rejected: %s", problem)
            return response
        if explicit:
            future = self.planner.request(f"plan_landing service ({len(explicit)} explicit states)", explicit)
        elif len(self.planner.service.intake):
            future = self.planner.request("plan_landing service (radar tracks)", lead=False)
        else:
            response.success, response.message = False, "no aircraft given and no radar tracks yet"
            response.error_code = Outcome.INVALID_INPUT.code.error_code
            return response
        outcome = self.wait(future)
        response.success, response.message, response.error_code = outcome.success, outcome.message, outcome.error_code
        if outcome.plan_msg is not None:
            response.plan = outcome.plan_msg
        response.paths = list(outcome.path_msgs)
        return response

    def explicit_states(self, messages: list[Any]) -> tuple[dict[str, Track], str | None]:
        """The tracks of a PlanLanding request, each through the intake's gates; the first problem (one line)."""
        explicit: dict[str, Track] = {}
        for i, msg in enumerate(messages):
            callsign = "?"
            try:
                track = Track(*aircraft_state_to_planner(msg))
                callsign = track.callsign
                reason = self.planner.service.intake.check_alone(track, str(msg.header.frame_id))
            except Exception as exc:
                reason = str(exc)
            if reason is None and callsign in explicit:
                reason = "duplicate callsign"
            if reason is not None:
                return {}, f"aircraft[{i}] ({callsign}): {reason}"
            explicit[callsign] = track
        return explicit, None

