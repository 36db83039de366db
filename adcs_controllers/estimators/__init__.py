"""Attitude estimators as pure functions of arrays (flight software: numpy, leading batch axis, no
rclpy, never the truth model). Quaternions scalar last, body in inertial, as :mod:`adcs_core.attitude`."""
