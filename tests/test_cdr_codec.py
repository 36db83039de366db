"""The serialized fast path (adcs_msgs_py.cdr) against the object path, on fuzzed values.

Encoding: every encoder's bytes are rosbags' CDR of the object path's message (zero padding, the
wire length) and equal rclpy's ``serialize_message`` of that message on every byte but the
alignment padding (which rclpy's serialiser leaves uninitialised and rmw zeroes on the wire:
``test_cdr_wire.py``); rclpy reads them back to the same numbers, bit for bit.

Decoding: for any bytes (the encoders', rclpy's, truncated, flipped, extended, garbage), the codec
gives exactly what the object path gives (``deserialize_message`` then the ``*_from_msg``
conversion): the same values bit for bit, or an InvalidMessage with the same text; bytes that do not
deserialize are an InvalidMessage; nothing else is raised. Derandomised, bounded.
"""
from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState

from adcs_msgs_py import cdr
from adcs_msgs_py import conversions as cv
from adcs_msgs_py.conversions import InvalidMessage

FUZZ = settings(derandomize=True, max_examples=60, deadline=None, database=None,
                suppress_health_check=[HealthCheck.too_slow])

FLOAT = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=64),
                  st.sampled_from([0.0, -0.0, 5e-324, -5e-324, 2.2250738585072014e-308, 1e308, -1e308,
                                   math.nan, math.inf, -math.inf, 1.0, 0.5]))
T_NS = st.one_of(st.integers(0, (2**31 - 1) * cv.NS_PER_S + cv.NS_PER_S - 1),
                 st.sampled_from([0, 1, cv.NS_PER_S - 1, cv.NS_PER_S, (2**31 - 1) * cv.NS_PER_S]))
UNIT_Q = st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(lambda v: sum(x * x for x in v) > 0.01).map(
    lambda v: [x / math.sqrt(sum(y * y for y in v)) for x in v])
QUAT = st.one_of(UNIT_Q, st.lists(FLOAT, min_size=4, max_size=4))
VEC3 = st.lists(FLOAT, min_size=3, max_size=3)
WHEELS = ['rw_x', 'rw_y', 'rw_z']
NAMES = st.one_of(st.just(WHEELS), st.just(WHEELS[:2]), st.just(['rw_y']), st.just(['thr_1', 'thr_2', 'thr_3', 'thr_4']),
                  st.lists(st.sampled_from(WHEELS + ['rw_q', '', 'é']), max_size=4))
TEXT = st.text(st.characters(blacklist_categories=('Cs',), blacklist_characters='\x00'), max_size=12)


def bits(values) -> tuple:
    return tuple(struct.pack('<d', float(v)) for v in np.ravel(values))


def assert_wire_equal(ours: bytes, msg) -> None:
    """``ours`` is rosbags' CDR of ``msg``, rclpy reads it back, and it equals rclpy's
    ``serialize_message`` wherever that is not padding (ours zero there, and no number there)."""
    assert ours == cdr.rosbags_cdr(msg)
    ref = serialize_message(msg)
    assert len(ref) >= len(ours)
    differ = [i for i in range(len(ours)) if ours[i] != ref[i]]
    assert all(ours[i] == 0 for i in differ)
    assert cdr.rosbags_cdr(deserialize_message(ours, type(msg))) == ours


@FUZZ
@given(t_ns=T_NS, q=QUAT, w=VEC3)
def test_state_bytes_are_the_object_paths(t_ns, q, w):
    ours = cdr.StateCodec().encode(t_ns, np.array(q), np.array(w))
    msg = cv.state_to_msg(t_ns, np.array(q), np.array(w))
    assert_wire_equal(ours, msg)
    back = deserialize_message(ours, Odometry)
    o, a = back.pose.pose.orientation, back.twist.twist.angular
    assert bits((o.x, o.y, o.z, o.w, a.x, a.y, a.z)) == bits([*q, *w])
    assert cv.ns_from_stamp(back.header.stamp) == t_ns


@FUZZ
@given(t_ns=T_NS, names=NAMES, data=st.data())
def test_joint_state_bytes_are_the_object_paths(t_ns, names, data):
    n = len(names)
    position, velocity, effort = (data.draw(st.lists(FLOAT, min_size=n, max_size=n)) for _ in range(3))
    codec = cdr.JointStateCodec('wheels/state')
    assert_wire_equal(codec.encode(t_ns, names, position, velocity, effort),
                      cv.wheel_state_to_msg(t_ns, names, position, velocity, effort))
    assert_wire_equal(codec.encode(t_ns, names, effort=effort), cv.wheel_cmd_to_msg(t_ns, names, effort=effort))
    assert_wire_equal(codec.encode(t_ns, names, velocity=velocity), cv.wheel_cmd_to_msg(t_ns, names, velocity=velocity))
    assert_wire_equal(codec.encode(t_ns, names, effort=effort), cv.thruster_cmd_to_msg(t_ns, names, effort))


