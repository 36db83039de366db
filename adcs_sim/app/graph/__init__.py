"""Running the ROS graph: the runner (adcs-run), its node processes, domains and viewer layouts."""
