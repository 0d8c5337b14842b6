#!/bin/bash
# Source ROS 2 and our interface workspace, then run the command (default: mal-launch, see the Dockerfile).
set -e
source "/opt/ros/${ROS_DISTRO:-jazzy}/setup.bash"
source /opt/mal_planner/ros2_ws/install/setup.bash
export RMW_IMPLEMENTATION="${RMW_IMPLEMENTATION:-rmw_cyclonedds_cpp}"
export MAL_ROS_BACKEND="${MAL_ROS_BACKEND:-rclpy}"
cd /opt/mal_planner
exec "$@"
