"""The adcs_sim interface: topic names, QoS, message conversions, validation, parameter schemas.

Everything that crosses a process boundary is defined here and nowhere else:

* :mod:`adcs_msgs_py.names` — topic names (no ROS import);
* :mod:`adcs_msgs_py.topics` — message types and QoS of each topic (and why);
* :mod:`adcs_msgs_py.conversions` — numpy <-> message, with validation of incoming data;
* :mod:`adcs_msgs_py.guard` — reject / count / throttled warning of bad messages;
* :mod:`adcs_msgs_py.params` — parameter schemas: scenario files validated with errors naming keys.
"""
