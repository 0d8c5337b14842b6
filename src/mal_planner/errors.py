"""How a planning request can end badly: a small, fixed set of failure classes.

Every stage (CLI, node, campaigns) reports failures with one of :data:`FAILURE_CLASSES`, so that runs can
be compared. Exceptions that the pipeline raises for requests it refuses carry their class.
"""

from __future__ import annotations

from dataclasses import dataclass
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


@dataclass(frozen=True)
class OutcomeCode:
    """How a plan ended, as every interface reports it: the name (``success`` or a failure class), the error code
    (``PlanLanding`` response ``error_code`` and its ``ERROR_*`` constants, diagnostics, ``plan.json``; numbered as
    Nav2's planner error codes are, 0 = none), ``mal-plan``'s exit code, and what it means."""

    name: str
    error_code: int
    exit_code: int
    meaning: str


OUTCOMES: tuple[OutcomeCode, ...] = (
    OutcomeCode("success", 0, 0, "a verified plan (or, with --initial-only, the initial trajectories)"),
    OutcomeCode("invalid_input", 1, 2, "bad input: a file, message, parameter or option (one line, before planning)"),
    OutcomeCode("infeasible_request", 2, 2, "an impossible request: unreachable landing times, separation broken "
                                            "at the start (one line, before planning)"),
    OutcomeCode("initializer_failed", 3, 1, "the initializer found no initial paths or landing sequence"),
    OutcomeCode("optimizer_failed", 4, 1, "the optimizer found no plan"),
    OutcomeCode("verification_failed", 5, 3, "the optimizer succeeded but the plan failed the independent "
                                             "verification"),
    OutcomeCode("timeout", 6, 4, "the time limit ran out before a verified plan"),
    OutcomeCode("out_of_memory", 7, 1, "the planning process ran out of memory"),
    OutcomeCode("crash", 8, 1, "anything else: an exception or a dead process"),
)
"""The one table of outcomes; ``ros2_ws/src/mal_msgs/srv/PlanLanding.srv`` declares the same ``ERROR_*``
constants (``tests/test_msgs.py`` holds them equal)."""

_BY_NAME = {o.name: o for o in OUTCOMES}
if set(_BY_NAME) != {"success", *FAILURE_CLASSES}:
    raise AssertionError("OUTCOMES must list 'success' and every failure class once")


def outcome_code(failure_class: str | None) -> OutcomeCode:
    """The outcome of a failure class (None: success)."""
    return _BY_NAME["success" if failure_class is None else failure_class]


def exit_codes_help() -> str:
    """``mal-plan --help``'s exit-code section, from :data:`OUTCOMES`."""
    lines = ["exit codes (outcome: meaning):"]
    for code in sorted({o.exit_code for o in OUTCOMES}):
        for k, o in enumerate(o for o in OUTCOMES if o.exit_code == code):
            lines.append(f"  {str(code) if k == 0 else ' '}  {o.name}: {o.meaning}")
    return "\n".join(lines) + "\n"


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
