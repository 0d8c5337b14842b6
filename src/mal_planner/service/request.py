"""A plan the service asks for: its inputs, options and reason (the base type the core and the book share)."""

from __future__ import annotations

from dataclasses import dataclass

from mal_planner.options import PlanOptions
from mal_planner.scenario import Scenario
from mal_planner.scenario.traffic import Traffic
from mal_planner.service.inputs import PlanInputs


@dataclass(frozen=True)
class PlanRequest:
    """One plan to make: its inputs (the scenario at ``plan_start``), options and why it was asked for."""

    reason: str
    made_at: float
    """The radar's time when it was made."""
    plan_start: float
    """The time its initial states hold (``made_at`` plus the lead, for a replan the policy asked for)."""
    inputs: PlanInputs
    options: PlanOptions
    what_if: bool = False
    """Answered, never handed out (explicit states from a service call)."""
    given_tracks: bool = False
    """Made from tracks the caller gave, not from the radar's."""
    traffic: Traffic | None = None
    """A replan of what changed: the aircraft of ``scenario`` replanned among this traffic
    (:mod:`mal_planner.service.subsets`); None: a whole plan."""

    @property
    def scenario(self) -> Scenario:
        return self.inputs.scenario
