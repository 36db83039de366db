"""Topic names of the graph (no ROS import: usable by the pure scenario and analysis code).

:mod:`adcs_msgs_py.topics` pairs each name with its message type and QoS.
"""
CLOCK = '/clock'
STATE = 'state'
TRUTH_STATE = 'truth/state'
WHEELS_STATE = 'wheels/state'
WHEELS_CMD = 'wheels/cmd'
TORQUE_CMD = 'torque_cmd'
THRUSTERS_CMD = 'thrusters/cmd'
THRUSTERS_STATE = 'thrusters/state'
APPLIED_TORQUE = 'actuators/torque'
REFERENCE = 'reference'
FAULTS = 'faults'
CONTROLLER_STATUS = 'controller/status'
DYNAMICS_STATUS = 'dynamics/status'

# Command topics a controller may answer a state with (what the dynamics node can wait for).
COMMAND_TOPICS = (WHEELS_CMD, TORQUE_CMD, THRUSTERS_CMD)

