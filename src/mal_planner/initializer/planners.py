"""The registry of path planners and :func:`make_planner`.

Specs: ``"multi-rrt"`` (the thesis's multiple-tree RRT, on NumPy) and ``"ompl:<Planner>"`` (any planner of
``ompl.geometric`` by name, e.g. ``"ompl:RRTConnect"``, the bidirectional RRT of chapter 3). The interface they
implement is :class:`~mal_planner.initializer.base.PathPlanner`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from mal_planner.initializer.base import PathPlanner
from mal_planner.initializer.multi_rrt import MultiRRT
from mal_planner.initializer.ompl_planners import OMPL_PREFIX, OmplPlanner, available_ompl_planners

__all__ = ["PlannerFactory", "known_specs", "make_planner", "register_planner"]

PlannerFactory = Callable[..., PathPlanner]
_REGISTRY: dict[str, PlannerFactory] = {"multi-rrt": MultiRRT}


def register_planner(name: str, factory: PlannerFactory) -> None:
    """Make ``make_planner(name, **options)`` return ``factory(**options)``."""
    _REGISTRY[name] = factory


def known_specs() -> list[str]:
    """Registered specs plus the OMPL planners available in this installation."""
    return sorted(_REGISTRY) + [OMPL_PREFIX + name for name in available_ompl_planners()]


def make_planner(spec: str, **options: Any) -> PathPlanner:
    """Build the planner named by ``spec`` (e.g. ``"multi-rrt"``, ``"ompl:RRTConnect"``).

    ``options`` go to the planner's constructor. Raises ``ValueError`` naming the known specs.
    """
    if spec in _REGISTRY:
        return _REGISTRY[spec](**options)
    if spec.startswith(OMPL_PREFIX):
        name = spec[len(OMPL_PREFIX):]
        if name in available_ompl_planners():
            return OmplPlanner(name, **options)
    raise ValueError(f"unknown planner {spec!r} (known: {', '.join(known_specs())})")