@FUZZ
@given(t_ns=T_NS, v=VEC3, q=QUAT)
def test_clock_vector_and_transform_bytes_are_the_object_paths(t_ns, v, q):
    from adcs_msgs_py.visual import set_transform, transform_msg
    assert_wire_equal(cdr.ClockCodec().encode(t_ns), cv.clock_msg(t_ns))
    assert_wire_equal(cdr.VectorCodec().encode(t_ns, v), cv.vector_to_msg(t_ns, v))
    assert_wire_equal(cdr.TransformCodec('inertial', 'orbit').encode(t_ns, q),
                      set_transform(transform_msg('inertial', 'orbit'), t_ns, q))


STATUS_VALUE = st.one_of(FLOAT, st.integers(-2**63, 2**63), TEXT, st.booleans(), FLOAT.map(np.float64))


@FUZZ
@given(t_ns=T_NS, name=TEXT, values=st.dictionaries(TEXT, STATUS_VALUE, max_size=20),
       level=st.sampled_from(list(cv.STATUS_LEVELS)), message=TEXT, hardware_id=TEXT)
def test_status_bytes_are_the_object_paths(t_ns, name, values, level, message, hardware_id):
    ours = cdr.status_bytes(t_ns, name, values, level, message, hardware_id)
    msg = cv.status_to_msg(t_ns, name, values, level, message, hardware_id)
    assert_wire_equal(ours, msg)
    assert deserialize_message(ours, type(msg)) == msg


def test_a_nul_in_a_status_string_falls_back_to_the_message():
    assert cdr.status_bytes(0, 'a\x00b', {}) == cv.status_to_msg(0, 'a\x00b', {})


# --- decoding: the fast path against the object path ------------------------------------------

def outcome(convert) -> tuple:
    """What a conversion gives: its values bit for bit, or its InvalidMessage text."""
    try:
        out = convert()
    except InvalidMessage as exc:
        return ('invalid', str(exc))
    return ('ok',) + tuple(bits(v) if isinstance(v, np.ndarray) else v for v in out)


def object_path(data: bytes, msg_type, convert) -> tuple:
    try:
        msg = deserialize_message(data, msg_type)
    except Exception:  # noqa: BLE001 - rmw refuses the bytes: the codec must refuse them too
        return ('undeserializable',)
    return outcome(lambda: convert(msg))


def fast_path(convert) -> tuple:
    try:
        return outcome(convert)
    except Exception as exc:  # noqa: BLE001
        pytest.fail(f'the codec raised {type(exc).__name__}: {exc}')


MUTATION = st.one_of(
    st.tuples(st.just('truncate'), st.integers(0, 800)), st.tuples(st.just('flip'), st.integers(0, 800)),
    st.tuples(st.just('append'), st.binary(min_size=1, max_size=9)), st.tuples(st.just('none'), st.just(0)),
    st.tuples(st.just('length'), st.integers(0, 800)))


