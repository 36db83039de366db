"""Topic names, message types and QoS of the adcs_sim graph: the single source of truth.

Names are relative (except ``/clock``) so that ``-r __ns:=/sat1`` runs several spacecraft in one
domain. Every node and the recorder take their topics from :data:`TOPICS`.

QoS choices
-----------
* **Lockstep data** (state, wheel and thruster states/commands, torque commands, applied
  torque): RELIABLE,
  VOLATILE, KEEP_LAST depth :data:`DEPTH` (500). Lockstep must not lose a state or a command (a
  lost one costs a wall-clock timeout and a missed step). The controllers answer every state, but
  the recorder only acknowledges: a RELIABLE KEEP_LAST writer drops a sample it has not had
  acknowledged once ``depth`` newer ones are written, so a recorder that falls behind (seen under
  CPU load with depth 10: five states missing from a 4 500-step bag) would lose data. Hence, when
  a recorder is expected (``startup.expect_recorder``, set by the runner), the publishers of every
  recorded per-step topic wait for all acknowledgements every :data:`ACK_INTERVAL` (250) steps: a
  reader is then never more than ~250 steps behind, inside the writer's depth with a 2x margin, and
  the wait (one heartbeat/acknowledgement round, up to ~10 ms: fastdds_profile.xml) is paid once
  per 250 steps instead of at every step (issue 18: a wait is ~8 ms, ~80 µs a step when it came
  every 100 steps, ~9 % of the showcase's loop). The dynamics node waits at the steps k with
  k % ACK_INTERVAL == 0, once it has step k's commands; the controllers and estimators at the same
  k, after they have answered state k, so that the two waits overlap instead of adding up. Memory stays bounded (500 messages per topic).
  A reliable reader acknowledges what DDS has put in its history, not what the node has taken:
  the recorder's readers hold at most 1000 untaken messages a topic (adcs_sim/nodes/recorder_fastdds.xml),
  so a full one acknowledges nothing more and the waits hold the loop until the recorder catches
  up. A wait that times out (``lockstep.timeout`` per publisher) is logged: a recorder stalled
  that long could be overwritten two intervals later. The nodes' own subscriptions keep
  depth :data:`SUB_DEPTH` (10, :func:`subscriber_qos`): a controller that falls behind in
  real-time mode must act on recent states, not work through a backlog of 200 stale ones.
  VOLATILE because a late joiner must not act on an old state.
* **/clock**: RELIABLE, same depth and pacing. rclpy's time source subscribes best-effort, which
  matches a reliable publisher; reliable lets the recorder keep every tick.
* **Status / diagnostics**: RELIABLE, same depth and pacing: what the papers plot, one per step,
  recorded.
* **Faults**: RELIABLE, TRANSIENT_LOCAL, depth 100: a controller or recorder that joins late still
  learns which actuators are gone.
* **Recorder** subscriptions: KEEP_ALL (see :func:`recorder_qos`). In lockstep free flight (no
  command awaited) the dynamics node also waits for its step's messages to be acknowledged
  before the next step, so a slower recorder paces the run instead of losing data.
"""
from __future__ import annotations

from dataclasses import dataclass

from builtin_interfaces.msg import Time  # noqa: F401  (re-exported for type hints)
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseWithCovarianceStamped, TransformStamped, Vector3Stamped
from nav_msgs.msg import Odometry
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState, MagneticField
from std_msgs.msg import String
from visualization_msgs.msg import MarkerArray

from adcs_msgs_py.names import (  # noqa: F401
    APPLIED_TORQUE,
    CLOCK,
    COMMAND_TOPICS,
    CONTROLLER_STATUS,
    DYNAMICS_STATUS,
    ERROR_EIGENAXIS,
    ERROR_EULER_213,
    ESTIMATE_STATE,
    ESTIMATOR_STATUS,
    FAULTS,
    FRAME_TOPICS,
    FRAMES_BODY,
    FRAMES_ORBIT,
    MARKERS,
    MARKERS_STATIC,
    RECORDED_TOPICS,
    RECORDED_VISUAL_TOPICS,
    RECORDING_CONFIG,
    RECORDER_MATCHED,
    REFERENCE,
    SENSOR_IMU,
    SENSOR_MAGNETOMETER,
    SENSOR_STAR_TRACKER,
    SENSOR_SUN,
    STATE,
    THRUSTERS_CMD,
    THRUSTERS_STATE,
    TORQUE_CMD,
    TRUTH_STATE,
    VISUAL_TOPICS,
    WHEELS_CMD,
    WHEELS_STATE,
)
from adcs_msgs_py.sensor_interfaces import SENSOR_INTERFACES

