"""Serialized (CDR) fast path of the lockstep loop's hot messages: encode to and decode from the bytes
DDS carries, without building rclpy message objects.

rclpy's ``Publisher.publish`` takes ``bytes`` (``publish_raw``) and a subscription made with
``raw=True`` hands over the serialized bytes, so a node can skip the Python message objects, their
conversion to C and rmw's (de)serialisation, which cost the graph most of its per-step time
(issue 18's profiles: ~140 us per publish in the dynamics node, ~500 us per ``take_message`` of an
``Odometry`` in the controller).

* **Encoding** (:class:`Template`): a message whose variable-length parts (frame ids, joint names,
  sequence lengths) are fixed for a publisher has a fixed layout. Its bytes are made once by rosbags'
  CDR serialiser (zero padding and the exact wire length, as rmw puts an rclpy message on the wire;
  rclpy's ``serialize_message`` leaves padding bytes uninitialised), and the offset of every number
  the node changes is derived by serialising two sentinel values into it and locating the bytes that
  differ. Each step copies the template and writes the numbers with precompiled
  ``struct.Struct.pack_into`` runs. The status (:func:`status_bytes`, strings of varying lengths) is
  written string by string (CDR: ``uint32`` length with the NUL, UTF-8 bytes, NUL, 4-byte alignment).
* **Decoding** (:meth:`Template.decode`): when a message has its template's length and every byte outside
  the numbers (encapsulation, strings, sequence lengths, padding) equals the template's, the numbers
  are read with one ``Struct.unpack_from`` and go through the very validation of the object path
  (:mod:`adcs_msgs_py.conversions`: same acceptance, same :class:`InvalidMessage` texts). Anything
  else falls back to ``rclpy.serialization.deserialize_message`` and the ``*_from_msg`` function;
  bytes that do not deserialize are an :class:`InvalidMessage` too (nothing else escapes). The
  layouts of a received JointState (whose names the receiver does not fix) are learnt from the
  messages the object path accepted (:class:`JointStateCodec`).

Measured (``benchmarks/cdr_codec.py``: us per message, the three ways alternated in one run, medians;
2-core machine shared with other jobs, so the ratios are the figures, the absolute times ~5-10x a
quiet machine's). Encode: rclpy objects + ``serialize_message`` / rosbags ``serialize_cdr`` (its
message object updated in place) / this module: Odometry state 426 / 102 / 35 us, JointState of 3
wheels 253 / 145 / 94, /clock 113 / 44 / 12, 17-value status 722 / 584 / 284. Decode + validation:
``deserialize_message`` / rosbags ``deserialize_cdr`` / this module: state 735 / 288 / 71, wheel
state 213 / 170 / 81. rosbags is the library made for CDR and makes the templates here (and serves
the bag code), but per message it builds and walks dataclass objects as rclpy does: this module is
1.5-4x faster than rosbags and 2.5-12x faster than the object path, so the hot path uses it.
"""
from __future__ import annotations

import array
import copy
import struct
from collections.abc import Mapping, Sequence

import numpy as np
from geometry_msgs.msg import TransformStamped, Vector3Stamped
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState

from adcs_msgs_py import conversions as cv
from adcs_msgs_py.conversions import NS_PER_S, InvalidMessage
from adcs_msgs_py.topics import TOPICS
from adcs_msgs_py.typestore import typestore

_SLOT_FORMATS = {'double': 'd', 'float': 'f', 'int32': 'i', 'uint32': 'I', 'int64': 'q', 'uint64': 'Q'}
# Two values of each number format whose bytes all differ (the offset probe's sentinels).
_SENTINELS = {'d': (struct.unpack('<d', bytes(range(0x11, 0x18)) + b'\x3f')[0],
                    struct.unpack('<d', bytes(range(0x21, 0x28)) + b'\x40')[0]),
              'f': (struct.unpack('<f', b'\x11\x12\x13\x3f')[0], struct.unpack('<f', b'\x21\x22\x23\x40')[0]),
              'i': (0x11121314, 0x21222324), 'I': (0x11121314, 0x21222324),
              'q': (0x1112131415161718, 0x2122232425262728), 'Q': (0x1112131415161718, 0x2122232425262728)}
STAMP = ('header.stamp.sec', 'header.stamp.nanosec')


def type_name(msg_type: type) -> str:
    """``nav_msgs/msg/Odometry`` of an rclpy message class."""
    return f'{msg_type.__module__.split(".")[0]}/msg/{msg_type.__name__}'


