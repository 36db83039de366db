"""The recorder tests' publisher side: an rclpy node on a private context, the state messages they
publish (content a function of k), checks of what a bag holds, and polls with a deadline.
Needs rclpy."""
from __future__ import annotations

import math
import time
from contextlib import contextmanager

import numpy as np
import pytest
import rclpy
from rclpy.duration import Duration

from adcs_msgs_py.conversions import NS_PER_S
from adcs_sim.bag.reader import read_raw
from adcs_sim.bag.storage import typestore

STEP_NS = NS_PER_S // 10            # t_k = k * 0.1 s
STATE_TOPIC = '/state'              # the recorder runs in the root namespace
DEADLINE = 30.0                     # wall seconds for any single graph/DDS event
ACK_TIMEOUT = Duration(seconds=10)


def until(what: str, condition, timeout: float = DEADLINE):
    """Poll an observable condition until it holds (returns its value) or fail after ``timeout``."""
    deadline = time.monotonic() + timeout
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() > deadline:
            pytest.fail(f'timed out after {timeout:g} s waiting for {what}')


def state_values(k: int) -> tuple[np.ndarray, np.ndarray]:
    """Attitude (rotation 0.01 k rad about z) and body rate of message k: content to check."""
    a = 0.01 * k
    return np.array([0.0, 0.0, math.sin(a / 2), math.cos(a / 2)]), np.array([1e-3 * k, -2e-3 * k, 0.5])


def check_state(k: int, stamp_ns: int, q_xyzw, w_xyz) -> None:
    assert stamp_ns == k * STEP_NS
    q, w = state_values(k)
    assert list(q_xyzw) == list(q)      # float64 round trip: bit for bit
    assert list(w_xyz) == list(w)


@contextmanager
def ros_node(name: str):
    """An rclpy node on a private context (the domain id comes from the ros_domain fixture)."""
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    node = None
    try:
        node = rclpy.create_node(name, context=ctx)
        yield node
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown(context=ctx)


def odom_fields(msg):
    o, a = msg.pose.pose.orientation, msg.twist.twist.angular
    return (msg.header.stamp.sec * NS_PER_S + msg.header.stamp.nanosec,
            (o.x, o.y, o.z, o.w), (a.x, a.y, a.z))


def raw_states(bag) -> list[tuple]:
    store = typestore()
    out = []
    for topic, type_name, t, data in read_raw(bag):
        if topic == STATE_TOPIC:
            assert type_name == 'nav_msgs/msg/Odometry'
            stamp, q, w = odom_fields(store.deserialize_cdr(data, type_name))
            out.append((stamp, t, q, w))
    return out
