#!/usr/bin/env python3
"""The hot messages' encoding and decoding, three ways in the same run: us per message.

* ``rclpy``: the object path. Encode = the conversion building the rclpy message
  (``state_to_msg``, ...) + ``rclpy.serialization.serialize_message`` (what ``publish`` of an object
  does: the Python -> C conversion and rmw's serialisation); decode = ``deserialize_message`` (what
  ``take_message`` does) + the ``*_from_msg`` validation.
* ``rosbags``: rosbags' CDR (``Typestore.serialize_cdr`` / ``deserialize_cdr``), its message object
  updated in place (its cheapest use), then ``bytes``; decoding validates the rosbags object with the
  same ``*_from_msg`` function.
* ``cdr``: :mod:`adcs_msgs_py.cdr` (templates with the numbers written in; the layout check and one
  ``unpack`` + the same validation).

Each case is timed ``--repeat`` times, the three ways alternated; medians printed with the ratio
to ``cdr``. No ROS graph (no DDS, no domain): serialisation only.

    .venv/bin/python benchmarks/cdr_codec.py [--n 20000] [--repeat 5]
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402

from adcs_msgs_py import cdr  # noqa: E402
from adcs_msgs_py import conversions as cv  # noqa: E402

Q = np.array([0.1, -0.2, 0.3, np.sqrt(1 - 0.14)])
W = np.array([1e-3, -2e-3, 3e-4])
NAMES = ['rw_x', 'rw_y', 'rw_z']
STATUS = {'V': 0.125, 'eta_err': 0.999, 'angle_deg': 3.5, 'sigma_x': 1e-3, 'sigma_y': -2e-3, 'sigma_z': 0.0,
          'mode': 'gsmn', 'phase': 'two_wheel', 'u_x': 0.01, 'u_y': -0.02, 'u_z': 0.0, 'demand_max': 0.02,
          'rejected_messages': 0, 'available_wheels': 'rw_x,rw_y', 'late_faults': 0, 'h_norm': 0.5, 'k': 3}


def rosbags_state():
    """rosbags' encoder of a state: its Odometry made once, the numbers set in place per message."""
    store = cdr.typestore()
    msg = cdr.to_rosbags(cv.state_to_msg(0, Q, W))

    def encode(t_ns, q, w):
        sec, nanosec = divmod(t_ns, cv.NS_PER_S)
        msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
        o, a = msg.pose.pose.orientation, msg.twist.twist.angular
        o.x, o.y, o.z, o.w = (float(v) for v in q)
        a.x, a.y, a.z = (float(v) for v in w)
        return bytes(store.serialize_cdr(msg, 'nav_msgs/msg/Odometry'))
    return encode


def rosbags_joint_state():
    store = cdr.typestore()
    msg = cdr.to_rosbags(cv.wheel_state_to_msg(0, NAMES, Q[:3], W, W))

    def encode(t_ns, names, position, velocity, effort):
        sec, nanosec = divmod(t_ns, cv.NS_PER_S)
        msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
        msg.name = list(names)
        msg.position, msg.velocity, msg.effort = (np.array(v, dtype=float) for v in (position, velocity, effort))
        return bytes(store.serialize_cdr(msg, 'sensor_msgs/msg/JointState'))
    return encode


def rosbags_status():
    store = cdr.typestore()
    types = store.types
    Array, Status, KeyValue = (types[f'diagnostic_msgs/msg/{n}'] for n in ('DiagnosticArray', 'DiagnosticStatus',
                                                                         'KeyValue'))
    header = cdr.to_rosbags(cv.status_to_msg(0, 'x', {})).header

    def encode(t_ns, name, values):
        header.stamp.sec, header.stamp.nanosec = divmod(t_ns, cv.NS_PER_S)
        status = Status(level=0, name=name, message='', hardware_id='',
                        values=[KeyValue(key=k, value=v) for k, v in cv.status_pairs(values)])
        return bytes(store.serialize_cdr(Array(header=header, status=[status]), 'diagnostic_msgs/msg/DiagnosticArray'))
    return encode