def to_rosbags(msg):
    """The rosbags message object equal to the rclpy message ``msg`` (for its CDR serialiser)."""
    cls = typestore().types[type_name(type(msg))]
    fields = {}
    for name in msg.get_fields_and_field_types():
        value = getattr(msg, name)
        if hasattr(value, 'get_fields_and_field_types'):
            value = to_rosbags(value)
        elif isinstance(value, (array.array, np.ndarray)):
            value = np.array(value)
        elif isinstance(value, list) and value and hasattr(value[0], 'get_fields_and_field_types'):
            value = [to_rosbags(v) for v in value]
        elif isinstance(value, bytes) and len(value) == 1:   # an octet (DiagnosticStatus.level)
            value = value[0]
        fields[name] = value
    return cls(**fields)


def rosbags_cdr(msg) -> bytes:
    """CDR bytes of the rclpy message ``msg`` by rosbags' serialiser (zero padding, wire length)."""
    return bytes(typestore().serialize_cdr(to_rosbags(msg), type_name(type(msg))))


def _walk(obj, path: str):
    """``(parent, key, is_index)`` of the leaf ``path`` (``a.b[3].c``) of a message object."""
    parts = path.split('.')
    for part in parts[:-1]:
        obj = _step(obj, part)
    last = parts[-1]
    if '[' in last:
        name, index = last[:-1].split('[')
        return getattr(obj, name), int(index), True
    return obj, last, False


def _step(obj, part: str):
    if '[' in part:
        name, index = part[:-1].split('[')
        return getattr(obj, name)[int(index)]
    return getattr(obj, part)


def _set(obj, path: str, value) -> None:
    parent, key, is_index = _walk(obj, path)
    if is_index:
        parent[key] = value
    else:
        setattr(parent, key, value)


def slot_format(msg, path: str) -> str:
    """``struct`` format character of the number at ``path`` of the rclpy message ``msg``."""
    parts = path.split('.')
    parent = msg
    for part in parts[:-1]:
        parent = _step(parent, part)
    kind = type(parent).get_fields_and_field_types()[parts[-1].split('[')[0]]
    return _SLOT_FORMATS[kind.removeprefix('sequence<').removesuffix('>').split('[')[0]]


def probe_offset(rb_msg, typename: str, path: str, fmt: str) -> int:
    """Byte offset of the number at ``path`` in the CDR of the rosbags message ``rb_msg``: the bytes
    that differ between two serialisations with two sentinel values, checked to be exactly the
    number's bytes holding the sentinel."""
    out = []
    for value in _SENTINELS[fmt]:
        m = copy.deepcopy(rb_msg)
        _set(m, path, value)
        out.append(bytes(typestore().serialize_cdr(m, typename)))
    a, b = out
    diff = [i for i in range(len(a)) if a[i] != b[i]]
    size = struct.calcsize('<' + fmt)
    if len(a) != len(b) or not diff or diff != list(range(diff[0], diff[0] + size)) \
            or struct.unpack_from('<' + fmt, a, diff[0])[0] != _SENTINELS[fmt][0]:
        raise ValueError(f'{typename}.{path}: not a fixed-layout number of format {fmt!r}')
    return diff[0]


class Template:
    """The CDR bytes of one message layout, with the numbers at ``slots`` (attribute paths in wire
    order, e.g. ``header.stamp.sec``, ``position[2]``) to be written (:meth:`encode`) or read
    (:meth:`decode`); ``free`` slots are numbers a reader ignores (any value passes :meth:`decode`)."""

    def __init__(self, msg, slots: Sequence[str], free: Sequence[str] = ()) -> None:
        self.msg_type = type(msg)
        typename = type_name(self.msg_type)
        rb = to_rosbags(msg)
        self.data = bytes(typestore().serialize_cdr(rb, typename))
        self.size = len(self.data)
        offsets = [probe_offset(rb, typename, p, slot_format(msg, p)) for p in slots]
        if offsets != sorted(set(offsets)):
            raise ValueError(f'{typename}: slots must be given in wire order ({list(slots)})')
        read = [(o, slot_format(msg, p)) for o, p in zip(offsets, slots)]
        placed = sorted([(o, f, False) for o, f in read]
                        + [(probe_offset(rb, typename, p, slot_format(msg, p)),
                            slot_format(msg, p), True) for p in free])
        self._runs = _runs(read)
        self._unpack, self._checks = _reader(self.data, placed)

    def encode(self, values: Sequence) -> bytes:
        """The template with ``values`` (one per slot, in order) written in."""
        buf = bytearray(self.data)
        for offset, packer, start, stop in self._runs:
            packer.pack_into(buf, offset, *values[start:stop])
        return bytes(buf)

    def decode(self, data: bytes) -> tuple | None:
        """The slots' values if ``data`` has this layout (its length, and every byte that is not a
        slot's or a free slot's equal to the template's), else None."""
        if type(data) is not bytes or len(data) != self.size:
            return None
        for start, stop, expected in self._checks:
            if data[start:stop] != expected:
                return None
        return self._unpack(data)


