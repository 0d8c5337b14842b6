"""How a planning request ends: one table of outcomes, the exceptions that carry them, and their classification.

Every interface (``mal-plan``, the node, the campaigns) reports a run as one :class:`Outcome` (``success`` or a
failure class), numbered by :data:`OUTCOMES` for each interface: the ``PlanLanding`` ``error_code`` (as Nav2's
planner error codes, 0 = none), ``mal-plan``'s exit code. Every exception the planner raises for a request it
refuses or cannot serve is a :class:`PlanningError` carrying its outcome; :func:`classify` maps whatever a run
returned or raised (and, for a run in a child process, how that process ended) to an outcome and a one-line reason.
"""

from __future__ import annotations

import enum
import signal
from dataclasses import dataclass
from typing import NamedTuple, Protocol


class Outcome(str, enum.Enum):
    """How a plan ended: success or exactly one failure class (str-valued: ``Outcome.TIMEOUT == "timeout"``)."""

    SUCCESS = "success"
    INVALID_INPUT = "invalid_input"
    """A file, message, parameter or option that cannot be used."""
    INFEASIBLE_REQUEST = "infeasible_request"
    """Well-formed but impossible (unreachable landing times, separation broken at start)."""
    INITIALIZER_FAILED = "initializer_failed"
    """No initial paths or landing sequence found."""
    OPTIMIZER_FAILED = "optimizer_failed"
    """IPOPT (or the mesh refinement) did not reach a solution."""
    VERIFICATION_FAILED = "verification_failed"
    """A solution whose flown controls break a minimum."""
    TIMEOUT = "timeout"
    """The time limit ran out before a verified plan."""
    OUT_OF_MEMORY = "out_of_memory"
    """The planning process exhausted its memory limit."""
    CRASH = "crash"
    """Anything else: an exception or a dead process."""

    __str__ = str.__str__
    __format__ = str.__format__

    @property
    def code(self) -> OutcomeCode:
        return _BY_NAME[self]


FailureClass = Outcome
"""A failure class: an :class:`Outcome` other than ``SUCCESS``."""
FAILURE_CLASSES: tuple[str, ...] = tuple(o.value for o in Outcome if o is not Outcome.SUCCESS)


@dataclass(frozen=True)
class OutcomeCode:
    """How a plan ended, as every interface reports it: the outcome, the error code (``PlanLanding`` response
    ``error_code`` and its ``ERROR_*`` constants, diagnostics, ``plan.json``; numbered as Nav2's planner error codes
    are, 0 = none), ``mal-plan``'s exit code, and what it means."""

    name: Outcome
    error_code: int
    exit_code: int
    meaning: str


OUTCOMES: tuple[OutcomeCode, ...] = (
    OutcomeCode(Outcome.SUCCESS, 0, 0, "a verified plan (or, with --initial-only, the initial trajectories)"),
    OutcomeCode(Outcome.INVALID_INPUT, 1, 2, "bad input: a file, message, parameter or option (one line, before "
                                             "planning)"),
    OutcomeCode(Outcome.INFEASIBLE_REQUEST, 2, 2, "an impossible request: unreachable landing times, separation "
                                                  "broken at the start (one line, before planning)"),
    OutcomeCode(Outcome.INITIALIZER_FAILED, 3, 1, "the initializer found no initial paths or landing sequence"),
    OutcomeCode(Outcome.OPTIMIZER_FAILED, 4, 1, "the optimizer found no plan"),
    OutcomeCode(Outcome.VERIFICATION_FAILED, 5, 3, "the optimizer succeeded but the plan failed the independent "
                                                   "verification"),
    OutcomeCode(Outcome.TIMEOUT, 6, 4, "the time limit ran out before a verified plan"),
    OutcomeCode(Outcome.OUT_OF_MEMORY, 7, 1, "the planning process ran out of memory"),
    OutcomeCode(Outcome.CRASH, 8, 1, "anything else: an exception or a dead process"),
)
"""The one table of outcomes; ``ros2_ws/src/mal_msgs/srv/PlanLanding.srv`` declares the same ``ERROR_*``
constants (``tests/test_msgs.py`` holds them equal)."""

_BY_NAME = {o.name: o for o in OUTCOMES}
if set(_BY_NAME) != set(Outcome):
    raise AssertionError("OUTCOMES must list every Outcome once")


def outcome_code(failure: Outcome | str | None) -> OutcomeCode:
    """The code of an outcome (a failure class; None: success)."""
    return _BY_NAME[Outcome.SUCCESS if failure is None else Outcome(failure)]


def exit_codes_help() -> str:
    """``mal-plan --help``'s exit-code section, from :data:`OUTCOMES`."""
    lines = ["exit codes (outcome: meaning):"]
    for code in sorted({o.exit_code for o in OUTCOMES}):
        for k, o in enumerate(o for o in OUTCOMES if o.exit_code == code):
            lines.append(f"  {str(code) if k == 0 else ' '}  {o.name}: {o.meaning}")
    return "\n".join(lines) + "\n"


class Failure(NamedTuple):
    """Why a result is not a verified plan: its failure class and one line."""

    outcome: Outcome
    reason: str


