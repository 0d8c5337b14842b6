"""How a scenario's landing order and free landing times are decided (``sequencing:``; ``mal-schedule``'s options).

The strategies themselves are in :mod:`mal_planner.sequencing`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

Strategy = Literal["fcfs", "optimal"]
Objective = Literal["cost", "makespan"]
STRATEGIES: tuple[str, ...] = Strategy.__args__  # type: ignore[attr-defined]
OBJECTIVES: tuple[str, ...] = Objective.__args__  # type: ignore[attr-defined]


@dataclass(frozen=True)
class SequencingOptions:
    """How the order and the times are chosen (scenario file ``sequencing:``, ``mal-schedule`` options)."""

    strategy: Strategy = "fcfs"
    """fcfs: first come (by target time), first served, each at its earliest free slot; optimal: a MILP."""
    objective: Objective = "cost"
    """cost: Beasley's weighted earliness and tardiness; makespan: the last landing time."""
    max_shift: int | None = None
    """Constrained position shifting: no aircraft more than this many places from its first-come position."""
    time_limit_s: float = 10.0
    """The MILP returns the best order found when this runs out, with its proven gap."""
    mip_rel_gap: float = 1e-6
    """Relative gap at which the MILP stops as optimal (the published optima are integers: this is exact)."""
