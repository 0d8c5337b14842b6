"""How a planning request can end badly: a small, fixed set of failure classes.

Every stage (CLI, node, campaigns) reports failures with one of :data:`FAILURE_CLASSES`, so that runs can
be compared. Exceptions that the pipeline raises for requests it refuses carry their class.
"""

from __future__ import annotations

from typing import Literal

FailureClass = Literal[
    "invalid_input",        # a file, message, parameter or option that cannot be used
    "infeasible_request",   # well-formed but impossible (unreachable landing times, separation broken at start)
    "initializer_failed",   # no initial paths / landing sequence found
    "optimizer_failed",     # IPOPT (or the mesh refinement) did not reach a solution
    "verification_failed",  # a solution whose flown controls break a minimum
    "timeout",              # the time limit ran out before a verified plan
    "out_of_memory",        # the planning process exhausted its memory limit
    "crash",                # anything else: an exception or a dead process
]
FAILURE_CLASSES: tuple[str, ...] = FailureClass.__args__  # type: ignore[attr-defined]


class PlanningError(Exception):
    """A request the planner refuses or cannot serve; ``str()`` is one line naming what and why."""

    failure_class: FailureClass = "crash"


class InvalidInput(PlanningError, ValueError):
    """Bad input: a file, field, option or message that cannot be used."""

    failure_class: FailureClass = "invalid_input"


class InfeasibleRequest(PlanningError, ValueError):
    """A well-formed request that no plan can satisfy (found before any NLP is built)."""

    failure_class: FailureClass = "infeasible_request"


class TimeLimitReached(PlanningError):
    """The plan's time limit ran out in a stage with nothing to return yet (the initializer); ``str()`` names the
    stage, e.g. "time limit 60 s reached in the initializer (RRT of aircraft T07, 41 of 100 planned)"."""

    failure_class: FailureClass = "timeout"
