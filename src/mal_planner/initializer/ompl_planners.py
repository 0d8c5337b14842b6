"""The planning query answered by OMPL's geometric planners (``ompl:RRT``, ``ompl:RRTConnect``, ...).

The state space is ``RealVectorStateSpace(3)`` bounded by the airspace; both the state validity checker
and the motion validator call our :class:`CollisionChecker`, so OMPL's motions are tested with the exact
segment check and cannot step through a thin wall. OMPL's global RNG is re-seeded from the caller's
NumPy generator before every query, and planners stop after a fixed number of iterations (or at the
time limit: the query's own or what is left of the plan's), so results are reproducible unless a time limit
is hit. Paths are simplified with our shortcutting.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from functools import cache

import numpy as np

from mal_planner.deadline import NO_DEADLINE, Deadline
from mal_planner.initializer.base import PlanningFailed, default_step, require_free_endpoints
from mal_planner.initializer.collision import CollisionChecker
from mal_planner.initializer.smoothing import SmoothedSearch

OMPL_PREFIX = "ompl:"
"""Specs of OMPL's planners: this prefix and the planner's name in ``ompl.geometric``."""

_GEOMETRIC_PLANNERS = (
    "RRT", "RRTConnect", "RRTstar", "InformedRRTstar", "SORRTstar", "AORRTC", "BITstar", "BFMT", "FMT",
    "KPIECE1", "BKPIECE1", "LBKPIECE1", "PRM", "PRMstar",
)
# Planners that keep improving the path until told to stop; the others return their first solution.
_THREADED = {"PRM", "PRMstar", "LazyPRM", "LazyPRMstar", "SPARS", "SPARStwo"}
"""Planners that grow their roadmap in a second thread while solve() polls the termination condition: a
Python condition would need the GIL that solve() holds (deadlock), so they get OMPL's own timed one."""
_ANYTIME = {"RRTstar", "InformedRRTstar", "SORRTstar", "AORRTC", "BITstar", "PRM", "PRMstar"}


@cache
def available_ompl_planners() -> tuple[str, ...]:
    """Names of the ``ompl.geometric`` planners usable here (empty when OMPL is not installed)."""
    try:
        import ompl.geometric as og
    except ImportError:
        return ()
    return tuple(name for name in _GEOMETRIC_PLANNERS if hasattr(og, name))


