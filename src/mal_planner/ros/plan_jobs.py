"""The planner node's queue of plans to make: what-if plans in order, radar plans coalesced into one.

A radar plan asked for while one waits joins it (its reason added, its caller answered by the same plan); what-if
plans (explicit states from a service call) each get their own. The node's plan thread takes them one at a time.
"""

from __future__ import annotations

import threading
from collections import deque
from concurrent.futures import Future
from dataclasses import dataclass, field
from typing import Any

from mal_planner.errors import Outcome
from mal_planner.pipeline import PlanResult
from mal_planner.service.tracks import Track


@dataclass
class PlanOutcome:
    """How one job ended, for the service call that asked for it."""

    success: bool
    message: str
    plan_msg: Any = None
    path_msgs: list[Any] = field(default_factory=list)
    result: PlanResult | None = None
    failure: Outcome | None = None
    """None, or why the plan failed or is not verified."""

    @property
    def error_code(self) -> int:
        return (self.failure or Outcome.SUCCESS).code.error_code


@dataclass
class PlanJob:
    """Work for the plan thread: a radar plan (``explicit`` None, coalesced) or a what-if plan."""

    reasons: list[str]
    explicit: dict[str, Track] | None = None
    lead: bool = True
    """Start the plan ahead of the tracks (the policy's replans); False: from the tracks as they are."""
    waiters: list[Future[PlanOutcome]] = field(default_factory=list)

    @property
    def what_if(self) -> bool:
        return self.explicit is not None


class JobQueue:
    """Thread-safe: callbacks and services put, the plan thread takes (blocking)."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._what_if: deque[PlanJob] = deque()
        self._radar: PlanJob | None = None
        self.busy = False
        """The plan thread is planning."""
        self.stopped = False

    def put(self, reason: str, explicit: dict[str, Track] | None = None, lead: bool = True) -> Future[PlanOutcome]:
        future: Future[PlanOutcome] = Future()
        with self._cond:
            if self.stopped:
                future.set_result(PlanOutcome(False, "planner is shutting down", failure=Outcome.CRASH))
                return future
            if explicit is not None:
                self._what_if.append(PlanJob([reason], explicit, False, [future]))
            elif self._radar is None:
                self._radar = PlanJob([reason], None, lead, [future])
            else:
                self._radar.reasons.append(reason)
                self._radar.lead = self._radar.lead and lead
                self._radar.waiters.append(future)
            self._cond.notify_all()
        return future

    @property
    def pending(self) -> bool:
        return self._radar is not None or bool(self._what_if)

    def take(self) -> PlanJob | None:
        """The next job (what-if plans first), waiting for one; None once stopped."""
        with self._cond:
            while not self.stopped and not self.pending:
                self._cond.wait()
            if self.stopped:
                return None
            job = self._what_if.popleft() if self._what_if else self._radar
            if job is self._radar:
                self._radar = None
            self.busy = True
            return job

    def done(self, job: PlanJob, outcome: PlanOutcome) -> None:
        with self._cond:
            self.busy = False
        for fut in job.waiters:
            if not fut.done():
                fut.set_result(outcome)

    def stop(self) -> None:
        """No more jobs: the waiting ones are answered "shutting down"."""
        with self._cond:
            if self.stopped:
                return
            self.stopped = True
            jobs = list(self._what_if) + ([self._radar] if self._radar else [])
            self._what_if.clear()
            self._radar = None
            self._cond.notify_all()
        for job in jobs:
            self.done(job, PlanOutcome(False, "planner is shutting down", failure=Outcome.CRASH))
