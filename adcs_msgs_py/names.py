"""Topic names of the graph (no ROS import: usable by the pure scenario and analysis code).

:mod:`adcs_msgs_py.topics` pairs each name with its message type and QoS.
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping

from adcs_msgs_py.sensor_interfaces import SENSOR_TOPICS

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
# attitude determination (adcs_msgs_py.conversions_determination): the dynamics node's sensor models
# publish every step on the topic each sensor declares (adcs_msgs_py.sensor_interfaces: SENSOR_TOPICS,
# by sensor name); an estimator answers with its estimate, on which a controller may fly (a remap of
# its ``state`` to ESTIMATE_STATE). The four below are named for the code that predates the declarations.
SENSOR_IMU = SENSOR_TOPICS['gyro']
SENSOR_STAR_TRACKER = SENSOR_TOPICS['star_tracker']
SENSOR_SUN = SENSOR_TOPICS['sun']
SENSOR_MAGNETOMETER = SENSOR_TOPICS['magnetometer']
ESTIMATE_STATE = 'estimate/state'
ESTIMATOR_STATUS = 'estimator/status'
# For viewers (Foxglove, RViz, PlotJuggler): published by the dynamics node with
# ``visualization.enabled`` (adcs_msgs_py/visual.py builds them), built only when subscribed.
FRAMES_BODY = 'frames/body'          # geometry_msgs/TransformStamped inertial -> body
FRAMES_ORBIT = 'frames/orbit'        # geometry_msgs/TransformStamped inertial -> orbit (with an orbit)
MARKERS = 'markers'                  # visualization_msgs/MarkerArray: what moves (wheel momentum, thruster plumes)
MARKERS_STATIC = 'markers/static'    # visualization_msgs/MarkerArray, latched: body box and axes, target axes
ERROR_EIGENAXIS = 'error/eigenaxis'  # geometry_msgs/Vector3Stamped: x = eigenaxis error (deg)
ERROR_EULER_213 = 'error/euler_213'  # geometry_msgs/Vector3Stamped: 2-1-3 Euler errors about x, y, z (deg)
VISUAL_TOPICS = (FRAMES_BODY, FRAMES_ORBIT, MARKERS, MARKERS_STATIC, ERROR_EIGENAXIS, ERROR_EULER_213)
# The per-step viewer topics the recorder writes into the bag itself (with /clock), from what it
# records and the dynamics node's latched RECORDING_CONFIG (adcs_msgs_py/recorded_topics.py): the
# dynamics node publishes them only to live subscribers (a viewer), not to the recorder (issue 18).
RECORDED_VISUAL_TOPICS = (FRAMES_BODY, FRAMES_ORBIT, MARKERS, ERROR_EIGENAXIS, ERROR_EULER_213)
RECORDED_TOPICS = (CLOCK, *RECORDED_VISUAL_TOPICS)
RECORDING_CONFIG = 'dynamics/recording'   # std_msgs/String, latched: what the recorder writes itself (JSON)
# std_msgs/String, latched: the publishers the recorder's readers have matched (JSON, start-up only)
RECORDER_MATCHED = 'recorder/matched'
FRAME_TOPICS = (FRAMES_BODY, FRAMES_ORBIT)
# Written by the recorder into the bag only: the transforms received on FRAME_TOPICS as
# tf2_msgs/TFMessage (no tf2_msgs wheel for Jazzy on PyPI: it cannot be published here), the
# topic RViz and Foxglove read transforms from. Relative: /tf for a run in the root namespace.
TF = 'tf'

# Command topics a controller may answer a state with (what the dynamics node can wait for).
COMMAND_TOPICS = (WHEELS_CMD, TORQUE_CMD, THRUSTERS_CMD)

RUN_NODES = '*'  # the startup.publishers entry naming every node of the run (whose subscriptions count)
# the startup.publishers entry naming the nodes the runner may start again (adcs-run --restart): a
# second node of such a name is held, not an intrusion at once, until one of the two leaves the graph
RESTARTABLE = '+'
INTRUSIONS = 'intrusions'  # written by the recorder into the bag: publishers the run does not allow
QUARANTINE_PREFIX = 'quarantine'  # the recorder keeps a compromised topic's messages under quarantine/<topic>


def quarantined(topic: str) -> bool:
    """Whether ``topic`` (a resolved name) is where the recorder keeps the messages of a compromised
    topic (``<ns>/quarantine/<topic>``): never a run's own data, whatever its name ends with."""
    return f'/{QUARANTINE_PREFIX}/' in topic


def quarantine_topic(topic: str, namespace: str) -> str:
    """Where the recorder keeps the messages of ``topic`` (resolved, in ``namespace``) once it is
    compromised: ``<namespace>/quarantine/<topic relative to it>``."""
    ns = namespace.rstrip('/')
    return f'{ns}/{QUARANTINE_PREFIX}{topic[len(ns):]}'


# Who may publish on each topic a node of the graph listens to, by role (the scenario's sections
# say which nodes of each role run; a node's name is its section's name). An empty tuple: nobody.
PUBLISHER_ROLES: dict[str, tuple[str, ...]] = {
    CLOCK: ('dynamics',), STATE: ('dynamics',), TRUTH_STATE: ('dynamics',), WHEELS_STATE: ('dynamics',),
    THRUSTERS_STATE: ('dynamics',), APPLIED_TORQUE: ('dynamics',), DYNAMICS_STATUS: ('dynamics',),
    WHEELS_CMD: ('controller',), TORQUE_CMD: ('controller',), THRUSTERS_CMD: ('controller',),
    CONTROLLER_STATUS: ('controller',), FAULTS: ('faults',), REFERENCE: (),
    **{topic: ('dynamics',) for topic in SENSOR_TOPICS.values()},
    ESTIMATE_STATE: ('estimator',), ESTIMATOR_STATUS: ('estimator',),
    **{topic: ('dynamics',) for topic in (*VISUAL_TOPICS, RECORDING_CONFIG)},
    RECORDER_MATCHED: ('recorder',),
}


def parse_publishers(entries: Iterable[str]) -> dict[str, frozenset[str]]:
    """``['topic=node,node', 'faults=']`` -> ``{topic: {node, ...}}`` (an empty list: nobody may
    publish there); ValueError naming a malformed entry."""
    out: dict[str, frozenset[str]] = {}
    for entry in entries:
        topic, sep, nodes = entry.partition('=')
        if not sep or not topic.strip():
            raise ValueError(f'{entry!r} is not "topic=node[,node...]"')
        out[topic.strip()] = frozenset(n.strip() for n in nodes.split(',') if n.strip())
    return out


def format_publishers(allowed: Mapping[str, Iterable[str]]) -> list[str]:
    """Inverse of :func:`parse_publishers`."""
    return [f'{topic}={",".join(sorted(nodes))}' for topic, nodes in sorted(allowed.items())]


