"""Attitude control laws of the source papers and their ROS nodes.

* ``adcs_controllers.laws`` — the laws as pure numpy functions (batchable, no ROS), one module per
  paper / law family, equation numbers in the docstrings;
* ``adcs_controllers.nodes`` — one thin ROS node per law family.
"""
