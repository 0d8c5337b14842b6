"""The planning pipeline shared by the CLI, the ROS node and the closed loop: initializer -> optimizer -> verification.

:mod:`.planner` plans a scenario (and replans it warm); :mod:`.among` replans some aircraft among others whose paths
stay as they are (a replan of what changed).
"""

from mal_planner.airspace_entry import inside_airspace
from mal_planner.pipeline.planner import Planner, PlanResult, plan

__all__ = ["PlanResult", "Planner", "inside_airspace", "plan"]