# -- the exceptions ------------------------------------------------------------------------------------------------
class PlanningError(Exception):
    """A request the planner refuses or cannot serve; ``str()`` is one line naming what and why."""

    outcome: Outcome = Outcome.CRASH
    named_in_reason: bool = True
    """A classified run's reason starts with the exception's type (not for a scenario file's own errors)."""

    @property
    def failure_class(self) -> Outcome:
        return self.outcome


class InvalidInput(PlanningError, ValueError):
    """Bad input: a file, field, option or message that cannot be used."""

    outcome = Outcome.INVALID_INPUT


class InfeasibleRequest(PlanningError, ValueError):
    """A well-formed request that no plan can satisfy (found before any NLP is built)."""

    outcome = Outcome.INFEASIBLE_REQUEST


class PlanningFailed(PlanningError, RuntimeError):
    """The initializer found no path (or no landing sequence) for an aircraft."""

    outcome = Outcome.INITIALIZER_FAILED
    named_in_reason = False


class TimeLimitReached(PlanningError):
    """The plan's time limit ran out in a stage with nothing to return yet (the initializer); ``str()`` names the
    stage, e.g. "time limit 60 s reached in the initializer (RRT of aircraft T07, 41 of 100 planned)"."""

    outcome = Outcome.TIMEOUT
    named_in_reason = True


# -- classification ------------------------------------------------------------------------------------------------
MEMORY_MARKERS = ("MemoryError", "std::bad_alloc", "Cannot allocate memory", "out of memory")
"""Text in a dead child's last output that means it ran out of memory (RLIMIT_AS makes allocations fail)."""


class _Result(Protocol):
    """What :func:`classify` reads of a :class:`~mal_planner.pipeline.PlanResult`."""

    @property
    def failure(self) -> Failure | None: ...

    @property
    def verified(self) -> bool: ...


@dataclass(frozen=True)
class RunOutcome:
    """How one planning run ended: its outcome and one line (the first verification reason, the exception's
    message, how the process ended ...)."""

    outcome: Outcome
    reason: str

    @property
    def ok(self) -> bool:
        return self.outcome is Outcome.SUCCESS

    @property
    def failure_class(self) -> Outcome | None:
        """None when the plan is verified, else the failure class."""
        return None if self.ok else self.outcome


def one_line(text: str, limit: int = 300) -> str:
    """Collapse whitespace to one line of at most ``limit`` characters."""
    line = " ".join(str(text).split())
    return line if len(line) <= limit else line[: limit - 3] + "..."


def classify(result: _Result | None = None, error: BaseException | None = None, *,
             timed_out: float | None = None, exit_code: int | None = None, output_tail: str = "") -> RunOutcome:
    """The outcome of one planning run, from the first of these that applies.

    * ``timed_out`` (the limit in s): the run was killed at its time limit -> ``timeout``;
    * ``error``: what the run raised: a :class:`PlanningError` (a scenario file's error is an
      :class:`InvalidInput`, the initializer's :class:`PlanningFailed` ``initializer_failed``) -> its own outcome,
      MemoryError -> ``out_of_memory``, anything else -> ``crash``;
    * ``result``: :attr:`PlanResult.failure` (optimizer not successful -> ``optimizer_failed``, plan not verified
      -> ``verification_failed``, either because the plan's time limit ran out -> ``timeout``); a campaign counts
      only a verified plan as success;
    * neither (the process died without a result): ``exit_code`` (negative: the signal) and the tail of its
      output -> ``out_of_memory`` when the output shows a failed allocation, else ``crash``.
    """
    if timed_out is not None:
        return RunOutcome(Outcome.TIMEOUT, f"no result within the time limit of {timed_out:g} s (killed)")
    if error is not None:
        if isinstance(error, PlanningError):
            named = error.named_in_reason
            return RunOutcome(error.outcome, one_line(f"{type(error).__name__}: {error}" if named else str(error)))
        outcome = Outcome.OUT_OF_MEMORY if isinstance(error, MemoryError) else Outcome.CRASH
        return RunOutcome(outcome, one_line(f"{type(error).__name__}: {error}"))
    if result is not None:
        failure = result.failure  # the pipeline's own verdict, shared with mal-plan and the node
        if failure is not None:
            return RunOutcome(failure.outcome, one_line(failure.reason))
        if not result.verified:
            return RunOutcome(Outcome.VERIFICATION_FAILED, "the plan was not verified (optimizer or verification off)")
        return RunOutcome(Outcome.SUCCESS, "verified")
    return _dead_process(exit_code, output_tail)


def _dead_process(exit_code: int | None, output_tail: str) -> RunOutcome:
    last = next((line for line in reversed(output_tail.strip().splitlines()) if line.strip()), "")
    if exit_code is None:
        how = "the planning process ended without a result"
    elif exit_code < 0:
        try:
            name = signal.Signals(-exit_code).name
        except ValueError:
            name = f"signal {-exit_code}"
        how = f"the planning process was killed by {name}"
    else:
        how = f"the planning process exited with code {exit_code} without a result"
    detail = f" ({one_line(last, 200)})" if last else ""
    if any(marker in output_tail for marker in MEMORY_MARKERS):
        return RunOutcome(Outcome.OUT_OF_MEMORY, how + detail)
    return RunOutcome(Outcome.CRASH, how + detail)
