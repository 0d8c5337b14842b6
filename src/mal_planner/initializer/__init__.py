"""Initial trajectories (chapters 3 and 4): collision checking, path planners and the landing sequencer."""

from mal_planner.initializer.base import PathPlanner, PlanningFailed, path_length
from mal_planner.initializer.collision import CheckCounts, CollisionChecker
from mal_planner.initializer.multi_rrt import MultiRRT
from mal_planner.initializer.planners import known_specs, make_planner, register_planner
from mal_planner.initializer.sequencer import InitialPlan, InitialTrajectory, Sequencer, plan_initial

__all__ = [
    "CheckCounts", "CollisionChecker", "InitialPlan", "InitialTrajectory", "MultiRRT", "PathPlanner",
    "PlanningFailed", "Sequencer", "known_specs", "make_planner", "path_length", "plan_initial",
    "register_planner",
]
