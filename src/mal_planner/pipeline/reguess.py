"""A new initial guess of one aircraft, clear of the traffic: the sequential strategy's recovery 'another guess'.

One definition for every plan that recovers this way (:class:`~mal_planner.pipeline.planner.Planner`'s plans and
:func:`~mal_planner.pipeline.among.plan_joining`): each attempt draws the initializer's seed plus a prime step, so
attempts differ and a run is reproducible.
"""

from __future__ import annotations

import logging

from mal_planner.deadline import Deadline
from mal_planner.errors import PlanningFailed
from mal_planner.initializer.base import PathPlanner
from mal_planner.initializer.sequencer import Sequencer
from mal_planner.landing.guess import AircraftGuess, guess_from_initial_plan
from mal_planner.scenario import Scenario

log = logging.getLogger("mal_planner")

SEED_STEP = 7919
"""Seed offset per attempt (a prime, so attempts of neighbouring seeds do not repeat one another)."""


def another_guess(initializer: str | PathPlanner, seed: int | None, deadline: Deadline | None, scenario: Scenario,
                  callsign: str, landing_time: float, traffic, attempt: int) -> AircraftGuess | None:
    """``callsign``'s new initial path to land at ``landing_time`` clear of ``traffic`` (timed paths), by the
    ``initializer`` (options or a name) with attempt ``attempt``'s seed, as a guess; None when none is found."""
    seed = None if seed is None else seed + SEED_STEP * (attempt + 1)
    try:
        path = Sequencer(initializer).replan_one(scenario, callsign, landing_time, traffic, seed, deadline=deadline)
    except PlanningFailed as exc:
        log.info("%s: no new initial path (%s)", callsign, exc)
        return None
    return guess_from_initial_plan(scenario, [path], [landing_time])[0]
