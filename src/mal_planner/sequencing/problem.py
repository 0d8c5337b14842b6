"""The static aircraft landing problem (Beasley et al. 2000) that every sequencing strategy solves.

Aircraft i lands at x_i in [E_i, L_i]; when i lands before j, x_j >= x_i + S_ij (every pair, not only
consecutive ones: S need not obey the triangle inequality). Landing before the target T_i costs g_i per
second, after it h_i per second. Times are seconds from any common origin (the plan start, or the
OR-Library file's own clock).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mal_planner.scenario.sequencing import OBJECTIVES, STRATEGIES, Objective, SequencingOptions, Strategy

__all__ = ["OBJECTIVES", "STRATEGIES", "Objective", "SequenceResult", "SequencingInfeasible", "SequencingOptions",
           "SequencingProblem", "Strategy"]



class SequencingInfeasible(ValueError):
    """No landing sequence meets the time windows; ``str()`` is one line naming the aircraft."""

    def __init__(self, message: str, names: tuple[str, ...] = ()) -> None:
        super().__init__(message)
        self.names = names




@dataclass(frozen=True)
class SequencingProblem:
    names: tuple[str, ...]
    earliest: np.ndarray
    target: np.ndarray
    latest: np.ndarray
    """May hold inf (no latest time): strategies bound it by :meth:`horizon`."""
    cost_early: np.ndarray
    cost_late: np.ndarray
    separation: np.ndarray
    """(n, n): S[i, j] seconds from i's landing to j's when i lands first (the diagonal is ignored)."""

    def __post_init__(self) -> None:
        n = len(self.names)
        for field in ("earliest", "target", "latest", "cost_early", "cost_late"):
            value = np.asarray(getattr(self, field), float)
            if value.shape != (n,):
                raise ValueError(f"{field}: expected {n} values, got shape {value.shape}")
            object.__setattr__(self, field, value)
        sep = np.asarray(self.separation, float)
        if sep.shape != (n, n):
            raise ValueError(f"separation: expected a {n} x {n} matrix, got shape {sep.shape}")
        object.__setattr__(self, "separation", sep)
        if len(set(self.names)) != n:
            raise ValueError(f"aircraft names must be unique, got {list(self.names)}")
        for field in ("earliest", "target", "cost_early", "cost_late"):
            bad = [self.names[i] for i in range(n) if not np.isfinite(getattr(self, field)[i])]
            if bad:
                raise ValueError(f"{bad[0]}: {field} must be finite")
        if np.any(np.isnan(self.latest)) or np.any(np.isnan(sep)) or np.any(sep < 0):
            raise ValueError("latest landing times and separations must be numbers, separations >= 0")
        negative = [self.names[i] for i in range(n) if self.cost_early[i] < 0 or self.cost_late[i] < 0]
        if negative:
            raise ValueError(f"{negative[0]}: costs per second early and late must be >= 0")
        for i in range(n):
            if self.latest[i] < self.earliest[i]:
                raise SequencingInfeasible(
                    f"{self.names[i]}: latest landing time {self.latest[i]:g} s is before its earliest "
                    f"{self.earliest[i]:g} s", (self.names[i],))

    @property
    def n(self) -> int:
        return len(self.names)

    def first_come_order(self) -> list[int]:
        """First come: by target time, then earliest time, then name."""
        return sorted(range(self.n), key=lambda i: (self.target[i], self.earliest[i], self.names[i]))

    def cost(self, times: np.ndarray) -> float:
        x = np.asarray(times, float)
        return float(np.sum(self.cost_early * np.maximum(self.target - x, 0.0)
                            + self.cost_late * np.maximum(x - self.target, 0.0)))

    def objective_value(self, times: np.ndarray, objective: Objective) -> float:
        return float(np.max(times)) if objective == "makespan" else self.cost(times)

    def horizon(self) -> float:
        """A landing time no optimal schedule needs to exceed: every aircraft can be served after all the
        others' earliest and target times, one largest separation apart."""
        off = self.separation[~np.eye(self.n, dtype=bool)] if self.n > 1 else np.zeros(1)
        start = float(max(np.max(self.earliest), np.max(np.minimum(self.target, self.latest))))
        return start + self.n * float(max(np.max(off), 0.0)) + 1.0

    def bounded_latest(self) -> np.ndarray:
        return np.where(np.isfinite(self.latest), self.latest, max(self.horizon(), float(np.max(
            np.where(np.isfinite(self.latest), self.latest, -math.inf)))))

    def violations(self, times: np.ndarray, tol: float = 1e-6) -> list[str]:
        """Windows and separations broken by ``times`` (empty when the schedule is feasible)."""
        x = np.asarray(times, float)
        out = [f"{self.names[i]}: lands at {x[i]:g}, outside [{self.earliest[i]:g}, {self.latest[i]:g}]"
               for i in range(self.n) if x[i] < self.earliest[i] - tol or x[i] > self.latest[i] + tol]
        order = np.argsort(x, kind="stable")
        for a in range(self.n):
            for b in range(a + 1, self.n):
                i, j = order[a], order[b]
                if x[j] - x[i] < self.separation[i, j] - tol:
                    out.append(f"{self.names[i]}->{self.names[j]}: {x[j] - x[i]:g} s apart, "
                               f"needs {self.separation[i, j]:g} s")
        return out


@dataclass(frozen=True)
class SequenceResult:
    order: tuple[int, ...]
    """Indices into the problem's aircraft, first to land first."""
    times: np.ndarray
    """Landing time of each aircraft (problem index)."""
    value: float
    """The objective's value (cost or makespan)."""
    cost: float
    """Beasley's cost of these times (whatever the objective)."""
    strategy: str
    objective: str
    status: str
    """optimal, feasible (time limit: best found, see ``gap``) or heuristic (first come, first served)."""
    gap: float | None
    """Proven relative gap (value - bound) / value; 0 when optimal, None for a heuristic."""
    bound: float | None
    solve_time_s: float

    def order_names(self, problem: SequencingProblem) -> list[str]:
        return [problem.names[i] for i in self.order]
