"""The optimizer a scenario gets: one NLP for all aircraft (:class:`~mal_planner.landing.solve.LandingOptimizer`) or
one per aircraft in landing order (:mod:`mal_planner.landing.sequential`)."""

from __future__ import annotations

from mal_planner.landing.base import LandingOptions, LandingResult
from mal_planner.landing.guess import AircraftGuess
from mal_planner.landing.sequential import SequentialOptimizer
from mal_planner.landing.solve import LandingOptimizer, make_guesses, uses_sequential
from mal_planner.scenario import Scenario


def make_optimizer(scenario: Scenario, guesses: list[AircraftGuess], options: LandingOptions, reguess=None):
    """The optimizer ``options.strategy`` asks for: a :class:`LandingOptimizer` or a SequentialOptimizer (whose
    first recovery, a new guess, comes from ``reguess``; see :data:`mal_planner.landing.sequential.Reguess`)."""
    if uses_sequential(options, len(guesses)):
        return SequentialOptimizer(scenario, guesses, options, reguess)
    return LandingOptimizer(scenario, guesses, options)


def optimize_landing(scenario: Scenario, initial_plan=None, options: LandingOptions | None = None) -> LandingResult:
    """One-shot: build and solve (see :class:`LandingOptimizer` for re-solving)."""
    options = options or LandingOptions()
    guesses = make_guesses(scenario, initial_plan, options)
    return make_optimizer(scenario, guesses, options).solve()
