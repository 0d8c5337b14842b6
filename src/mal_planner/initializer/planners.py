"""The path-planner interface, the registry of planners and :func:`make_planner`.

A planner answers one query: an obstacle-free polyline from ``start`` to ``goal`` (3-D points in nm)
for a :class:`~mal_planner.initializer.collision.CollisionChecker`. Specs: ``"multi-rrt"`` (the thesis's
multiple-tree RRT, on NumPy) and ``"ompl:<Planner>"`` (any planner of ``ompl.geometric`` by name, e.g.
``"ompl:RRTConnect"``, the bidirectional RRT of chapter 3).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable

import numpy as np

from mal_planner.errors import TimeLimitReached
from mal_planner.initializer.collision import CollisionChecker


class PlanningFailed(RuntimeError):
    """No obstacle-free path was found; ``str()`` is one line."""


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


PlannerFactory = Callable[..., PathPlanner]
_REGISTRY: dict[str, PlannerFactory] = {}
OMPL_PREFIX = "ompl:"


def register_planner(name: str, factory: PlannerFactory) -> None:
    """Make ``make_planner(name, **options)`` return ``factory(**options)``."""
    _REGISTRY[name] = factory


def known_specs() -> list[str]:
    """Registered specs plus the OMPL planners available in this installation."""
    from mal_planner.initializer.ompl_planners import available_ompl_planners

    _register_builtin()
    return sorted(_REGISTRY) + [OMPL_PREFIX + name for name in available_ompl_planners()]


def make_planner(spec: str, **options: Any) -> PathPlanner:
    """Build the planner named by ``spec`` (e.g. ``"multi-rrt"``, ``"ompl:RRTConnect"``).

    ``options`` go to the planner's constructor. Raises ``ValueError`` naming the known specs.
    """
    _register_builtin()
    if spec in _REGISTRY:
        return _REGISTRY[spec](**options)
    if spec.startswith(OMPL_PREFIX):
        from mal_planner.initializer.ompl_planners import OmplPlanner, available_ompl_planners

        name = spec[len(OMPL_PREFIX):]
        if name in available_ompl_planners():
            return OmplPlanner(name, **options)
    raise ValueError(f"unknown planner {spec!r} (known: {', '.join(known_specs())})")


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


def _register_builtin() -> None:
    if "multi-rrt" not in _REGISTRY:
        from mal_planner.initializer.multi_rrt import MultiRRT

        register_planner("multi-rrt", MultiRRT)
