"""The executor of the lockstep nodes: rclpy's single-threaded executor with a lean ``spin_once``.

rclpy's ``SingleThreadedExecutor.spin_once`` rebuilds its wait set in Python at every call: every
entity entered as a context manager, counted, a new ``WaitSet`` allocated, a timer created for the
timeout, a generator walked, a task made to run the callback. A lockstep node spins once or twice
a step, each spin one message, so that rebuild is a large part of its step. :class:`LockstepExecutor`
keeps one rcl wait set per set of entities and, at each spin, clears it, adds the same handles,
waits (the timeout passed to rcl, no timer), then takes every ready message and calls its
callback directly, with the message info when the callback takes two arguments, as rclpy does.

It serves what the graph's nodes have: subscriptions, and matched-event handlers
(:func:`adcs_msgs_py.node._take_matched`). A node with anything else (timers, services, clients,
its own guard conditions, other waitables) is spun by rclpy's own ``spin_once``, as before, so the
behaviour never depends on which path runs; SIGINT and the executor's wake-up guard condition are
in the wait set, so Ctrl-C and ``shutdown`` end a wait as with rclpy. Exceptions from callbacks
propagate out of ``spin_once`` as with rclpy.
"""
from __future__ import annotations

from rclpy.event_handler import EventHandler
from rclpy.exceptions import InvalidHandle
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.subscription import Subscription
from rclpy.utilities import timeout_sec_to_nsec


class LockstepExecutor(SingleThreadedExecutor):
    """``SingleThreadedExecutor`` whose ``spin_once`` waits on a kept rcl wait set (module doc)."""

    def __init__(self, *, context=None) -> None:
        super().__init__(context=context)
        self._layout: tuple | None = None   # (key, wait set, subscriptions, event handlers)
        self.lean_spins = 0                  # spins served by the lean path (tests)

    def _lean_layout(self):
        """``(wait set, subscriptions, event handlers)`` for the nodes' entities now, or None when a
        node has something the lean path does not serve."""
        subs, events = [], []
        for node in self.get_nodes():
            if node._timers or node._clients or node._services or node._guards:
                return None
            subs.extend(node._subscriptions)
            for w in node.waitables:
                if type(w) is not EventHandler:
                    return None
                events.append(w)
        key = (tuple(map(id, subs)), tuple(map(id, events)))
        if self._layout is None or self._layout[0] != key:
            wait_set = _rclpy.WaitSet(len(subs), 2, 0, 0, 0, len(events), self._context.handle)
            self._layout = (key, wait_set, subs, events)
        return self._layout[1:]

    def spin_once(self, timeout_sec: float | None = None) -> None:
        layout = self._lean_layout() if not self._is_shutdown else None
        if layout is None:
            super().spin_once(timeout_sec)
            return
        wait_set, subs, events = layout
        if not self._context.ok():
            raise ExternalShutdownException()
        self.lean_spins += 1
        with self._context.handle:
            wait_set.clear_entities()
            for sub in subs:
                wait_set.add_subscription(sub.handle)
            wait_set.add_guard_condition(self._guard.handle)
            wait_set.add_guard_condition(self._sigint_gc.handle)
            for handler in events:
                handler.add_to_wait_set(wait_set)
            wait_set.wait(-1 if timeout_sec is None else timeout_sec_to_nsec(timeout_sec))
        if self._is_shutdown:
            return
        if not self._context.ok():
            raise ExternalShutdownException()
        ready = wait_set.get_ready_entities('subscription')
        ready_events = [h for h in events if h.is_ready(wait_set)]
        for sub in subs:
            if sub.handle.pointer in ready:
                self._deliver(sub)
        for handler in ready_events:
            data = handler.take_data()
            if data:
                handler.callback(data)

    @staticmethod
    def _deliver(sub: Subscription) -> None:
        """Take one message of ``sub`` and call its callback (as rclpy's ``_take_subscription``)."""
        try:
            with sub.handle:
                taken = sub.handle.take_message(sub.msg_type, sub.raw)
        except InvalidHandle:   # destroyed by an earlier callback of this spin
            return
        if taken is None:
            return
        if sub._callback_type is Subscription.CallbackType.MessageOnly:
            sub.callback(taken[0])
        else:
            sub.callback(*taken)
