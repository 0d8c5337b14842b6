"""The path-planner interface every planner implements, and what planners share.

A planner answers one query: an obstacle-free polyline from ``start`` to ``goal`` (3-D points in nm)
for a :class:`~mal_planner.initializer.collision.CollisionChecker`. Implementations (:mod:`.multi_rrt`,
:mod:`.ompl_planners`) import this module; the registry that names them is :mod:`.planners`.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from mal_planner.errors import PlanningFailed, TimeLimitReached
from mal_planner.initializer.collision import CollisionChecker

__all__ = ["InitializerTimeout", "PathPlanner", "PlanningFailed", "path_length", "require_free_endpoints"]


class InitializerTimeout(TimeLimitReached, PlanningFailed):
    """The plan's time limit ran out in the initializer: a :class:`PlanningFailed` for callers that catch the
    initializer's failures, classed ``timeout``; ``str()`` names the stage and how far it got."""


def require_free_endpoints(checker: CollisionChecker, spec: str, start: np.ndarray, goal: np.ndarray
                           ) -> tuple[np.ndarray, np.ndarray]:
    """Both ends as float arrays; :class:`PlanningFailed` naming the planner if one is not free."""
    start, goal = np.asarray(start, dtype=float), np.asarray(goal, dtype=float)
    for label, p in (("start", start), ("goal", goal)):
        if not checker.point_free(p):
            raise PlanningFailed(f"{spec}: the {label} {np.round(p, 4).tolist()} is not free")
    return start, goal


@runtime_checkable
class PathPlanner(Protocol):
    """Plans a free polyline (K, 3): first row = start, last row = goal."""

    spec: str

    def plan(
        self, checker: CollisionChecker, start: np.ndarray, goal: np.ndarray, rng: np.random.Generator
    ) -> np.ndarray: ...


STEP_SHARE = 0.12
"""The planners' steering step (RRT's maximum edge, OMPL's range) as a share of the airspace's diagonal: 1 nm in
the thesis's 6 x 6 x 0.3 nm box, 7.6 nm in a 45 x 45 nm terminal area (OMPL's own default is 0.2)."""


def default_step(checker: CollisionChecker) -> float:
    """The steering step (nm) for the checker's airspace (see :data:`STEP_SHARE`)."""
    return STEP_SHARE * float(np.linalg.norm(checker.upper - checker.lower))


def path_length(path: np.ndarray) -> float:
    """Total length of a polyline (K, 3)."""
    path = np.asarray(path, dtype=float)
    return float(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1))) if len(path) > 1 else 0.0