def _runs(read) -> list[tuple[int, struct.Struct, int, int]]:
    """Contiguous slots merged: ``(offset, Struct, first value, end value)`` per run."""
    runs: list[list] = []
    for i, (offset, fmt) in enumerate(read):
        if runs and runs[-1][0] + struct.calcsize('<' + runs[-1][1]) == offset:
            runs[-1][1] += fmt
            runs[-1][3] = i + 1
        else:
            runs.append([offset, fmt, i, i + 1])
    return [(o, struct.Struct('<' + f), a, b) for o, f, a, b in runs]


def _reader(data: bytes, placed):
    """One ``Struct.unpack`` of the read slots over the whole message (pad bytes elsewhere) and the
    ``(start, stop, bytes)`` regions that must equal the template's."""
    fmt, checks, pos = '<', [], 0
    for offset, f, is_free in placed:
        size = struct.calcsize('<' + f)
        if offset > pos:
            fmt += f'{offset - pos}x'
            checks.append((pos, offset, data[pos:offset]))
        fmt += f'{size}x' if is_free else f
        pos = offset + size
    if pos < len(data):
        fmt += f'{len(data) - pos}x'
        checks.append((pos, len(data), data[pos:]))
    return struct.Struct(fmt).unpack, checks


def _stamp(t_ns: int) -> tuple[int, int]:
    return divmod(int(t_ns), NS_PER_S)


def _floats(values) -> Sequence:
    """Numbers as ``pack`` takes them fastest: an array's ``tolist`` (Python floats: ``float(v)``
    of each element, as the object path's conversions take them)."""
    return values.tolist() if isinstance(values, np.ndarray) else values


def deserialized(data: bytes, msg_type: type, topic: str):
    """``deserialize_message`` of received bytes (a ``msg_type`` object is taken as it is: the
    handlers also take the object path's messages); InvalidMessage if they are not a ``msg_type``."""
    if isinstance(data, msg_type):
        return data
    try:
        return deserialize_message(data, msg_type)
    except Exception as exc:  # noqa: BLE001 - rmw's error for bytes that are not the type
        what = f'{len(data)} bytes' if isinstance(data, bytes) else type(data).__name__
        raise InvalidMessage(f'{topic}: {what} that are not a {type_name(msg_type)} '
                             f'({type(exc).__name__})') from None


# --- the hot messages ---------------------------------------------------------------------

ORIENTATION = tuple(f'pose.pose.orientation.{c}' for c in 'xyzw')
ANGULAR = tuple(f'twist.twist.angular.{c}' for c in 'xyz')
# The numbers of an Odometry a state reader ignores (an estimate fills the covariances).
ODOMETRY_UNREAD = (*(f'pose.pose.position.{c}' for c in 'xyz'), *(f'pose.covariance[{i}]' for i in range(36)),
                   *(f'twist.twist.linear.{c}' for c in 'xyz'), *(f'twist.covariance[{i}]' for i in range(36)))


class StateCodec:
    """``state`` / ``truth/state`` / ``estimate/state`` (nav_msgs/Odometry): :meth:`encode` is
    :func:`~adcs_msgs_py.conversions.state_to_msg`, :meth:`decode` is
    :func:`~adcs_msgs_py.conversions.state_from_msg` of the deserialized bytes."""

    def __init__(self, topic: str = 'state') -> None:
        self.topic = topic
        msg = cv.state_to_msg(0, (0.0, 0.0, 0.0, 1.0), (0.0, 0.0, 0.0))
        self.template = Template(msg, (*STAMP, *ORIENTATION, *ANGULAR), free=ODOMETRY_UNREAD)

    def encode(self, t_ns: int, q, w) -> bytes:
        sec, nanosec = _stamp(t_ns)
        return self.template.encode((sec, nanosec, float(q[0]), float(q[1]), float(q[2]), float(q[3]),
                                     float(w[0]), float(w[1]), float(w[2])))

    def decode(self, data: bytes) -> tuple[int, np.ndarray, np.ndarray]:
        v = self.template.decode(data)
        if v is None:
            return cv.state_from_msg(deserialized(data, Odometry, self.topic))
        return cv.state_from_values(v[2:6], v[6:9], v[0], v[1])


