"""numpy <-> message conversions, with validation of everything that comes in.

Simulated time travels as integer nanoseconds (``t_ns``) so that a command's stamp matches the
state it answers exactly; seconds are derived only for the physics.

Every ``*_from_msg`` function validates and raises :class:`InvalidMessage` with a reason; nodes
catch it through :class:`adcs_msgs_py.guard.RejectCounter`, which counts and warns (throttled).
"""
from __future__ import annotations

import json
import math
import struct
from collections.abc import Mapping, Sequence

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Vector3Stamped
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from adcs_core.attitude import quat_norm
from adcs_core.faults import FAULT_ERROR_MODES, FAULT_OK_MODES, FaultState
from adcs_msgs_py.measurements import received_attitude
from adcs_msgs_py.sensor_interfaces import SENSOR_FAULT_MODES

NS_PER_S = 1_000_000_000
# A quaternion whose norm is further than this from 1 is rejected (not silently renormalised).
UNIT_QUATERNION_TOLERANCE = 1e-6

INERTIAL_FRAME = 'inertial'
BODY_FRAME = 'body'

STATUS_LEVELS = {'OK': DiagnosticStatus.OK, 'WARN': DiagnosticStatus.WARN,
                 'ERROR': DiagnosticStatus.ERROR, 'STALE': DiagnosticStatus.STALE}


class InvalidMessage(ValueError):
    """A received message that must not reach the physics or a control law."""


# --- time -------------------------------------------------------------------------------------

def stamp_from_ns(t_ns: int) -> Time:
    """Integer nanoseconds -> builtin_interfaces/Time."""
    sec, nanosec = divmod(int(t_ns), NS_PER_S)
    return Time(sec=sec, nanosec=nanosec)


def ns_from_stamp(stamp: Time) -> int:
    """builtin_interfaces/Time -> integer nanoseconds."""
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def checked_stamp(topic: str, stamp: Time) -> int:
    """A received ``builtin_interfaces/Time`` -> integer nanoseconds; InvalidMessage for a stamp
    simulated time never has: negative seconds, or nanoseconds outside [0, 1e9)."""
    return _checked_ns(topic, int(stamp.sec), int(stamp.nanosec))


def _checked_ns(topic: str, sec: int, nanosec: int) -> int:
    if sec < 0 or not 0 <= nanosec < NS_PER_S:
        raise InvalidMessage(f'{topic}: stamp out of range (sec {sec}, nanosec {nanosec})')
    return sec * NS_PER_S + nanosec


def clock_from_msg(msg: Clock) -> int:
    """A received ``/clock`` -> simulated time (ns); InvalidMessage for an out-of-range stamp."""
    return checked_stamp('/clock', msg.clock)


def checked_cdr_stamp(topic: str, data: bytes) -> int:
    """Stamp (ns) of a serialized message whose first field is a ``builtin_interfaces/Time`` (every
    topic of the graph), read from the CDR bytes (4-byte encapsulation header, int32 sec, uint32
    nanosec) and checked as :func:`checked_stamp`; InvalidMessage for too short a message."""
    if len(data) < 12:
        raise InvalidMessage(f'{topic}: {len(data)} bytes, too short for a stamped message')
    sec, nanosec = struct.unpack_from('<iI' if data[1] & 1 else '>iI', data, 4)
    return _checked_ns(topic, sec, nanosec)


def ns_from_seconds(t: float) -> int:
    """Seconds -> integer nanoseconds, rounded to the nearest nanosecond."""
    return int(round(float(t) * NS_PER_S))


def clock_msg(t_ns: int) -> Clock:
    """/clock message for simulated time ``t_ns``."""
    return Clock(clock=stamp_from_ns(t_ns))


# --- validation helpers -------------------------------------------------------------------

def _finite(name: str, values, length: int | None = None) -> np.ndarray:
    # Plain-float checks: messages carry a handful of numbers, and numpy's per-call overhead
    # would dominate (this runs on every message of the lockstep loop).
    values = [float(v) for v in values]
    if length is not None and len(values) != length:
        raise InvalidMessage(f'{name}: expected {length} values, got {len(values)}')
    if not all(map(math.isfinite, values)):
        raise InvalidMessage(f'{name}: non-finite value in {values}')
    return np.array(values)


