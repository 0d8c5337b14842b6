"""How one planning run ended: success or exactly one of :data:`mal_planner.errors.FAILURE_CLASSES`.

:func:`classify` is the single place that maps what the pipeline returned or raised (and, for a run in a
child process, how that process ended) to a failure class and a one-line reason.
"""

from __future__ import annotations

import signal
from dataclasses import dataclass
from typing import TYPE_CHECKING

from mal_planner.errors import FAILURE_CLASSES, PlanningError
from mal_planner.scenario import ScenarioError

if TYPE_CHECKING:
    from mal_planner.pipeline import PlanResult

MEMORY_MARKERS = ("MemoryError", "std::bad_alloc", "Cannot allocate memory", "out of memory")
"""Text in a dead child's last output that means it ran out of memory (RLIMIT_AS makes allocations fail)."""


@dataclass(frozen=True)
class Outcome:
    failure_class: str | None
    """None when the plan is optimal and verified, else one of FAILURE_CLASSES."""
    reason: str
    """One line: the first verification reason, the exception message, how the process ended ..."""

    @property
    def ok(self) -> bool:
        return self.failure_class is None

    def __post_init__(self) -> None:
        if self.failure_class is not None and self.failure_class not in FAILURE_CLASSES:
            raise ValueError(f"unknown failure class {self.failure_class!r}")


def one_line(text: str, limit: int = 300) -> str:
    """Collapse whitespace to one line of at most ``limit`` characters."""
    line = " ".join(str(text).split())
    return line if len(line) <= limit else line[: limit - 3] + "..."


def classify(result: PlanResult | None = None, error: BaseException | None = None, *,
             timed_out: float | None = None, exit_code: int | None = None, output_tail: str = "") -> Outcome:
    """The outcome of one planning run, from the first of these that applies.

    * ``timed_out`` (the limit in s): the run was killed at its time limit -> ``timeout``;
    * ``error``: what the run raised: ScenarioError / InvalidInput -> ``invalid_input``, InfeasibleRequest ->
      ``infeasible_request`` (any PlanningError: its own class), the initializer's PlanningFailed ->
      ``initializer_failed``, MemoryError -> ``out_of_memory``, anything else -> ``crash``;
    * ``result``: :attr:`PlanResult.failure` (optimizer not successful -> ``optimizer_failed``, plan not
      verified -> ``verification_failed``, either because the plan's time limit ran out -> ``timeout``);
      a campaign counts only a verified plan as success;
    * neither (the process died without a result): ``exit_code`` (negative: the signal) and the tail of its
      output -> ``out_of_memory`` when the output shows a failed allocation, else ``crash``.
    """
    from mal_planner.initializer.planners import PlanningFailed

    if timed_out is not None:
        return Outcome("timeout", f"no result within the time limit of {timed_out:g} s (killed)")
    if error is not None:
        message = one_line(f"{type(error).__name__}: {error}")
        if isinstance(error, ScenarioError):
            return Outcome("invalid_input", one_line(str(error)))
        if isinstance(error, PlanningError):
            return Outcome(error.failure_class, message)
        if isinstance(error, PlanningFailed):
            return Outcome("initializer_failed", one_line(str(error)))
        if isinstance(error, MemoryError):
            return Outcome("out_of_memory", message)
        return Outcome("crash", message)
    if result is not None:
        failure = result.failure  # the pipeline's own verdict, shared with mal-plan and the node
        if failure is not None:
            return Outcome(failure[0], one_line(failure[1]))
        if not result.verified:
            return Outcome("verification_failed", "the plan was not verified (optimizer or verification off)")
        return Outcome(None, "verified")
    return _dead_process(exit_code, output_tail)


def _dead_process(exit_code: int | None, output_tail: str) -> Outcome:
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
        return Outcome("out_of_memory", how + detail)
    return Outcome("crash", how + detail)
