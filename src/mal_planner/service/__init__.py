"""The planning service's rules, without ROS: radar intake, the replan policy, plan jobs and the plan's inputs.

The planner node (:mod:`mal_planner.ros.planner_node`) and the closed-loop simulation
(:mod:`mal_planner.closedloop`) both run these rules, so that what a closed-loop campaign measures is what the
node does.
"""