def checked_quaternion(name: str, xyzw, tol: float = UNIT_QUATERNION_TOLERANCE) -> np.ndarray:
    """Validate a unit quaternion (x, y, z, w); return it as an array (renormalised within tol)."""
    q = _finite(name, xyzw, 4)
    norm = float(quat_norm(q))  # the norm received_attitude divides by
    if abs(norm - 1.0) > tol:
        raise InvalidMessage(f'{name}: quaternion norm {norm:.9g} is not 1 (tolerance {tol:g})')
    return received_attitude(q, norm)


# --- state (attitude + rate in one stamped message) ---------------------------------------

def state_to_msg(t_ns: int, q: np.ndarray, w: np.ndarray, msg: Odometry | None = None) -> Odometry:
    """Attitude ``q`` (x, y, z, w; body in inertial) and body rate ``w`` -> nav_msgs/Odometry.

    The twist is expressed in the child (body) frame as REP-105 prescribes. A message object can be
    passed in to be reused (saves allocation on the hot path).
    """
    if msg is None:
        msg = Odometry()
        msg.header.frame_id = INERTIAL_FRAME
        msg.child_frame_id = BODY_FRAME
    msg.header.stamp = stamp_from_ns(t_ns)
    o = msg.pose.pose.orientation
    o.x, o.y, o.z, o.w = (float(v) for v in q)
    a = msg.twist.twist.angular
    a.x, a.y, a.z = (float(v) for v in w)
    return msg


def state_from_msg(msg: Odometry) -> tuple[int, np.ndarray, np.ndarray]:
    """nav_msgs/Odometry -> (t_ns, q (x y z w), w); raises InvalidMessage."""
    o, a, stamp = msg.pose.pose.orientation, msg.twist.twist.angular, msg.header.stamp
    return state_from_values((o.x, o.y, o.z, o.w), (a.x, a.y, a.z), stamp.sec, stamp.nanosec)


def state_from_values(xyzw, w, sec: int, nanosec: int) -> tuple[int, np.ndarray, np.ndarray]:
    """:func:`state_from_msg` of the message's numbers (orientation, angular rate, stamp): the
    checks of the object path and of the serialized one (:mod:`adcs_msgs_py.cdr`)."""
    q = checked_quaternion('state.pose.orientation', xyzw)
    w = _finite('state.twist.angular', w, 3)
    return _checked_ns('state', int(sec), int(nanosec)), q, w


# --- wheels -------------------------------------------------------------------------------

def wheel_state_to_msg(t_ns: int, names: Sequence[str], angle, speed, torque,
                       msg: JointState | None = None) -> JointState:
    """Wheel angles (rad), speeds relative to the body (rad/s), applied motor torques (N m)."""
    return _joint_state_to_msg(t_ns, names, angle, speed, torque, msg)


def wheel_state_from_msg(msg: JointState) -> tuple[int, list[str], np.ndarray, np.ndarray, np.ndarray]:
    """sensor_msgs/JointState of the wheels -> (t_ns, names, angle, speed, torque)."""
    return _joint_state_from_msg('wheels/state', msg)


def _joint_state_to_msg(t_ns, names, position, velocity, effort, msg: JointState | None) -> JointState:
    """A per-actuator JointState (wheels, thrusters); ``msg`` is reused (names kept) if given."""
    if msg is None:
        msg = JointState()
        msg.name = list(names)
    msg.header.stamp = stamp_from_ns(t_ns)
    msg.position = [float(v) for v in position]
    msg.velocity = [float(v) for v in velocity]
    msg.effort = [float(v) for v in effort]
    return msg


def _joint_state_from_msg(topic: str, msg: JointState):
    """(t_ns, names, position, velocity, effort) of a per-actuator JointState, each array finite
    and one value per name (else InvalidMessage naming ``topic`` and the field)."""
    n = len(msg.name)
    return (checked_stamp(topic, msg.header.stamp), list(msg.name), _finite(f'{topic}.position', msg.position, n),
            _finite(f'{topic}.velocity', msg.velocity, n), _finite(f'{topic}.effort', msg.effort, n))


def wheel_speeds_from_msg(msg: JointState, names: Sequence[str]) -> tuple[int, np.ndarray]:
    """``(t_ns, speeds)`` of the wheels ``names`` (in that order) from a ``wheels/state``; a wheel
    the message does not carry makes it invalid."""
    t_ns, got, _, speed, _ = wheel_state_from_msg(msg)
    index = {n: i for i, n in enumerate(got)}
    missing = [n for n in names if n not in index]
    if missing:
        raise InvalidMessage(f'wheels/state: no speed for wheel(s) {missing} (got {got})')
    return t_ns, speed[[index[n] for n in names]]