DEPTH = 500        # writers' history of the per-step topics (messages)
SUB_DEPTH = 10     # the nodes' own readers of those topics
ACK_INTERVAL = 250  # steps between two waits for every reader's acknowledgement (< DEPTH)

QOS_LOCKSTEP = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=DEPTH,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
QOS_CLOCK = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=DEPTH,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
QOS_STATUS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=DEPTH,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
QOS_LATCHED = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=100,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def subscriber_qos(offered: QoSProfile) -> QoSProfile:
    """A node's subscription QoS for a topic offered with ``offered``: the same, but a volatile
    topic's queue is only :data:`SUB_DEPTH` deep (a latched one keeps its whole history)."""
    if offered.durability != DurabilityPolicy.VOLATILE:
        return offered
    return QoSProfile(history=offered.history, depth=SUB_DEPTH, reliability=offered.reliability,
                      durability=offered.durability)


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
        return type_name(self.msg_type)


def type_name(msg_type: type) -> str:
    """ROS 2 type name of a message class, as the graph lists it (``nav_msgs/msg/Odometry``)."""
    return f'{msg_type.__module__.split(".")[0]}/msg/{msg_type.__name__}'



# The message class of each sensor codec's type (adcs_msgs_py.sensor_interfaces.CODEC_MESSAGES).
SENSOR_MESSAGES = {'sensor_msgs/msg/Imu': Imu, 'geometry_msgs/msg/PoseWithCovarianceStamped': PoseWithCovarianceStamped,
                   'geometry_msgs/msg/Vector3Stamped': Vector3Stamped, 'sensor_msgs/msg/MagneticField': MagneticField}

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
    TopicSpec(THRUSTERS_CMD, JointState, QOS_LOCKSTEP,
              'per thruster: on-time (effort, s) from the start of the control period the stamp '
              'names; 0: off, the period: on throughout (seed 002 section 2.5)'),
    TopicSpec(THRUSTERS_STATE, JointState, QOS_LOCKSTEP,
              'per thruster, for the step [t, t + period] of the stamp: thrust at t (effort, N), '
              'on-time applied after the valve rules (velocity, s), cumulated impulse at the '
              'end of the step (position, N s)'),
    TopicSpec(APPLIED_TORQUE, Vector3Stamped, QOS_LOCKSTEP,
              'control torque applied to the body at the start of the step (wheels + torquers, '
              'after saturation), held over the step'),
    TopicSpec(REFERENCE, Odometry, QOS_LOCKSTEP, 'attitude and rate target'),
    TopicSpec(FAULTS, DiagnosticArray, QOS_LATCHED, 'one status per actuator: OK / ERROR and mode'),
    TopicSpec(CONTROLLER_STATUS, DiagnosticArray, QOS_STATUS,
              'control-law mode, Lyapunov value, estimates, rejected-message counts'),
    TopicSpec(DYNAMICS_STATUS, DiagnosticArray, QOS_STATUS,
              'missed steps, stale and rejected commands, integration statistics'),
    *(TopicSpec(s.topic, SENSOR_MESSAGES[s.message], QOS_LOCKSTEP, s.description) for s in SENSOR_INTERFACES),
    TopicSpec(ESTIMATE_STATE, Odometry, QOS_LOCKSTEP,
              'estimated attitude and rate, the layout of state (a controller flies on it by a remap '
              'of state), with the attitude covariance (pose, inertial axes) and rate covariance '
              '(twist, body axes) filled in; stamped with the step of the measurements it used'),
    TopicSpec(ESTIMATOR_STATUS, DiagnosticArray, QOS_STATUS,
              'estimator diagnostics: bias estimate, innovations and their normalised squares (NIS), '
              'measurements used and rejected'),
    # For viewers (visualization.enabled; adcs_msgs_py/visual.py), true state, every step.
    TopicSpec(FRAMES_BODY, TransformStamped, QOS_LOCKSTEP,
              'the body frame: transform inertial -> body (rotation = true attitude, no translation)'),
    TopicSpec(FRAMES_ORBIT, TransformStamped, QOS_LOCKSTEP,
              'the orbit frame (x along track, z nadir): transform inertial -> orbit, with an orbit'),
    TopicSpec(MARKERS, MarkerArray, QOS_LOCKSTEP,
              'what moves, every step: the wheel momentum vector, the plumes of the thrusters firing'),
    TopicSpec(MARKERS_STATIC, MarkerArray, QOS_LATCHED,
              'published once at t = 0: body box and axes (frame body), target attitude axes (frame inertial)'),
    TopicSpec(ERROR_EIGENAXIS, Vector3Stamped, QOS_LOCKSTEP,
              'x: eigenaxis angle (deg) of the true attitude relative to the target; y, z: 0'),
    TopicSpec(ERROR_EULER_213, Vector3Stamped, QOS_LOCKSTEP,
              '2-1-3 Euler angles (deg) of the attitude error: x, y, z = the rotations about body x, y, z'),
    TopicSpec(RECORDING_CONFIG, String, QOS_LATCHED,
              'published once before t = 0: what the recorder writes itself (JSON: /clock from the '
              'state stamps; the viewer messages\' target, axis length, wheel and thruster geometry, '
              'orbit, attitude topic): adcs_msgs_py/recorded_topics.py'),
    TopicSpec(RECORDER_MATCHED, String, QOS_LATCHED,
              'the recorder\'s start-up handshake: JSON {topic: [node, ...]}, the nodes whose publishers '
              'on each recorded topic its readers have matched; a writer waits to be named before its '
              'first message (AdcsNode.wait_recorder_matched). Not recorded'),
)}


