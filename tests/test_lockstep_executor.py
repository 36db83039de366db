"""The lockstep nodes' executor (adcs_msgs_py/executor.py): rclpy's semantics, a lean wait.

Against real rclpy endpoints on a leased loopback domain (talker and listener in two contexts, so
two DDS participants as in the graph): messages arrive in order, with the message info when the
callback takes it; a node with anything the lean path does not serve (a timer) is spun by rclpy's
own ``spin_once``; entities added or destroyed between and during spins are followed; callback
exceptions propagate; ``shutdown`` and a shut-down context end the spin as with rclpy.
"""
from __future__ import annotations

import threading

import pytest
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from std_msgs.msg import String

from adcs_msgs_py.executor import LockstepExecutor
from adcs_msgs_py.node import MatchedWait

SPIN_LIMIT = 2000   # spins of <= 1 s each before a test gives up (never reached when it passes)


@pytest.fixture
def graph(two_contexts):
    """(listener node, talker node, executor of the listener) in two contexts on a leased domain."""
    contexts = two_contexts
    # as an AdcsNode: no parameter services (a node with services is spun by rclpy's own path)
    listener = rclpy.create_node('listener', context=contexts[0], start_parameter_services=False,
                                 parameter_overrides=[Parameter('start_type_description_service', value=False)])
    talker = rclpy.create_node('talker', context=contexts[1])
    executor = LockstepExecutor(context=contexts[0])
    executor.add_node(listener)
    yield listener, talker, executor
    executor.shutdown()
    for node in (talker, listener):
        node.destroy_node()


def connect(talker, topic: str, *subs):
    pub = talker.create_publisher(String, topic, 10)
    waiter = MatchedWait(talker.context, [pub])
    try:
        while pub.get_subscription_count() < len(subs) or any(s.get_publisher_count() < 1 for s in subs):
            waiter.wait(1.0)
    finally:
        waiter.destroy()
    return pub


def spin_until(executor, done) -> None:
    for _ in range(SPIN_LIMIT):
        if done():
            return
        executor.spin_once(timeout_sec=1.0)
    raise AssertionError('nothing arrived')


def test_messages_arrive_in_order_with_their_info(graph):
    listener, talker, executor = graph
    got, plain = [], []
    sub = listener.create_subscription(String, 'chatter', lambda m, info: got.append((m.data, info)), 100)
    listener.create_subscription(String, 'chatter', lambda m: plain.append(m.data), 100)
    pub = connect(talker, 'chatter', *listener.subscriptions)
    for i in range(20):
        pub.publish(String(data=str(i)))
    spin_until(executor, lambda: len(got) == 20 and len(plain) == 20)
    assert [d for d, _ in got] == plain == [str(i) for i in range(20)]
    assert all(info['source_timestamp'] > 0 for _, info in got)   # rclpy's message info, as rclpy passes it
    assert executor.lean_spins > 0 and sub.handle is not None


def test_raw_subscription_gets_the_bytes(graph):
    listener, talker, executor = graph
    got = []
    listener.create_subscription(String, 'raw', got.append, 10, raw=True)
    pub = connect(talker, 'raw', *listener.subscriptions)
    pub.publish(String(data='x'))
    spin_until(executor, lambda: got)
    assert got == [serialize_message(String(data='x'))]


def test_a_node_with_a_timer_is_spun_by_rclpy(graph):
    listener, _, executor = graph
    fired = []
    listener.create_timer(0.001, lambda: fired.append(1))
    spin_until(executor, lambda: fired)
    assert executor.lean_spins == 0


def test_entities_added_and_destroyed_between_and_during_spins(graph):
    listener, talker, executor = graph
    first, second = [], []
    sub_a = listener.create_subscription(String, 'a', first.append, 10)
    pub_a = connect(talker, 'a', sub_a)
    pub_a.publish(String(data='1'))
    spin_until(executor, lambda: first)
    sub_b = listener.create_subscription(String, 'b', second.append, 10)   # after the first spins
    pub_b = connect(talker, 'b', sub_b)

    def drop_b(msg):
        second.append(msg)
        listener.destroy_subscription(sub_b)   # destroyed inside its own callback
    sub_b.callback = drop_b
    pub_b.publish(String(data='2'))
    spin_until(executor, lambda: second)
    pub_a.publish(String(data='3'))
    spin_until(executor, lambda: len(first) == 2)
    assert [m.data for m in first] == ['1', '3'] and [m.data for m in second] == ['2']
    assert list(listener.subscriptions) == [sub_a]


def test_a_callback_exception_propagates(graph):
    listener, talker, executor = graph

    def boom(msg):
        raise RuntimeError(f'bad {msg.data}')
    sub = listener.create_subscription(String, 'boom', boom, 10)
    pub = connect(talker, 'boom', sub)
    pub.publish(String(data='m'))
    with pytest.raises(RuntimeError, match='bad m'):
        for _ in range(SPIN_LIMIT):
            executor.spin_once(timeout_sec=1.0)


def test_shutdown_ends_a_wait_and_a_dead_context_raises(graph):
    listener, _, executor = graph
    listener.create_subscription(String, 'quiet', lambda m: None, 10)
    executor.spin_once(timeout_sec=0.0)   # nothing there: returns
    assert executor.lean_spins == 1
    # shut down from another thread, before or during the wait: either way the spin ends
    threading.Thread(target=rclpy.try_shutdown, kwargs={'context': listener.context}).start()
    with pytest.raises(ExternalShutdownException):
        executor.spin_once(timeout_sec=60.0)
    with pytest.raises(ExternalShutdownException):   # rclpy's own spin_once: an RCLError here
        executor.spin_once(timeout_sec=0.0)


def test_executor_shutdown_returns_without_spinning(graph):
    listener, _, executor = graph
    listener.create_subscription(String, 'quiet', lambda m: None, 10)
    executor.shutdown()
    executor.spin_once(timeout_sec=0.0)
    assert executor.lean_spins == 0