def wheel_cmd_to_msg(t_ns: int, names: Sequence[str], effort=None, velocity=None) -> JointState:
    """Wheel command: motor torques (``effort``) or speeds (``velocity``), one per named wheel."""
    if (effort is None) == (velocity is None):
        raise ValueError('give exactly one of effort (torque mode) or velocity (speed mode)')
    msg = JointState()
    msg.header.stamp = stamp_from_ns(t_ns)
    msg.name = list(names)
    if effort is not None:
        msg.effort = [float(v) for v in effort]
    else:
        msg.velocity = [float(v) for v in velocity]
    return msg


def _command_names(topic: str, what: str, msg: JointState, known: Mapping[str, int]) -> list[str]:
    """The actuator names of a command: at least one, unique, all known (else InvalidMessage)."""
    names = list(msg.name)
    if not names:
        raise InvalidMessage(f'{topic}: no {what} names')
    if len(set(names)) != len(names):
        raise InvalidMessage(f'{topic}: duplicate {what} names {names}')
    unknown = [n for n in names if n not in known]
    if unknown:
        raise InvalidMessage(f'{topic}: unknown {what} name(s) {unknown}; known: {list(known)}')
    return names


def wheel_cmd_from_msg(msg: JointState, known: Mapping[str, int]) -> tuple[int, np.ndarray, np.ndarray, str]:
    """Validate a wheel command against the known wheel names.

    Returns ``(t_ns, index, values, mode)``: ``index`` maps each commanded wheel to its position in
    the plant, ``mode`` is ``'torque'`` (effort) or ``'speed'`` (velocity). A command may name a
    subset of the wheels; wheels it does not name keep their previous command.
    """
    names = _command_names('wheels/cmd', 'wheel', msg, known)
    has_effort, has_velocity = len(msg.effort) > 0, len(msg.velocity) > 0
    if has_effort == has_velocity:
        raise InvalidMessage('wheels/cmd: set exactly one of effort (torque) or velocity (speed)')
    if has_effort:
        values, mode = _finite('wheels/cmd.effort', msg.effort, len(names)), 'torque'
    else:
        values, mode = _finite('wheels/cmd.velocity', msg.velocity, len(names)), 'speed'
    index = np.array([known[n] for n in names], dtype=int)
    return checked_stamp('wheels/cmd', msg.header.stamp), index, values, mode


# --- thrusters (seed 002) --------------------------------------------------------------------
#
# Command = an on-time per thruster, not a force: a thruster is an on/off valve, so the on-time is
# what its driver is given; the plant applies the valve's rules (clip to the period, minimum
# on-time) and integrates the pulse exactly (adcs_sim.truth.thrusters.step_pulsed). A force command
# would make the plant re-invent the pulse (PWM) that the controller's firing logic decides.

def thruster_cmd_to_msg(t_ns: int, names: Sequence[str], on_time) -> JointState:
    """Thruster command for the period starting at ``t_ns``: on-time (s) per named thruster in
    ``effort`` (0: off; the period: on throughout)."""
    msg = JointState()
    msg.header.stamp = stamp_from_ns(t_ns)
    msg.name = list(names)
    msg.effort = [float(v) for v in on_time]
    return msg


def thruster_cmd_from_msg(msg: JointState, known: Mapping[str, int]) -> tuple[int, np.ndarray, np.ndarray]:
    """Validate a thruster command: ``(t_ns, index, on_time)``. Known, unique names; one finite,
    non-negative on-time (``effort``, s) per name; no ``position``/``velocity``. A command may name
    a subset of the thrusters; the others are off for the period."""
    names = _command_names('thrusters/cmd', 'thruster', msg, known)
    if len(msg.position) or len(msg.velocity):
        raise InvalidMessage('thrusters/cmd: the on-times go in effort (s); position and velocity '
                             'must be empty')
    on_time = _finite('thrusters/cmd.effort', msg.effort, len(names))
    if any(v < 0.0 for v in on_time):
        raise InvalidMessage(f'thrusters/cmd.effort: negative on-time in {on_time.tolist()}')
    index = np.array([known[n] for n in names], dtype=int)
    return checked_stamp('thrusters/cmd', msg.header.stamp), index, on_time


def thruster_state_to_msg(t_ns: int, names: Sequence[str], impulse, on_time, force,
                          msg: JointState | None = None) -> JointState:
    """Thruster state of the step starting at ``t_ns``: cumulated impulse at the step's end
    (``position``, N s), on-time applied (``velocity``, s), thrust at ``t_ns`` (``effort``, N)."""
    return _joint_state_to_msg(t_ns, names, impulse, on_time, force, msg)