def spec(name: str) -> TopicSpec:
    """Return the :class:`TopicSpec` of a graph topic, with a clear error for an unknown one."""
    try:
        return TOPICS[name]
    except KeyError:
        raise KeyError(f'unknown topic {name!r}; known topics: {sorted(TOPICS)}') from None




# Why each topic has the QoS it has: reliability, durability, history (issue #10). One entry per
# topic of TOPICS (a test checks it). What a lost, late or overwritten message would cost; lost
# and late commands are simulated on purpose by the dynamics node (``link_faults.*``,
# adcs_sim/truth/link_faults.py), the QoS is what keeps them from happening for real. BEST_EFFORT is
# used nowhere in the loop: every dropped datagram would become a missed step or a silent hole in
# the bag, and lockstep runs would depend on the network.
QOS_RATIONALE: dict[str, str] = {
    STATE: 'RELIABLE: a lost state is a step the controller never answers (a wall-clock timeout, '
           'a missed step) and a hole in the recording. VOLATILE: a controller that joins or '
           'restarts late must act on the next state, never on an old one. KEEP_LAST with the '
           'lockstep depth: one state per step, at most a few in flight while the dynamics node '
           'waits for the answer; the depth absorbs a busy recorder with bounded memory.',
    TRUTH_STATE: 'RELIABLE, VOLATILE, KEEP_LAST lockstep depth, as state: recorded every step for '
                 'the metrics; nobody acts on an old one.',
    WHEELS_STATE: 'RELIABLE, VOLATILE, KEEP_LAST lockstep depth, as state: per-step wheel data for '
                  'the recorder and observers; an old one is meaningless to a late joiner.',
    WHEELS_CMD: 'RELIABLE: one answer per state, stamped with its stamp; a lost one is a missed '
                'step under the timeout policy. VOLATILE: a command answers one step; replayed to '
                'a dynamics node that joins late it would only be counted stale. KEEP_LAST '
                'lockstep depth: one in flight per step.',
    TORQUE_CMD: 'RELIABLE, VOLATILE, KEEP_LAST lockstep depth, for the reasons of wheels/cmd.',
    APPLIED_TORQUE: 'RELIABLE: the metrics integrate the applied torque of every step. VOLATILE, '
                    'KEEP_LAST lockstep depth: for the recorder; nobody acts on it.',
    CLOCK: 'RELIABLE: a subscriber keeps every tick (the fault injector, the runner\'s progress; the '
           'recorder writes its own from the state: adcs_msgs_py/recorded_topics.py; rclpy\'s time '
           'source subscribes best effort, which matches a reliable writer). VOLATILE: the past clock is meaningless to a late '
           'joiner. KEEP_LAST lockstep depth: one tick per step.',
    REFERENCE: 'RELIABLE, VOLATILE, KEEP_LAST lockstep depth, like the state it is compared with.',
    FAULTS: 'RELIABLE and TRANSIENT_LOCAL: the whole fault schedule is published once at start '
            '(one snapshot per event, stamped with its due time); a node that joins or restarts '
            'late, the recorder included, must still receive all of it from the writer\'s '
            'history. KEEP_LAST depth 100 bounds the schedule.',
    CONTROLLER_STATUS: 'RELIABLE: what the papers plot (mode, Lyapunov value), one per step, '
                       'recorded. VOLATILE: diagnostics of the past are not state. KEEP_LAST '
                       'status depth: it goes out after the command, off the critical path, and '
                       'may queue behind it.',
    # seed 002's thrusters (their topics come with the thruster actuation)
    'thrusters/cmd': 'RELIABLE: per-step on-times answering a state; a lost one is a missed step. '
                     'VOLATILE: a command answers one step only. KEEP_LAST lockstep depth.',
    'thrusters/state': 'RELIABLE: what the thrusters applied each step, recorded for the metrics. '
                       'VOLATILE, KEEP_LAST lockstep depth, as wheels/state.',
    **{s.topic: s.qos_reason for s in SENSOR_INTERFACES},   # adcs_msgs_py.sensor_interfaces
    ESTIMATE_STATE: 'RELIABLE, VOLATILE, KEEP_LAST lockstep depth, as state: a controller flying on the '
                    'estimate answers each one; an old estimate must never reach a late joiner.',
    ESTIMATOR_STATUS: 'RELIABLE, VOLATILE, KEEP_LAST status depth, as controller/status: the NIS and '
                      'innovations of every step are recorded for the consistency analysis.',
    DYNAMICS_STATUS: 'RELIABLE: missed steps and their times come from it (the metrics and the '
                     'gap of a crashed controller). VOLATILE, KEEP_LAST status depth, as '
                     'controller/status.',
    # for viewers: nobody in the loop acts on them; built and sent only to live subscribers (the
    # recorder writes its own from dynamics/recording and the state: adcs_msgs_py/recorded_topics.py)
    FRAMES_BODY: 'RELIABLE: a live viewer replays every step (as the bag, whose /tf is made from '
                 'it: a lost one is a frame missing). VOLATILE: a viewer that joins late wants the '
                 'current attitude, not the past. KEEP_LAST lockstep depth, as every per-step topic.',
    FRAMES_ORBIT: 'RELIABLE, VOLATILE, KEEP_LAST lockstep depth, as frames/body.',
    MARKERS: 'RELIABLE: each array carries every moving marker (a viewer that seeks or joins late '
             'needs only the latest), recorded every step. VOLATILE, KEEP_LAST lockstep depth, as '
             'frames/body.',
    MARKERS_STATIC: 'RELIABLE and TRANSIENT_LOCAL: what never changes is sent once, before t = 0 (its '
                    'serialisation would cost the loop every step); a viewer or recorder that joins '
                    'late still gets it from the writer, and in a bag it is the latest message of its '
                    'topic for every later instant (what a viewer backfills on a seek). KEEP_LAST '
                    'depth 100 as faults (one message).',
    ERROR_EIGENAXIS: 'RELIABLE, VOLATILE, KEEP_LAST lockstep depth: a plotted series, one sample a '
                     'step, recorded; a hole would show as a gap in the plot.',
    ERROR_EULER_213: 'RELIABLE, VOLATILE, KEEP_LAST lockstep depth, as error/eigenaxis.',
    RECORDING_CONFIG: 'RELIABLE and TRANSIENT_LOCAL: sent once before t = 0 and needed by a recorder '
                   'that joins late (it cannot write /clock or a viewer message without it; the dynamics node '
                   'also waits for the acknowledgement before t = 0). KEEP_LAST depth 100 as faults '
                   '(one message).',
    RECORDER_MATCHED: 'RELIABLE and TRANSIENT_LOCAL: a node that subscribes after an announcement still '
                      'gets the latest; published again whenever the recorder\'s matches change. '
                      'KEEP_LAST depth 100 as faults (only the latest counts).',
}
