"""A node's executor waits until something is ready: no empty wake-ups from a matched status.

rmw_fastrtps' ``rmw_wait`` waits on each reader's status condition, which stays triggered while
one of its enabled statuses is changed and unread. The start-up's matched-event wait
(``MatchedWait``) enables "subscription matched" on it for good; a match nobody read afterwards
left it triggered, and rclpy's executor got waits that returned at once with nothing ready,
rebuilt its wait set and waited again: a busy loop for as long as it waited for a message (the
showcase's dynamics node woke 20-60 times a step waiting for the wheel command). AdcsNode gives
each subscription a handler of its matched event (``adcs_msgs_py.node._take_matched``), so the
executor takes the event and the next wait blocks.

The probe counts, for every wait of the executor, whether anything at all was ready (subscription,
guard condition, timer, event): the outcome does not depend on how fast the machine is, only on
whether a wait returned empty.
"""
from __future__ import annotations

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

from adcs_msgs_py import topics
from adcs_msgs_py.blocks import startup_params
from adcs_msgs_py.node import AdcsNode, MatchedWait
from adcs_msgs_py.params import Schema

KINDS = ('subscription', 'guard_condition', 'timer', 'client', 'service')


class Listener(AdcsNode):
    schema = Schema('wake_probe', [*startup_params()], doc='a node with one subscription, for the wait probe')


class Unhandled(Listener):
    take_matched_events = False   # as every AdcsNode was before the matched handler


def counting_wait_set(empty: list[int]):
    """rclpy's WaitSet, counting the waits after which nothing was ready."""
    class Counting(_rclpy.WaitSet):
        def add_event(self, event):
            index = super().add_event(event)
            self.events = [*getattr(self, 'events', []), index]
            return index

        def wait(self, timeout):
            super().wait(timeout)
            ready = any(self.get_ready_entities(k) for k in KINDS) or any(
                self.is_ready('event', i) for i in getattr(self, 'events', []))
            empty[0] += not ready
    return Counting


def empty_wakes(contexts, node_class, monkeypatch) -> int:
    """Empty wake-ups of ``node_class``'s executor over three spins, after a publisher (another
    participant's) on its subscription's topic was matched, and nothing was published."""
    context, other = contexts
    listener = node_class(context)
    talker = rclpy.create_node('talker', context=other)
    try:
        spec = topics.spec(topics.STATE)
        sub = listener.subscription(topics.STATE, lambda msg: None, raw=True)
        # the node's own start-up wait on its subscription (AdcsNode.wait_for), over before the
        # publisher matched: its matched-event handler enabled the status on the reader's condition
        MatchedWait(context, [sub]).destroy()
        pub = talker.create_publisher(spec.msg_type, spec.name, spec.qos)
        waiter = MatchedWait(other, [pub])   # the talker's side: the listener's status stays unread
        try:
            while pub.get_subscription_count() < 1 or sub.get_publisher_count() < 1:
                waiter.wait(1.0)
        finally:
            waiter.destroy()
        empty = [0]
        monkeypatch.setattr(_rclpy, 'WaitSet', counting_wait_set(empty))
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(listener)
        for _ in range(3):
            executor.spin_once(timeout_sec=0.05)
        executor.shutdown()
        return empty[0]
    finally:
        talker.destroy_node()
        listener.destroy_node()


def test_a_matched_publisher_does_not_make_the_executor_spin_empty(two_contexts, monkeypatch):
    assert empty_wakes(two_contexts, Listener, monkeypatch) == 0


def test_pins_rmw_fastrtps_without_the_handler_the_wait_returns_empty(two_contexts, monkeypatch):
    """The cause, pinned: if this fails, rmw_fastrtps resets the status itself and the handler
    (AdcsNode.take_matched_events) may go."""
    assert empty_wakes(two_contexts, Unhandled, monkeypatch) > 0


def test_every_subscription_of_a_node_carries_its_matched_handler(two_contexts):
    node = Listener(two_contexts[0])
    try:
        sub = node.subscription(topics.STATE, lambda msg: None, raw=True)
        assert [h.event_type.name for h in sub.event_handlers] == ['RCL_SUBSCRIPTION_MATCHED']
        assert all(h in list(node.waitables) for h in sub.event_handlers)
        handlers = sub.event_handlers
        node.destroy_subscription(sub)   # as the fault injector drops /clock: its handler leaves too
        assert not any(h in list(node.waitables) for h in handlers)
    finally:
        node.destroy_node()