def thruster_state_from_msg(msg: JointState) -> tuple[int, list[str], np.ndarray, np.ndarray, np.ndarray]:
    """sensor_msgs/JointState of the thrusters -> (t_ns, names, impulse, on_time, force)."""
    return _joint_state_from_msg('thrusters/state', msg)


# --- body torques ---------------------------------------------------------------------------

def vector_to_msg(t_ns: int, v, frame_id: str = BODY_FRAME) -> Vector3Stamped:
    """3-vector (body axes) -> geometry_msgs/Vector3Stamped."""
    msg = Vector3Stamped()
    msg.header.stamp = stamp_from_ns(t_ns)
    msg.header.frame_id = frame_id
    msg.vector.x, msg.vector.y, msg.vector.z = (float(x) for x in v)
    return msg


def vector_from_msg(msg: Vector3Stamped, name: str = 'torque_cmd') -> tuple[int, np.ndarray]:
    """geometry_msgs/Vector3Stamped -> (t_ns, vector); raises InvalidMessage."""
    v, stamp = msg.vector, msg.header.stamp
    return vector_from_values((v.x, v.y, v.z), stamp.sec, stamp.nanosec, name)


def vector_from_values(xyz, sec: int, nanosec: int, name: str = 'torque_cmd') -> tuple[int, np.ndarray]:
    """:func:`vector_from_msg` of the message's numbers (vector, stamp)."""
    return _checked_ns(name, int(sec), int(nanosec)), _finite(f'{name}.vector', xyz, 3)


# --- status (DiagnosticArray) ----------------------------------------------------------------

def status_to_msg(t_ns: int, name: str, values: Mapping[str, object], level: str = 'OK',
                  message: str = '', hardware_id: str = '') -> DiagnosticArray:
    """One DiagnosticStatus named ``name`` with ``values`` as key/value strings.

    Floats are written with ``repr`` so they read back bit for bit.
    """
    status = DiagnosticStatus(level=STATUS_LEVELS[level], name=name, message=message,
                              hardware_id=hardware_id)
    status.values = [KeyValue(key=k, value=v) for k, v in status_pairs(values)]
    msg = DiagnosticArray(status=[status])
    msg.header.stamp = stamp_from_ns(t_ns)
    return msg


def status_pairs(values: Mapping[str, object]) -> list[tuple[str, str]]:
    """The (key, value) strings of a status: floats by ``repr`` (they read back bit for bit)."""
    return [(str(k), repr(float(v)) if isinstance(v, (float, np.floating)) else str(v)) for k, v in values.items()]


def status_values(status: DiagnosticStatus) -> dict[str, object]:
    """KeyValues of a DiagnosticStatus -> dict, numbers parsed back to float where they parse."""
    out: dict[str, object] = {}
    for kv in status.values:
        try:
            out[kv.key] = float(kv.value)
        except ValueError:
            out[kv.key] = kv.value
    return out


# --- faults (DiagnosticArray, one status per actuator) -----------------------------------------



def faults_to_msg(t_ns: int, snapshot: Mapping[str, FaultState], event: int, events: int) -> DiagnosticArray:
    """The fault state of every actuator at ``t_ns``: one status per actuator (name = actuator,
    level ERROR for a fault and OK for nominal/recovered, message = mode) with key/values
    ``mode``, ``value``, ``time`` (of its last event, s) and the schedule position ``event`` of
    ``events`` (so a subscriber knows when it has the whole schedule)."""
    msg = DiagnosticArray()
    msg.header.stamp = stamp_from_ns(t_ns)
    for name, (mode, value, t) in snapshot.items():   # FaultState fields
        level = 'ERROR' if mode in FAULT_ERROR_MODES else 'OK'
        status = DiagnosticStatus(level=STATUS_LEVELS[level], name=name, message=mode,
                                  hardware_id='fault_injector')
        status.values = [KeyValue(key='mode', value=mode), KeyValue(key='value', value=repr(float(value))),
                         KeyValue(key='time', value=repr(float(t))),
                         KeyValue(key='event', value=str(int(event))),
                         KeyValue(key='events', value=str(int(events)))]
        msg.status.append(status)
    return msg


