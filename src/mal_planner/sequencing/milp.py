"""Optimal sequencing: the aircraft landing problem as a mixed-integer programme on HiGHS (SciPy's milp).

Beasley's formulation, tightened (:mod:`.formulation`), is narrowed before HiGHS branches on it:

* **Windows and pairs fixed by cost** (:mod:`.bounds`): a heuristic schedule bounds the optimum from above,
  the LP relaxation from below; each variable's reduced cost then bounds how far it can move in any schedule
  that is no worse, which narrows the windows, fixes pairs and shrinks the big-Ms, round after round.
* **Independent blocks.** When the narrowed windows split the aircraft into groups that no separation
  links, each group is its own, smaller MILP.

A time limit returns the best schedule found and the proven gap.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from mal_planner.sequencing.bounds import solve_narrowed
from mal_planner.sequencing.fcfs import first_come_first_served
from mal_planner.sequencing.problem import (
    SequenceResult,
    SequencingInfeasible,
    SequencingOptions,
    SequencingProblem,
)


def solve_milp(problem: SequencingProblem, options: SequencingOptions) -> SequenceResult:
    """The optimal schedule (or the best within the time limit); raises SequencingInfeasible."""
    t0 = time.perf_counter()
    times, optimal, bound = solve_narrowed(problem, options, t0 + options.time_limit_s)
    if times is None:
        return _fallback(problem, options, t0)
    x = np.asarray(times, float)
    order = tuple(sorted(range(problem.n), key=lambda i: (x[i], problem.earliest[i], problem.names[i])))
    value = problem.objective_value(x, options.objective)
    gap = 0.0 if optimal else _gap(value, bound)
    return SequenceResult(order, x, value, problem.cost(x), "optimal", options.objective,
                          "optimal" if optimal else "feasible", gap, value if optimal else bound,
                          time.perf_counter() - t0)


def _gap(value: float, bound: float | None) -> float | None:
    """HiGHS's relative gap (value - bound) / |value| (0 when both are 0)."""
    if bound is None:
        return None
    if value == 0.0:
        return 0.0 if bound >= 0.0 else 1.0
    return max(0.0, (value - bound) / abs(value))


def _fallback(problem: SequencingProblem, options: SequencingOptions, t0: float) -> SequenceResult:
    """Time limit without any schedule: first come, first served if it fits the windows."""
    try:
        fallback = first_come_first_served(problem)
    except SequencingInfeasible:
        raise TimeoutError(f"no landing sequence found within the time limit of {options.time_limit_s:g} s"
                           ) from None
    return dataclasses.replace(fallback, value=problem.objective_value(fallback.times, options.objective),
                               objective=options.objective, status="feasible", solve_time_s=time.perf_counter() - t0)
