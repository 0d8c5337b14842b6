"""Multiple-aircraft landing planner: scenario models, RRT initializer, pseudospectral optimizer.

The planning core (everything except :mod:`mal_planner.ros`) imports nothing from ROS.
Inside the planner all quantities use the thesis's units: nautical miles, seconds, radians.
"""

__version__ = "0.1.0"