class ClockCodec:
    """``/clock``: :func:`~adcs_msgs_py.conversions.clock_msg`."""

    def __init__(self) -> None:
        self.template = Template(cv.clock_msg(0), ('clock.sec', 'clock.nanosec'))

    def encode(self, t_ns: int) -> bytes:
        return self.template.encode(_stamp(t_ns))


class VectorCodec:
    """A geometry_msgs/Vector3Stamped in frame ``frame_id`` (``applied_torque``, ``torque_cmd``,
    ``error/*``): :func:`~adcs_msgs_py.conversions.vector_to_msg` / ``vector_from_msg``."""

    def __init__(self, topic: str = 'torque_cmd', frame_id: str = cv.BODY_FRAME) -> None:
        self.topic = topic
        self.template = Template(cv.vector_to_msg(0, (0.0, 0.0, 0.0), frame_id),
                                 (*STAMP, 'vector.x', 'vector.y', 'vector.z'))

    def encode(self, t_ns: int, v) -> bytes:
        sec, nanosec = _stamp(t_ns)
        return self.template.encode((sec, nanosec, float(v[0]), float(v[1]), float(v[2])))

    def decode(self, data: bytes) -> tuple[int, np.ndarray]:
        v = self.template.decode(data)
        if v is None:
            return cv.vector_from_msg(deserialized(data, Vector3Stamped, self.topic), self.topic)
        return cv.vector_from_values(v[2:5], v[0], v[1], self.topic)


class TransformCodec:
    """A rotation-only geometry_msgs/TransformStamped ``parent -> child`` (``frames/*``):
    :func:`adcs_msgs_py.visual.set_transform` of :func:`~adcs_msgs_py.visual.transform_msg`."""

    def __init__(self, parent: str, child: str) -> None:
        msg = TransformStamped()
        msg.header.frame_id, msg.child_frame_id = parent, child
        msg.transform.rotation.w = 1.0
        self.template = Template(msg, (*STAMP, *(f'transform.rotation.{c}' for c in 'xyzw')))

    def encode(self, t_ns: int, q) -> bytes:
        sec, nanosec = _stamp(t_ns)
        return self.template.encode((sec, nanosec, float(q[0]), float(q[1]), float(q[2]), float(q[3])))


class _Stamp:
    __slots__ = ('sec', 'nanosec')

    def __init__(self, sec: int, nanosec: int) -> None:
        self.sec, self.nanosec = sec, nanosec


class _Header:
    __slots__ = ('stamp',)

    def __init__(self, stamp: _Stamp) -> None:
        self.stamp = stamp


class JointStateView:
    """The fields of a received sensor_msgs/JointState that the ``*_from_msg`` conversions read
    (``header.stamp``, ``name``, ``position``, ``velocity``, ``effort``), read from its CDR bytes."""
    __slots__ = ('header', 'name', 'position', 'velocity', 'effort')

    def __init__(self, sec: int, nanosec: int, name, position, velocity, effort) -> None:
        self.header = _Header(_Stamp(sec, nanosec))
        self.name, self.position, self.velocity, self.effort = name, position, velocity, effort


def joint_state_template(frame_id: str, names: Sequence[str], lengths: tuple[int, int, int]) -> Template:
    """The template of a JointState of ``names`` with ``lengths`` positions, velocities, efforts."""
    msg = JointState(name=list(names))
    msg.header.frame_id = frame_id
    slots = list(STAMP)
    for field, n in zip(('position', 'velocity', 'effort'), lengths):
        setattr(msg, field, [0.0] * n)
        slots += [f'{field}[{i}]' for i in range(n)]
    return Template(msg, slots)


