"""The path planner as the sequencer uses it: shortest of several runs, quick candidate legs, the approach route
joined on, every search bounded by the query's deadline."""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from mal_planner.deadline import NO_DEADLINE, Deadline
from mal_planner.initializer.approach import Approach
from mal_planner.initializer.base import PathPlanner, PlanningFailed, path_length
from mal_planner.initializer.collision import CollisionChecker
from mal_planner.initializer.smoothing import SmoothedSearch, greedy_shortcut, remove_repeats, smooth_path


@dataclass
class LegPlanner:
    """``planner`` run for the legs of initial paths; ``runs``: runs per shortest path. ``deadline`` is set per
    query (checked before a planner that takes none)."""

    planner: PathPlanner
    runs: int
    deadline: Deadline = NO_DEADLINE

    def shortest(self, checker: CollisionChecker, start: np.ndarray, goal: np.ndarray,
                 rng: np.random.Generator) -> np.ndarray:
        """The shortest of ``runs`` planned paths; :class:`PlanningFailed` (the last error) if none was found."""
        best: np.ndarray | None = None
        errors = []
        for _ in range(self.runs):
            try:
                path = self.path(checker, start, goal, rng)
            except PlanningFailed as exc:
                errors.append(str(exc))
                continue
            if best is None or path_length(path) < path_length(best):
                best = path
        if best is None:
            raise PlanningFailed(errors[-1])
        return best

    def quick(self, checker: CollisionChecker, start: np.ndarray, goal: np.ndarray,
              rng: np.random.Generator) -> np.ndarray:
        """A candidate leg: the planner's path with the greedy shortcut only (the random shortcuts, about 40 %
        of a terminal area's initializer time, are for the path that is kept; see :meth:`polish`)."""
        if isinstance(self.planner, SmoothedSearch):
            return greedy_shortcut(checker, self.planner.search(checker, start, goal, rng, self.deadline))
        return self.path(checker, start, goal, rng)

    def path(self, checker: CollisionChecker, start: np.ndarray, goal: np.ndarray,
             rng: np.random.Generator) -> np.ndarray:
        """The planner's path, its search bounded by the deadline (checked before a planner that takes none)."""
        self.deadline.check()
        if isinstance(self.planner, SmoothedSearch):
            return self.planner.plan(checker, start, goal, rng, self.deadline)
        return self.planner.plan(checker, start, goal, rng)

    def polish(self, checker: CollisionChecker, path: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The kept path smoothed as the planner smooths its own (a no-op for other planners)."""
        if isinstance(self.planner, SmoothedSearch):
            return smooth_path(checker, path, rng, self.planner.smooth_rounds)
        return path

    def join(self, checker: CollisionChecker, to_route: np.ndarray, route: Approach,
             rng: np.random.Generator) -> np.ndarray:
        """A path to the route's first point, then the route; a leg of the route that is not free (e.g. from a
        gate's exit to the final approach fix, past a no-fly zone) is planned."""
        parts = [np.asarray(to_route, float)]
        for a, b in itertools.pairwise(route.points):
            parts.append(np.array([b]) if checker.segment_free(a, b) else self.path(checker, a, b, rng)[1:])
        return remove_repeats(np.vstack(parts))
