"""Topic names, message types and QoS of the adcs_sim graph: the single source of truth.

Names are relative (except ``/clock``) so that ``-r __ns:=/sat1`` runs several spacecraft in one
domain. Every node and the recorder take their topics from :data:`TOPICS`.

QoS choices, topic by topic
---------------------------
Reliability, history depth and durability of each topic, and why (what a lost, late or
overwritten message would cost). Lost and late commands are simulated and tested on purpose
(``link_faults.*``, :mod:`adcs_sim.link_faults`); the QoS is what keeps them from happening for
real.

* ``state``, ``truth/state``, ``wheels/state`` — RELIABLE, VOLATILE, KEEP_LAST 10.
  RELIABLE: in lockstep a lost state is a step the controller never answers, i.e. a wall-clock
  timeout and a missed step, and a hole in the recording. Depth 10: the dynamics node publishes
  one state per step and waits for the answer, so at most one or two are ever in flight; 10
  absorbs a burst while a subscriber (the recorder) is busy, with bounded memory. VOLATILE: a
  controller that joins (or restarts) late must act on the next state, never on an old one.
* ``wheels/cmd``, ``torque_cmd`` — RELIABLE, VOLATILE, KEEP_LAST 10. One answer per state,
  stamped with the state's stamp; a lost one is a missed step (the timeout policy applies), so
  the transport must not lose it. VOLATILE: a command answers one step; replaying it to a
  dynamics node that joins late would apply it at the wrong time (it would be counted stale).
* ``actuators/torque`` — RELIABLE, VOLATILE, KEEP_LAST 10: the applied torque of each step,
  for the recorder and the metrics (∫‖u‖dt needs every step); nobody acts on it.
* ``/clock`` — RELIABLE, VOLATILE, KEEP_LAST 10. rclpy's time source subscribes best-effort,
  which matches a reliable publisher; reliable lets the recorder keep every tick. VOLATILE: the
  clock of the past is meaningless to a late joiner.
* ``controller/status``, ``dynamics/status`` — RELIABLE, VOLATILE, KEEP_LAST 50: what the papers
  plot (mode, Lyapunov value, missed steps), one per step and recorded; depth 50 because the
  status goes out after the command, off the critical path, and may queue behind it.
* ``faults`` — RELIABLE, TRANSIENT_LOCAL, KEEP_LAST 100: the whole fault schedule is published
  once at start (one snapshot per event, each stamped with its due time); a controller, the
  dynamics node or the recorder that joins or restarts late must still receive all of it, so
  the publisher keeps it (depth 100 bounds the schedule's length).
* ``reference`` — RELIABLE, VOLATILE, KEEP_LAST 10, like the state it is compared with.
* **Recorder** subscriptions: KEEP_ALL with the offered reliability and durability (see
  :func:`recorder_qos`): a KEEP_LAST reader silently overwrites what it has not taken yet while
  it writes a chunk; transient-local topics deliver their history to it. In lockstep free flight
  (no command awaited) the dynamics node also waits for its step's messages to be acknowledged
  before the next step, so a slower recorder paces the run instead of losing data.
* Not BEST_EFFORT anywhere in the loop: best effort would turn every dropped UDP datagram into a
  missed step (or a silent gap in the bag) and make lockstep runs depend on the network.
"""
from __future__ import annotations

from dataclasses import dataclass

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from adcs_msgs_py.names import (APPLIED_TORQUE, CLOCK, COMMAND_TOPICS, CONTROLLER_STATUS,  # noqa: F401
                                DYNAMICS_STATUS, FAULTS, REFERENCE, STATE, TORQUE_CMD, TRUTH_STATE,
                                WHEELS_CMD, WHEELS_STATE)

from builtin_interfaces.msg import Time  # noqa: F401  (re-exported for type hints)
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

QOS_LOCKSTEP = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=10,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
QOS_CLOCK = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=10,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
QOS_STATUS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=50,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
QOS_LATCHED = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=100,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def recorder_qos(offered: QoSProfile) -> QoSProfile:
    """The recorder's subscription QoS for a topic offered with ``offered``.

    KEEP_ALL: the recorder must never drop a message while it writes a chunk (a KEEP_LAST reader
    silently overwrites what it has not taken yet). Same reliability and durability as offered,
    so transient-local topics deliver their history to it.
    """
    return QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=offered.reliability,
                      durability=offered.durability)


@dataclass(frozen=True)
class TopicSpec:
    """One topic of the graph: name, message class, QoS and what it carries."""

    name: str
    msg_type: type
    qos: QoSProfile
    doc: str

    @property
    def type_name(self) -> str:
        """ROS 2 type name, e.g. ``nav_msgs/msg/Odometry``."""
        module = self.msg_type.__module__.split('.')[0]
        return f'{module}/msg/{self.msg_type.__name__}'



TOPICS: dict[str, TopicSpec] = {spec.name: spec for spec in (
    TopicSpec(CLOCK, Clock, QOS_CLOCK, 'simulated time, published by the dynamics node'),
    TopicSpec(STATE, Odometry, QOS_LOCKSTEP,
              'attitude (body in inertial, x y z w) and body rate (rad/s, body axes) as measured; '
              'one stamped message so attitude and rate are always of the same step'),
    TopicSpec(TRUTH_STATE, Odometry, QOS_LOCKSTEP,
              'true attitude and rate, published only when measurement noise is configured'),
    TopicSpec(WHEELS_STATE, JointState, QOS_LOCKSTEP,
              'per wheel: angle (rad), speed relative to the body (rad/s), applied motor torque (N m)'),
    TopicSpec(WHEELS_CMD, JointState, QOS_LOCKSTEP,
              'per wheel: motor torque command (effort, N m) or speed command (velocity, rad/s)'),
    TopicSpec(TORQUE_CMD, Vector3Stamped, QOS_LOCKSTEP,
              'external body torque command for ideal torquers (N m, body axes)'),
    TopicSpec(APPLIED_TORQUE, Vector3Stamped, QOS_LOCKSTEP,
              'control torque applied to the body at the start of the step (wheels + torquers, '
              'after saturation), held over the step'),
    TopicSpec(REFERENCE, Odometry, QOS_LOCKSTEP, 'attitude and rate target'),
    TopicSpec(FAULTS, DiagnosticArray, QOS_LATCHED, 'one status per actuator: OK / ERROR and mode'),
    TopicSpec(CONTROLLER_STATUS, DiagnosticArray, QOS_STATUS,
              'control-law mode, Lyapunov value, estimates, rejected-message counts'),
    TopicSpec(DYNAMICS_STATUS, DiagnosticArray, QOS_STATUS,
              'missed steps, stale and rejected commands, integration statistics'),
)}


def spec(name: str) -> TopicSpec:
    """Return the :class:`TopicSpec` of a graph topic, with a clear error for an unknown one."""
    try:
        return TOPICS[name]
    except KeyError:
        raise KeyError(f'unknown topic {name!r}; known topics: {sorted(TOPICS)}') from None


