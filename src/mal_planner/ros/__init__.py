"""ROS 2 layer of the MAL planner (nodes, transport). The planning core never imports this package."""
