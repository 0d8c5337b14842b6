"""Partial plans (:attr:`~mal_planner.options.PlanOptions.partial`): which attempt to keep, and the plan of the
aircraft it planned.

The service would rather hand out the plans of the aircraft a sequential solve did plan (and hold the others) than
nothing: of a plan's attempts it keeps the one that planned the most aircraft, and stops at one that planned all but
those it left out.
"""

from __future__ import annotations

import logging
from dataclasses import replace

from mal_planner.initializer.sequencer import InitialPlan
from mal_planner.landing import LandingResult
from mal_planner.landing.aircraft_plans import planned_prefix
from mal_planner.scenario import Scenario

log = logging.getLogger("mal_planner")


def partial_plan(scenario: Scenario, landing: LandingResult, initial: InitialPlan
                 ) -> tuple[Scenario, LandingResult, InitialPlan, tuple[str, ...]]:
    """A failed sequential plan cut to the aircraft it planned (:attr:`PlanOptions.partial`), with those left
    unplanned; as it was (none unplanned) when it planned none."""
    part = planned_prefix(landing)
    if part is None:
        return scenario, landing, initial, ()
    names = {tr.callsign for tr in part.trajectories}
    unplanned = tuple(a.callsign for a in scenario.aircraft if a.callsign not in names)
    log.warning("partial plan: %d of %d aircraft planned (%s); %s left unplanned", len(names),
                len(scenario.aircraft), landing.status, ", ".join(unplanned))
    kept = replace(scenario, aircraft=tuple(a for a in scenario.aircraft if a.callsign in names))
    return kept, part, initial.only(names), unplanned


def better(kept: LandingResult | None, candidate: LandingResult, partial: bool) -> LandingResult:
    """The result to keep of ``kept`` and a new ``candidate``: a success; else, for a partial plan, the one that
    planned more aircraft before it failed (the earlier on a tie); else the latest failure."""
    if kept is None or candidate.success:
        return candidate
    if kept.success:
        return kept
    if not partial:
        return candidate
    return candidate if prefix_size(candidate) > prefix_size(kept) else kept


def others_planned(landing: LandingResult) -> bool:
    """Every aircraft planned but those left out (:attr:`LandingResult.left_out`): the plan to hand out now (the
    service holds those left out and plans them later)."""
    return bool(landing.left_out and landing.parts and all(p.success for p in landing.parts))


def prefix_size(landing: LandingResult) -> int:
    part = planned_prefix(landing)
    return 0 if part is None else len(part.trajectories)
