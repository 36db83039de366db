"""Nodes of the graph in the test's process (:class:`InProcessGraph`) and the lockstep runs built on
it; whether a message conversion refuses its input (:func:`refused`).

Importing this module needs no ROS: rclpy, the nodes and the message conversions are imported by
the functions that use them, so a module of pure tests may import it (its graph tests are marked
``graph`` through the ``ros_domain`` fixture they use).
"""
from __future__ import annotations

import time
from pathlib import Path

from support.scenarios import make_scenario


def spin_until(executor, condition, timeout: float = 30.0, what: str = 'the expected messages') -> None:
    """Spin until ``condition()``; the deadline only turns a hang into a failure."""
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, f'graph did not deliver {what} within {timeout} s'
        executor.spin_once(timeout_sec=0.1)


def refused(convert) -> bool:
    """Whether ``convert()`` (a message conversion of the interface) refuses its input
    (InvalidMessage): what a fuzzed node must then have counted instead of applied."""
    from adcs_msgs_py.conversions import InvalidMessage
    try:
        convert()
    except InvalidMessage:
        return True
    return False


class InProcessGraph:
    """Nodes of the graph in this process, on a private context, one executor.

    ``graph.add(NodeClass)`` builds an adcs_sim node from the scenario's parameters;
    ``graph.plain(name)`` a bare rclpy node for test publishers/subscribers. Everything is
    destroyed and the context shut down on exit.
    """

    def __init__(self, scenario: Path) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        self.rclpy = rclpy
        self.context = Context()
        rclpy.init(args=['--ros-args', '--params-file', str(scenario)], context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.nodes = []

    def add(self, node_class):
        return self._register(node_class(self.context))

    def plain(self, name: str):
        return self._register(self.rclpy.create_node(name, context=self.context))

    def _register(self, node):
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    def spin_until(self, condition, timeout: float = 30.0, what: str = 'the expected messages') -> None:
        spin_until(self.executor, condition, timeout, what)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        close_graph(self.rclpy, self.context, self.executor, self.nodes)


def close_graph(rclpy, context, executor=None, nodes=()) -> None:
    """Take a graph of this process down for good: its nodes out of the executor and destroyed, the
    executor shut down, the context shut down AND destroyed. A node still held by an executor is
    destroyed only when that lets go of it, and a context's DDS participant lives until the context
    is destroyed (rclpy: shutdown alone keeps it): a later graph of the same test on the same domain
    then met the earlier recorder's readers, which nobody takes from any more. Once full they
    acknowledged nothing, and every step of the later run waited out its 5 s acknowledgement wait
    (seen: test_measurement_noise_is_seeded_and_truth_is_recorded's second run at step ~300)."""
    for node in reversed(list(nodes)):
        if executor is not None:
            executor.remove_node(node)
        node.destroy_node()
    if executor is not None:
        executor.shutdown()
    rclpy.try_shutdown(context=context)
    context.destroy()


def record_pd_loop(tmp_path: Path, n: int, dynamics: dict | None = None, extra_counts: dict | None = None):
    """Dynamics + PD controller + recorder in this process, lockstep, ``n`` steps of the PD slew
    (``dynamics`` overrides its section); waits until the recorder has every message of the run.

    Returns ``(bag folder, dynamics node)``; ``extra_counts`` ({topic: count}) adds topics to wait for.
    """
    from adcs_controllers.nodes.pd_controller import PdController
    from adcs_sim.nodes.dynamics import DynamicsNode
    from adcs_sim.nodes.recorder import RecorderNode

    bag_dir = tmp_path / 'bag'
    scenario = make_scenario(tmp_path, {
        'dynamics': {'duration': float(n), 'startup.expect_recorder': True, **(dynamics or {})},
        'pd_controller': {'startup.expect_recorder': True},
        'recorder': {'output': str(bag_dir)}})
    expected = {'/state': n + 1, '/controller/status': n + 1, '/wheels/cmd': n + 1,
                '/dynamics/status': 2, **(extra_counts or {})}
    with InProcessGraph(scenario) as graph:
        rec = graph.add(RecorderNode)
        dyn = graph.add(DynamicsNode)
        pd = graph.add(PdController)
        pd.connect(graph.executor)
        dyn.run(graph.executor)
        counts = rec.bag.topics
        graph.spin_until(lambda: all(counts[t].count == c for t, c in expected.items()))
        rec.close()
    return bag_dir, dyn


def record_sensor_graph(scenario: Path, expected: dict):
    """Recorder + fault injector + dynamics in this process (free flight, no controller), the run of
    ``scenario`` (its recorder section names the bag); waits until the recorder has ``expected``
    ({topic: message count}). Returns the dynamics node."""
    from adcs_sim.nodes.dynamics import DynamicsNode
    from adcs_sim.nodes.fault_injector import FaultInjectorNode
    from adcs_sim.nodes.recorder import RecorderNode
    with InProcessGraph(scenario) as graph:
        rec = graph.add(RecorderNode)
        graph.add(FaultInjectorNode)
        dyn = graph.add(DynamicsNode)
        dyn.run(graph.executor)
        counts = rec.bag.topics
        graph.spin_until(lambda: all(t in counts and counts[t].count == c for t, c in expected.items()))
        rec.close()
    return dyn


def run_lockstep_graph(scenario: Path, controller_class, expected: dict, faults: bool = False,
                       timeout: float = 120.0):
    """Recorder (+ fault injector when ``faults``) + dynamics + ``controller_class`` in this
    process, lockstep, the run of ``scenario`` (its recorder section names the bag); with
    ``faults`` the controller collects the fault schedule first. Waits until the recorder has
    ``expected`` ({topic: message count}). Returns ``(dynamics node, controller node)``."""
    from adcs_sim.nodes.dynamics import DynamicsNode
    from adcs_sim.nodes.fault_injector import FaultInjectorNode
    from adcs_sim.nodes.recorder import RecorderNode
    with InProcessGraph(scenario) as graph:
        rec = graph.add(RecorderNode)
        if faults:
            injector = graph.add(FaultInjectorNode)
            if injector.params['startup.expect_recorder']:   # what its run() does first, under the runner
                injector.publish_once_recorded()
        dyn = graph.add(DynamicsNode)
        ctrl = graph.add(controller_class)
        if faults:
            ctrl.wait_for_faults(graph.executor)
        ctrl.connect(graph.executor)
        dyn.run(graph.executor)
        counts = rec.bag.topics
        graph.spin_until(lambda: all(t in counts and counts[t].count == c for t, c in expected.items()),
                         timeout=timeout, what=f'{expected}')
        rec.close()
    return dyn, ctrl


def run_fault_graph(scenario: Path, controller_class, n: int, timeout: float = 120.0):
    """:func:`run_lockstep_graph` with the fault injector, ``n`` steps of a wheel controller."""
    expected = {'/state': n + 1, '/controller/status': n + 1, '/wheels/cmd': n + 1,
                '/wheels/state': n + 1, '/dynamics/status': 2, '/faults': 2}
    return run_lockstep_graph(scenario, controller_class, expected, faults=True, timeout=timeout)
