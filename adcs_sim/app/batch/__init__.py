"""The batch engine: N runs of the same step as arrays, without ROS, and its compiled fast paths."""
