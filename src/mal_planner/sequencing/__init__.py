"""Arrival sequencing: the one place where landing order and times are decided.

:func:`sequence` solves a :class:`SequencingProblem` (Beasley's static aircraft landing problem: windows,
targets, costs per second early and late, pairwise separations) with a strategy of
:class:`SequencingOptions`: ``fcfs`` (first come, first served) or ``optimal`` (a MILP on HiGHS).
"""

from typing import Any

from mal_planner.sequencing.fcfs import first_come_first_served
from mal_planner.sequencing.problem import (
    OBJECTIVES,
    STRATEGIES,
    SequenceResult,
    SequencingInfeasible,
    SequencingOptions,
    SequencingProblem,
)

__all__ = ["OBJECTIVES", "STRATEGIES", "SequenceResult", "SequencingInfeasible", "SequencingOptions",
           "SequencingProblem", "first_come_first_served", "sequence", "solve_milp"]


def sequence(problem: SequencingProblem, options: SequencingOptions | None = None) -> SequenceResult:
    """The landing order and times by ``options.strategy``; raises :class:`SequencingInfeasible`."""
    options = options or SequencingOptions()
    if options.strategy == "fcfs":
        return first_come_first_served(problem)
    if options.strategy == "optimal":
        from mal_planner.sequencing.milp import solve_milp  # SciPy's optimizers load only when needed

        return solve_milp(problem, options)
    raise ValueError(f"sequencing strategy: expected one of {', '.join(STRATEGIES)}, got {options.strategy!r}")


def __getattr__(name: str) -> Any:
    if name == "solve_milp":
        from mal_planner.sequencing.milp import solve_milp

        return solve_milp
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