class JointStateCodec:
    """sensor_msgs/JointState of actuators (``wheels/state``, ``thrusters/state``, ``wheels/cmd``,
    ``thrusters/cmd``): a template per (names, sequence lengths), made on first use.

    :meth:`message` reads received bytes as the conversions' ``msg`` argument: a
    :class:`JointStateView` when they have the layout of a message this codec has already taken by
    the object path (it learns up to :data:`MAX_LAYOUTS` layouts, of messages of at most
    :data:`MAX_LEARNT_VALUES` names and values), else the deserialized message."""

    MAX_LAYOUTS = 8
    MAX_LEARNT_VALUES = 64

    def __init__(self, topic: str) -> None:
        self.topic = topic
        self._encoders: dict[tuple, Template] = {}
        self._layouts: dict[tuple, tuple | None] = {}   # key -> (template, name, n_pos, n_vel) or None
        self._known: list[tuple] = []

    def encode(self, t_ns: int, names: Sequence[str], position=(), velocity=(), effort=()) -> bytes:
        key = (tuple(names), len(position), len(velocity), len(effort))
        template = self._encoders.get(key)
        if template is None:
            template = self._encoders[key] = joint_state_template('', names, key[1:])
        sec, nanosec = _stamp(t_ns)
        return template.encode((sec, nanosec, *_floats(position), *_floats(velocity), *_floats(effort)))

    def message(self, data: bytes):
        for template, name, a, b in self._known:
            v = template.decode(data)
            if v is not None:
                return JointStateView(v[0], v[1], name, v[2:2 + a], v[2 + a:2 + a + b], v[2 + a + b:])
        msg = deserialized(data, JointState, self.topic)
        if type(data) is bytes:
            self._learn(msg, data)
        return msg

    def _learn(self, msg: JointState, data: bytes) -> None:
        lengths = (len(msg.position), len(msg.velocity), len(msg.effort))
        key = (msg.header.frame_id, tuple(msg.name), lengths)
        if key in self._layouts or len(self._layouts) >= self.MAX_LAYOUTS \
                or len(msg.name) + sum(lengths) > self.MAX_LEARNT_VALUES:
            return
        try:
            template = joint_state_template(msg.header.frame_id, msg.name, lengths)
        except Exception:  # noqa: BLE001 - a name rosbags cannot serialise: this layout stays slow
            template = None
        if template is None or template.decode(data) is None:   # not the canonical bytes of its layout
            self._layouts[key] = None
            return
        self._layouts[key] = layout = (template, list(msg.name), lengths[0], lengths[1])
        self._known.insert(0, layout)


# --- status (DiagnosticArray of one DiagnosticStatus) -----------------------------------------

_U32 = struct.Struct('<I').pack
_STAMP = struct.Struct('<iI').pack
_PADS = (b'', b'\0', b'\0\0', b'\0\0\0')
# Encapsulation (CDR, little endian), then after the stamp: frame_id '' and one status.
_ENCAPSULATION = b'\x00\x01\x00\x00'
_EMPTY_FRAME_ONE_STATUS = _U32(1) + b'\0' + _PADS[3] + _U32(1)


def command_codec(topic: str) -> 'JointStateCodec | VectorCodec':
    """The codec of command topic ``topic`` by its message type (:data:`adcs_msgs_py.topics.TOPICS`):
    a JointState (``wheels/cmd``, ``thrusters/cmd``) or a Vector3Stamped (``torque_cmd``)."""
    msg_type = TOPICS[topic].msg_type
    if msg_type is JointState:
        return JointStateCodec(topic)
    if msg_type is Vector3Stamped:
        return VectorCodec(topic)
    raise ValueError(f'{topic}: {type_name(msg_type)} is not a command message type')


def status_bytes(t_ns: int, name: str, values: Mapping[str, object], level: str = 'OK', message: str = '',
                 hardware_id: str = ''):
    """The CDR bytes of :func:`~adcs_msgs_py.conversions.status_to_msg` (the same strings, written
    directly); the message object itself if a string holds a NUL (which CDR strings cannot carry)."""
    pairs = cv.status_pairs(values)
    strings = [name, message, hardware_id]
    for kv in pairs:
        strings += kv
    if any('\x00' in s for s in strings):
        return cv.status_to_msg(t_ns, name, values, level, message, hardware_id)
    sec, nanosec = _stamp(t_ns)
    parts = [_ENCAPSULATION, _STAMP(sec, nanosec), _EMPTY_FRAME_ONE_STATUS, cv.STATUS_LEVELS[level], _PADS[3]]
    pos = 28   # after the level and its padding
    for i, s in enumerate(strings):
        if i == 3:   # after name, message, hardware_id: the key/value count
            parts.append(_PADS[-pos % 4] + _U32(len(pairs)))
            pos += -pos % 4 + 4
        b = s.encode()
        parts.append(_PADS[-pos % 4] + _U32(len(b) + 1) + b + b'\0')
        pos += -pos % 4 + 5 + len(b)
    if not pairs:
        parts.append(_PADS[-pos % 4] + _U32(0))
    return b''.join(parts)
