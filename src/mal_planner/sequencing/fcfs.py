"""First come, first served: the order of the target times, each aircraft at its earliest free slot.

Aircraft whose window is a single instant (a fixed landing time) keep it and are placed first; the others,
in first-come order, take the earliest time at or after max(earliest, target) that keeps the separation to
every time already taken (in both directions: a slot between two taken times must fit both).
"""

from __future__ import annotations

import time

import numpy as np

from mal_planner.sequencing.problem import SequenceResult, SequencingInfeasible, SequencingProblem

SLOT_TOL_S = 1e-9


def earliest_slot(problem: SequencingProblem, i: int, start: float, placed: dict[int, float]) -> float:
    """The earliest time >= ``start`` at which ``i`` keeps the separation to every placed aircraft."""
    S = problem.separation
    t = start
    moved = True
    while moved:
        moved = False
        for k, tk in sorted(placed.items(), key=lambda item: item[1]):
            if tk - S[i, k] < t < tk + S[k, i]:  # i would land too close after k, or k too close after i
                t = tk + S[k, i]
                moved = True
    return t


def first_come_first_served(problem: SequencingProblem) -> SequenceResult:
    """The first-come-first-served schedule; raises :class:`SequencingInfeasible` past a latest time."""
    t0 = time.perf_counter()
    times: dict[int, float] = {i: float(problem.earliest[i]) for i in range(problem.n)
                               if problem.earliest[i] == problem.latest[i]}
    S = problem.separation
    for i in times:
        for j in times:
            if i != j and times[i] <= times[j] < times[i] + S[i, j]:
                raise SequencingInfeasible(
                    f"{problem.names[i]} and {problem.names[j]}: fixed landing times {times[i]:g} s and {times[j]:g} s "
                    f"are closer than their separation {S[i, j]:g} s", (problem.names[i], problem.names[j]))
    for i in problem.first_come_order():
        if i in times:
            continue
        t = earliest_slot(problem, i, max(float(problem.earliest[i]), float(problem.target[i])), times)
        if t > problem.latest[i] + SLOT_TOL_S:
            raise SequencingInfeasible(
                f"{problem.names[i]}: first come, first served lands it at {t:.1f} s at the earliest, after its "
                f"latest landing time {problem.latest[i]:.1f} s", (problem.names[i],))
        times[i] = float(t)
    x = np.array([times[i] for i in range(problem.n)])
    order = tuple(sorted(range(problem.n), key=lambda i: (x[i], problem.earliest[i], problem.names[i])))
    cost = problem.cost(x)
    return SequenceResult(order, x, cost, cost, "fcfs", "cost", "heuristic", None, None,
                          time.perf_counter() - t0)
