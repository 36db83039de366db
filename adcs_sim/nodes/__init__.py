"""ROS nodes of the simulator side: dynamics (plant + clock) and recorder."""
