"""The multiple-aircraft landing problem on the general OCP engine (thesis chapter 5, generalised)."""

from mal_planner.landing.base import LandingOptions, LandingResult
from mal_planner.landing.guess import AircraftGuess, guess_from_initial_plan, straight_line_guess
from mal_planner.landing.layout import Event, PhaseLayout, plan_layout
from mal_planner.landing.problem import LandingProblem, build_landing_problem
from mal_planner.landing.strategy import optimize_landing

__all__ = [
    "AircraftGuess",
    "Event",
    "LandingOptions",
    "LandingProblem",
    "LandingResult",
    "PhaseLayout",
    "build_landing_problem",
    "guess_from_initial_plan",
    "optimize_landing",
    "plan_layout",
    "plan_layout",
    "straight_line_guess",
]