def faults_from_msg(msg: DiagnosticArray, known: Mapping[str, int]
                    ) -> tuple[int, int, int, dict[str, FaultState]]:
    """``(t_ns, event, events, {actuator: FaultState})`` of a ``faults`` message; InvalidMessage
    for an out-of-range stamp, no status, an unknown or repeated actuator, an unknown mode, a
    non-finite or (degraded) negative value, or a schedule position that is missing, out of
    ``0 <= event < events <= MAX_FAULT_EVENTS`` or differs between the statuses."""
    t_ns = checked_stamp('faults', msg.header.stamp)
    if not msg.status:
        raise InvalidMessage('faults: no actuator status')
    out: dict[str, FaultState] = {}
    positions = set()
    for status in msg.status:
        name, state, position = _fault_status(status, known)
        if name in out:
            raise InvalidMessage(f'faults: actuator {name!r} named twice')
        out[name] = state
        positions.add(position)
    if len(positions) != 1:
        raise InvalidMessage(f'faults: the statuses disagree on the schedule position {sorted(positions)}')
    event, events = positions.pop()
    return t_ns, event, events, out


MAX_FAULT_EVENTS = 100  # snapshots in a schedule: the depth of the latched faults topic


def _fault_status(status: DiagnosticStatus, known: Mapping[str, int]) -> tuple[str, FaultState, tuple[int, int]]:
    """``(actuator, FaultState, (event, events))`` of one status of a ``faults`` message."""
    name = status.name
    if name not in known and name not in SENSOR_FAULT_MODES:
        raise InvalidMessage(f'faults: unknown actuator {name!r} (known: {sorted(known)} and the sensor '
                             f'targets {list(SENSOR_FAULT_MODES)})')
    values = {kv.key: kv.value for kv in status.values}
    mode = values.get('mode', status.message)
    allowed = SENSOR_FAULT_MODES[name] if name in SENSOR_FAULT_MODES else FAULT_ERROR_MODES
    if mode not in allowed + FAULT_OK_MODES:
        raise InvalidMessage(f'faults: unknown mode {mode!r} for {name!r}')
    try:
        value, t = float(values.get('value', '0')), float(values.get('time', '0'))
        event, events = int(values['event']), int(values['events'])
    except (KeyError, ValueError, OverflowError) as exc:
        raise InvalidMessage(f'faults: bad or missing key/value for {name!r}: {exc}') from None
    if not math.isfinite(value) or (mode == 'degraded' and value < 0.0):
        raise InvalidMessage(f'faults: value {value!r} is not valid for {name!r} ({mode})')
    if not (math.isfinite(t) and t >= 0.0):
        raise InvalidMessage(f'faults: event time {t!r} of {name!r} is not a finite time >= 0')
    if not 0 <= event < events <= MAX_FAULT_EVENTS:
        raise InvalidMessage(f'faults: schedule position {event} of {events} for {name!r} is out of '
                             f'0 <= event < events <= {MAX_FAULT_EVENTS}')
    return name, FaultState(mode, value, t), (event, events)


# --- the recorder's start-up handshake (recorder/matched) ----------------------------------------

MAX_MATCHED_TEXT = 1 << 20   # bytes: a handshake of hundreds of topics is ~10 kB


def matched_to_msg(matched: Mapping[str, Sequence[str]]) -> String:
    """``{resolved topic: [fully qualified node name, ...]}`` -> std_msgs/String (JSON, sorted)."""
    return String(data=json.dumps({t: sorted(n) for t, n in sorted(matched.items())}))


def matched_from_msg(msg: String, topic: str = 'recorder/matched') -> dict[str, frozenset[str]]:
    """The inverse of :func:`matched_to_msg`, checked: a JSON object of topic names to lists of node
    names, at most :data:`MAX_MATCHED_TEXT` bytes; anything else is an :class:`InvalidMessage`."""
    text = msg.data
    if not isinstance(text, str) or len(text) > MAX_MATCHED_TEXT:
        raise InvalidMessage(f'{topic}: not a JSON text of at most {MAX_MATCHED_TEXT} bytes')
    try:
        raw = json.loads(text)
    except (ValueError, RecursionError) as exc:   # RecursionError: a nesting bomb
        raise InvalidMessage(f'{topic}: not JSON ({type(exc).__name__})') from None
    if not isinstance(raw, dict) or not all(
            isinstance(t, str) and isinstance(n, list) and all(isinstance(x, str) for x in n) for t, n in raw.items()):
        raise InvalidMessage(f'{topic}: not an object of topic names to lists of node names')
    return {t: frozenset(n) for t, n in raw.items()}
