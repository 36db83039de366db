"""What rmw puts on the wire for the object path's messages is what adcs_msgs_py.cdr encodes.

rclpy's ``serialize_message`` leaves the alignment padding uninitialised (and over-allocates the
tail); what a subscriber receives raw from a publisher of the message object is the exact length
with zero padding. One publisher per hot message type, a raw subscription in the same process
(loopback, leased domain): each message the object path publishes arrives as the codec's bytes.
"""
from __future__ import annotations

import numpy as np
import pytest
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor

from adcs_msgs_py import cdr, topics
from adcs_msgs_py import conversions as cv
from adcs_sim.app.graph.domains import DomainLease

Q = np.array([0.1, -0.2, 0.3, np.sqrt(1 - 0.14)])
W = np.array([1e-3, -0.0, 5e-324])
NAMES = ['rw_x', 'rw_y', 'rw_z']
STATUS = {'step': 7, 'u_x': 0.0125, 'h': np.float64(-2.5e-7), 'mode': 'lockstep', 'final': 'false',
          'available_wheels': 'rw_x,rw_y'}
CASES = [   # topic, the object path's message, the codec's bytes
    (topics.STATE, cv.state_to_msg(1_500_000_001, Q, W), cdr.StateCodec().encode(1_500_000_001, Q, W)),
    (topics.CLOCK, cv.clock_msg(42), cdr.ClockCodec().encode(42)),
    (topics.WHEELS_STATE, cv.wheel_state_to_msg(3, NAMES, [1.0, 2.0, 3.0], W, Q[:3]),
     cdr.JointStateCodec('wheels/state').encode(3, NAMES, [1.0, 2.0, 3.0], W, Q[:3])),
    (topics.WHEELS_CMD, cv.wheel_cmd_to_msg(3, NAMES[:2], effort=[0.01, -0.02]),
     cdr.JointStateCodec('wheels/cmd').encode(3, NAMES[:2], effort=[0.01, -0.02])),
    (topics.APPLIED_TORQUE, cv.vector_to_msg(9, W), cdr.VectorCodec().encode(9, W)),
    (topics.CONTROLLER_STATUS, cv.status_to_msg(5, 'snlc', STATUS), cdr.status_bytes(5, 'snlc', STATUS)),
    (topics.DYNAMICS_STATUS, cv.status_to_msg(5, 'dyn', {'odd': 'x'}, 'WARN'),
     cdr.status_bytes(5, 'dyn', {'odd': 'x'}, 'WARN')),
]


@pytest.fixture(scope='module')
def node():
    lease = DomainLease(100, 232)
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
        mp.setenv('ROS_DOMAIN_ID', str(lease.domain_id))
        context = Context()
        rclpy.init(context=context)
        n = rclpy.create_node('cdr_wire', context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(n)
        try:
            yield n, executor
        finally:
            n.destroy_node()
            rclpy.try_shutdown(context=context)
            lease.release()


@pytest.mark.graph
@pytest.mark.parametrize('topic, msg, ours', CASES, ids=[c[0] for c in CASES])
def test_the_wire_bytes_of_the_object_path_are_the_codecs(node, topic, msg, ours):
    n, executor = node
    spec = topics.spec(topic)
    got = []
    pub = n.create_publisher(spec.msg_type, topic, spec.qos)
    sub = n.create_subscription(spec.msg_type, topic, got.append, topics.subscriber_qos(spec.qos), raw=True)
    for _ in range(200):   # matching: spun, not slept; bounded
        if pub.get_subscription_count():
            break
        executor.spin_once(timeout_sec=0.05)
    pub.publish(msg)
    for _ in range(200):
        if got:
            break
        executor.spin_once(timeout_sec=0.05)
    n.destroy_subscription(sub)
    n.destroy_publisher(pub)
    assert got == [ours]