@dataclass
class OmplPlanner(SmoothedSearch):
    """An ``ompl.geometric`` planner by name. Options:

    ``time_limit`` (s per query); ``max_iterations``: anytime planners such as RRT* run in rounds of this
    many termination-condition polls (about one per iteration) until a round ends with an exact solution
    (None: 1000); ``iteration_cap``: polls after which any planner gives up;
    ``range`` (nm; the planner's maximum motion, None: :func:`default_step` of the airspace, as multi-rrt's),
    ``smooth_rounds``.
    """

    name: str
    time_limit: float = 5.0
    max_iterations: int | None = None
    iteration_cap: int = 50000
    range: float | None = None
    smooth_rounds: int = 40

    def __post_init__(self) -> None:
        if self.name not in available_ompl_planners():
            raise ValueError(f"unknown OMPL planner {self.name!r} (known: {', '.join(available_ompl_planners())})")
        self.spec = OMPL_PREFIX + self.name
        if self.max_iterations is None:
            self.max_iterations = 1000
        self.last_iterations = 0

    def search(
        self, checker: CollisionChecker, start: np.ndarray, goal: np.ndarray, rng: np.random.Generator,
        deadline: Deadline | None = None,
    ) -> np.ndarray:
        """The planner's raw path (K, 3); raises :class:`PlanningFailed`. The query's time budget is at most what
        is left of ``deadline``; :class:`~mal_planner.errors.TimeLimitReached` when that cut it short."""
        import ompl.base as ob
        import ompl.geometric as og
        import ompl.util as ou

        deadline = deadline or NO_DEADLINE
        deadline.check()
        start, goal = require_free_endpoints(checker, self.spec, start, goal)
        ou.setLogLevel(ou.LOG_NONE)  # setSeed reports an error once sampling has started; it still reseeds
        ou.RNG.setSeed(int(rng.integers(1, 2**31 - 1)))

        space = _airspace_space(checker)
        ss = og.SimpleSetup(space)
        si = ss.getSpaceInformation()

        def state_valid(state) -> bool:
            return checker.point_free(np.array([state[0], state[1], state[2]]))

        class ExactMotionValidator(ob.MotionValidator):
            def checkMotion(self, s1, s2, *rest) -> bool:  # noqa: N802 (OMPL's name)
                a = np.array([s1[0], s1[1], s1[2]])
                b = np.array([s2[0], s2[1], s2[2]])
                return checker.segment_free(a, b)

        ss.setStateValidityChecker(state_valid)
        validator = ExactMotionValidator(si)
        si.setMotionValidator(validator)
        s_state, g_state = space.allocState(), space.allocState()
        for i in range(3):
            s_state[i], g_state[i] = float(start[i]), float(goal[i])
        ss.setStartAndGoalStates(s_state, g_state)
        planner = getattr(og, self.name)(si)
        if hasattr(planner, "setRange"):
            planner.setRange(float(self.range or default_step(checker)))
        ss.setPlanner(planner)
        ss.setOptimizationObjective(ob.PathLengthOptimizationObjective(si))

        status, polls = self._solve(ss, min(self.time_limit, deadline.remaining()))
        self.last_iterations = polls
        if not ss.haveExactSolutionPath():
            deadline.check()  # the plan's time limit, not the planner, ended the query
            raise PlanningFailed(
                f"{self.spec}: no path from {np.round(start, 3).tolist()} to {np.round(goal, 3).tolist()} "
                f"({status}, {polls} iterations)"
            )
        path = ss.getSolutionPath()
        out = np.array([[path.getState(i)[j] for j in range(3)] for i in range(path.getStateCount())])
        out[0], out[-1] = start, goal
        return out

    def _solve(self, ss, budget_s: float) -> tuple[object, int]:
        """Run the set-up query until it has an exact solution, for at most ``budget_s`` seconds and
        :attr:`iteration_cap` termination-condition polls: (the last solve status, the polls)."""
        import ompl.base as ob

        polls = [0]
        ends = time.perf_counter() + budget_s
        # Anytime planners report their solution only when solve() returns: run them in rounds of
        # max_iterations polls (each solve() continues the same tree) until one has an exact solution.
        budget = self.max_iterations if self.name in _ANYTIME else self.iteration_cap
        limit = [0]

        def stop() -> bool:
            polls[0] += 1
            return polls[0] >= min(limit[0], self.iteration_cap) or time.perf_counter() > ends

        status = None
        if self.name in _THREADED:  # OMPL's own timed condition: no Python call from the planner's threads
            while not ss.haveExactSolutionPath() and time.perf_counter() <= ends:
                status = ss.solve(ob.timedPlannerTerminationCondition(min(0.2, budget_s)))
                polls[0] += 1
        while (self.name not in _THREADED and polls[0] < self.iteration_cap
               and time.perf_counter() <= ends):
            limit[0] = polls[0] + budget
            status = ss.solve(ob.PlannerTerminationCondition(stop))
            if ss.haveExactSolutionPath():
                break
        return status, polls[0]


def _airspace_space(checker: CollisionChecker):
    """OMPL's ``RealVectorStateSpace(3)`` bounded by the checker's airspace."""
    import ompl.base as ob

    space = ob.RealVectorStateSpace(3)
    bounds = ob.RealVectorBounds(3)
    for i, (lo, hi) in enumerate(checker.airspace):
        bounds.setLow(i, float(lo))
        bounds.setHigh(i, float(hi))
    space.setBounds(bounds)
    return space