def cases():
    """name -> {way: callable}; each call handles one message."""
    store = cdr.typestore()
    state, wheels, clock = cdr.StateCodec(), cdr.JointStateCodec('wheels/state'), cdr.ClockCodec()
    rb_state, rb_wheels, rb_status = rosbags_state(), rosbags_joint_state(), rosbags_status()
    state_bytes = state.encode(1_000_000_000, Q, W)
    wheel_bytes = wheels.encode(7, NAMES, Q[:3], W, W)
    wheels.message(wheel_bytes)   # the layout learnt (the first message of a run)
    odo, js = cv.Odometry, cv.JointState
    return {
        'encode state (Odometry)': {
            'rclpy': lambda: serialize_message(cv.state_to_msg(1_000_000_000, Q, W)),
            'rosbags': lambda: rb_state(1_000_000_000, Q, W), 'cdr': lambda: state.encode(1_000_000_000, Q, W)},
        'encode wheels/state (JointState x3)': {
            'rclpy': lambda: serialize_message(cv.wheel_state_to_msg(7, NAMES, Q[:3], W, W)),
            'rosbags': lambda: rb_wheels(7, NAMES, Q[:3], W, W), 'cdr': lambda: wheels.encode(7, NAMES, Q[:3], W, W)},
        'encode /clock': {
            'rclpy': lambda: serialize_message(cv.clock_msg(7)),
            'rosbags': lambda: bytes(store.serialize_cdr(store.types['rosgraph_msgs/msg/Clock'](
                clock=store.types['builtin_interfaces/msg/Time'](sec=0, nanosec=7)), 'rosgraph_msgs/msg/Clock')),
            'cdr': lambda: clock.encode(7)},
        'encode status (17 key/values)': {
            'rclpy': lambda: serialize_message(cv.status_to_msg(7, 'ctl', STATUS)),
            'rosbags': lambda: rb_status(7, 'ctl', STATUS), 'cdr': lambda: cdr.status_bytes(7, 'ctl', STATUS)},
        'decode + check state': {
            'rclpy': lambda: cv.state_from_msg(deserialize_message(state_bytes, odo)),
            'rosbags': lambda: cv.state_from_msg(store.deserialize_cdr(state_bytes, 'nav_msgs/msg/Odometry')),
            'cdr': lambda: state.decode(state_bytes)},
        'decode + check wheels/state': {
            'rclpy': lambda: cv.wheel_speeds_from_msg(deserialize_message(wheel_bytes, js), NAMES),
            'rosbags': lambda: cv.wheel_speeds_from_msg(store.deserialize_cdr(wheel_bytes, 'sensor_msgs/msg/JointState'),
                                                        NAMES),
            'cdr': lambda: cv.wheel_speeds_from_msg(wheels.message(wheel_bytes), NAMES)},
    }


def per_message_us(fn, n: int) -> float:
    t0 = time.perf_counter()
    for _ in range(n):
        fn()
    return (time.perf_counter() - t0) / n * 1e6


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--n', type=int, default=20000, help='messages per timing')
    ap.add_argument('--repeat', type=int, default=5, help='alternated timings per way (median)')
    args = ap.parse_args()
    table = cases()
    print(f'us per message (median of {args.repeat}, {args.n} messages each; ways alternated)')
    print(f'{"":38s} {"rclpy":>8s} {"rosbags":>8s} {"cdr":>8s}   rclpy/cdr  rosbags/cdr')
    for name, ways in table.items():
        times = {w: [] for w in ways}
        for _ in range(args.repeat):
            for way, fn in ways.items():
                times[way].append(per_message_us(fn, args.n))
        med = {w: statistics.median(t) for w, t in times.items()}
        print(f'{name:38s} {med["rclpy"]:8.2f} {med["rosbags"]:8.2f} {med["cdr"]:8.2f}   '
              f'{med["rclpy"] / med["cdr"]:8.1f}x {med["rosbags"] / med["cdr"]:10.1f}x', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