def mutate(data: bytes, how) -> bytes:
    kind, arg = how
    if kind == 'truncate':
        return data[:arg % (len(data) + 1)]
    if kind == 'flip':
        i = arg % len(data)
        return data[:i] + bytes([data[i] ^ 0xFF]) + data[i + 1:]
    if kind == 'append':
        return data + arg
    if kind == 'length':   # a uint32 (a string or sequence length, a stamp) made wrong
        i = (arg % (len(data) // 4)) * 4
        return data[:i] + struct.pack('<I', (struct.unpack_from('<I', data, i)[0] + 1 + arg) & 0xFFFFFFFF) + data[i + 4:]
    return data


def same(data: bytes, msg_type, slow, fast) -> None:
    expected = object_path(data, msg_type, slow)
    got = fast_path(fast)
    if expected == ('undeserializable',):
        assert got[0] == 'invalid'
    else:
        assert got == expected


STATE = cdr.StateCodec('state')


@FUZZ
@given(t_ns=T_NS, q=QUAT, w=VEC3, how=MUTATION, rclpy_bytes=st.booleans(), garbage=st.binary(max_size=64))
def test_state_decoding_is_the_object_paths(t_ns, q, w, how, rclpy_bytes, garbage):
    msg = cv.state_to_msg(t_ns, np.array(q), np.array(w))
    msg.pose.covariance[7] = 0.25   # an estimate's covariance: read by nobody, any value passes
    data = serialize_message(msg) if rclpy_bytes else STATE.encode(t_ns, q, w)
    if not rclpy_bytes and how[0] == 'none':
        assert STATE.template.decode(data) is not None   # the encoder's bytes take the fast path
    for raw in (mutate(data, how), garbage):
        same(raw, Odometry, cv.state_from_msg, lambda raw=raw: STATE.decode(raw))


KNOWN = {n: i for i, n in enumerate(WHEELS)}
THRUSTERS = {f'thr_{i}': i - 1 for i in range(1, 5)}
CODECS = {'wheels/cmd': cdr.JointStateCodec('wheels/cmd'), 'thrusters/cmd': cdr.JointStateCodec('thrusters/cmd'),
          'wheels/state': cdr.JointStateCodec('wheels/state')}
CONVERT = {'wheels/cmd': lambda m: cv.wheel_cmd_from_msg(m, KNOWN),
           'thrusters/cmd': lambda m: cv.thruster_cmd_from_msg(m, THRUSTERS),
           'wheels/state': lambda m: cv.wheel_speeds_from_msg(m, WHEELS)}


@FUZZ
@given(t_ns=T_NS, names=NAMES, data=st.data(), how=MUTATION, topic=st.sampled_from(list(CODECS)),
       rclpy_bytes=st.booleans())
def test_joint_state_decoding_is_the_object_paths(t_ns, names, data, how, topic, rclpy_bytes):
    lengths = [data.draw(st.sampled_from([0, len(names), len(names) + 1])) for _ in range(3)]
    position, velocity, effort = (data.draw(st.lists(FLOAT, min_size=n, max_size=n)) for n in lengths)
    msg = JointState(name=names, position=position, velocity=velocity, effort=effort)
    msg.header.stamp = cv.stamp_from_ns(t_ns)
    codec = CODECS[topic]
    raw = serialize_message(msg) if rclpy_bytes else codec.encode(t_ns, names, position, velocity, effort)
    for _ in range(2):   # the second time a learnt layout takes the fast path
        for b in (raw, mutate(raw, how)):
            same(b, JointState, CONVERT[topic], lambda b=b: CONVERT[topic](codec.message(b)))


def test_a_learnt_layout_takes_the_fast_path():
    codec = cdr.JointStateCodec('wheels/cmd')
    data = codec.encode(5, WHEELS, effort=[0.1, -0.0, 5e-324])
    assert isinstance(codec.message(data), JointState)          # first: the object path, layout learnt
    view = codec.message(data)
    assert isinstance(view, cdr.JointStateView)
    assert outcome(lambda: cv.wheel_cmd_from_msg(view, KNOWN)) == \
        outcome(lambda: cv.wheel_cmd_from_msg(deserialize_message(data, JointState), KNOWN))


@FUZZ
@given(t_ns=T_NS, v=VEC3, how=MUTATION)
def test_vector_decoding_is_the_object_paths(t_ns, v, how):
    codec = cdr.VectorCodec('torque_cmd')
    raw = mutate(codec.encode(t_ns, v), how)
    from geometry_msgs.msg import Vector3Stamped
    same(raw, Vector3Stamped, cv.vector_from_msg, lambda: codec.decode(raw))


@FUZZ
@given(t_ns=T_NS, speed=st.lists(st.floats(-1e4, 1e4), min_size=3, max_size=3),
       on_time=st.lists(st.sampled_from([0.0, 0.1, 1.0]), min_size=4, max_size=4))
def test_marker_bytes_are_the_object_paths(t_ns, speed, on_time):
    from adcs_msgs_py.visual import VisualMessages
    visual = VisualMessages([0.0, 0.0, 0.0, 1.0], 1.0, np.eye(3), [0.01] * 3, [100.0] * 3,
                            [[1.0, 0.0, 0.0]] * 4, [[0.0, 1.0, 0.0]] * 4)
    ours = visual.marker_array_cdr(t_ns, speed, on_time)
    assert_wire_equal(ours, visual.marker_array(t_ns, speed, on_time))


@FUZZ
@given(t_ns=T_NS, q=st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4).filter(
    lambda v: 0.1 < math.sqrt(sum(x * x for x in v))))
def test_error_bytes_are_the_object_paths(t_ns, q):
    from adcs_msgs_py.visual import VisualMessages
    visual = VisualMessages([0.0, 0.0, 0.0, 1.0], 1.0)
    q = np.array(q) / math.sqrt(sum(x * x for x in q))
    for ours, msg in zip(visual.errors_cdr(t_ns, q), visual.errors(t_ns, q)):
        assert_wire_equal(ours, msg)
