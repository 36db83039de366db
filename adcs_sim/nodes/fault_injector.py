"""Fault injector node: publishes the scenario's actuator fault schedule on ``faults``.

At start it publishes the **whole schedule** on the latched (transient local, depth 100)
``faults`` topic: first the all-nominal state stamped 0, then one ``DiagnosticArray`` per
distinct event time, stamped with that (simulated) time, holding one status per wheel (name =
wheel, level ERROR for failed / degraded / bias / stuck and OK for nominal / recovered, message =
mode, key/values ``mode``, ``value``, ``time``, ``event``, ``events``). The nodes that act on
faults apply each array when their step time reaches its stamp (:mod:`adcs_core.faults`), so a
fault stamped ``t_k`` holds over exactly ``[t_k, t_k+1]`` however fast the lockstep loop runs:
publishing "when the time comes" would race the loop. The node then follows ``/clock`` only to
log each event when it becomes due (and drops its ``/clock`` subscription once the last one is
logged: no wake-up at every step for the rest of the run), and spins until it is stopped.

With ``startup.expect_recorder`` (set by the runner) it publishes the schedule only once the
recorder's subscription is matched, then waits until every matched reader acknowledged it. The
dynamics node and the controllers wait for the complete schedule before t = 0
(``startup.expect_faults``), so the lockstep loop cannot start, and a short run cannot end, before
the recorder holds the schedule: transient local history alone reaches a late reader only once its
participant is discovered, which on a loaded machine could come after the last step (a bag with
the torques of a fault but not the fault).
"""
from __future__ import annotations

from adcs_core.faults import FAULT_OK_MODES
from adcs_msgs_py import conversions as cv
from adcs_msgs_py import topics
from adcs_msgs_py.guard import subscribed_by
from adcs_msgs_py.node import AdcsNode, entry_point
from adcs_sim.bag.schema import RECORDER_SCHEMA
from adcs_sim.truth.fault_schedule import FAULT_SCHEMA, fault_schedule


class FaultInjectorNode(AdcsNode):
    schema = FAULT_SCHEMA

    def __init__(self, context) -> None:
        super().__init__(context)
        self.schedule = fault_schedule(self.params)
        self.pub_faults = self.publisher(topics.FAULTS)
        self._logged = 0  # snapshots already announced as due
        # /clock only until the last event is announced (then dropped: the lockstep loop runs on a
        # machine shared by every node, and a process woken at every step costs each step CPU)
        self.sub_clock = self.subscription(topics.CLOCK, self._on_clock) if len(self.schedule) > 1 else None
        if not self.params['startup.expect_recorder']:
            self.publish_schedule()

    def publish_schedule(self) -> None:
        n = len(self.schedule)
        for i, (t_ns, snapshot) in enumerate(self.schedule):
            self.pub_faults.publish(cv.faults_to_msg(t_ns, snapshot, i, n))
        self.get_logger().info(f'published the fault schedule: {n - 1} event time(s)')

    def _on_clock(self, msg) -> None:
        t_ns = self.rejects.accept(topics.CLOCK, lambda: cv.clock_from_msg(msg))
        if t_ns is None:
            return
        while self._logged + 1 < len(self.schedule) and self.schedule[self._logged + 1][0] <= t_ns:
            self._logged += 1
            due_ns, snapshot = self.schedule[self._logged]
            faulty = {w: s.mode for w, s in snapshot.items() if s.mode not in FAULT_OK_MODES}
            self.get_logger().info(f't = {due_ns / cv.NS_PER_S:g} s: faults now {faulty or "none"}')
        if self._logged + 1 == len(self.schedule) and self.sub_clock is not None:
            self.destroy_subscription(self.sub_clock)   # every event announced: nothing left to follow
            self.sub_clock = None

    def _recorder_matched(self) -> bool:
        """The recorder subscribes to ``faults`` and this writer is matched with every
        subscription the graph lists (the recorder's among them)."""
        return subscribed_by(self, self.pub_faults, RECORDER_SCHEMA.node)

    def publish_once_recorded(self) -> None:
        """Wait until the recorder's subscription is matched, publish the schedule, wait until
        every matched reader acknowledged it (``startup.timeout`` each; GraphTimeout)."""
        timeout = self.params['startup.timeout']
        self.wait_for(f'the recorder subscribing to {self.pub_faults.topic_name}',
                      self._recorder_matched, timeout, endpoints=[self.pub_faults])
        self.publish_schedule()
        self.wait_acked([self.pub_faults], timeout)

    def run(self, executor) -> None:
        # Without a recorder to wait for the schedule went out at construction: the topic is
        # transient local, so the dynamics node and the controllers receive it whenever they join.
        if self.params['startup.expect_recorder']:
            self.publish_once_recorded()
        executor.spin()


main = entry_point(FaultInjectorNode)

if __name__ == '__main__':
    main()
