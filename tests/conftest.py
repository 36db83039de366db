"""Shared fixtures: every ROS test runs on its own domain id, loopback discovery only."""
from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

import pytest

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from adcs_sim.app.domains import DomainLease  # noqa: E402
from adcs_sim.truth.plant import Plant  # noqa: E402

# Tests use UDP only: a killed Fast DDS process would otherwise leave shared-memory files.
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ['FASTDDS_BUILTIN_TRANSPORTS'] = 'UDPv4'
from adcs_msgs_py.node import network_hygiene_defaults  # noqa: E402

network_hygiene_defaults()  # the same Fast DDS profile as the nodes, for in-process graphs
CONFIG = ROOT / 'config'


def pytest_sessionstart(session):
    """Load the compiled plant kernel (on a fresh clone: compile it into its cache, once) before
    any test starts a node, so no graph test's start-up time includes a compilation."""
    Plant(np.eye(3))


@pytest.fixture
def ros_domain(monkeypatch):
    """A leased ROS_DOMAIN_ID (in 100..232, away from the runner's default range), set in os.environ.

    Yields the lease; ``lease.env()`` is the environment for subprocesses of the test.
    """
    lease = DomainLease(100, 232)
    monkeypatch.setenv('ROS_DOMAIN_ID', str(lease.domain_id))
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    try:
        yield lease
    finally:
        lease.release()


def make_scenario(tmp_path: Path, overrides: dict | None = None, base: str = 'microsat_pd_slew.yaml',
                  drop: tuple[str, ...] = ()) -> Path:
    """Copy of a config/ scenario with ``overrides`` ({section: {dotted.name: value}}) applied.

    A value of None deletes the parameter; sections named in ``drop`` are removed.
    """
    import yaml
    tree = yaml.safe_load((CONFIG / base).read_text())
    for section in drop:
        tree.pop(section, None)
    for section, params in (overrides or {}).items():
        node = tree.setdefault(section, {'ros__parameters': {}})['ros__parameters']
        for dotted, value in params.items():
            *parents, leaf = dotted.split('.')
            d = node
            for p in parents:
                d = d.setdefault(p, {})
            if value is None:
                d.pop(leaf, None)
            else:
                d[leaf] = value
    path = tmp_path / f'scenario_{len(list(tmp_path.glob("scenario_*.yaml")))}.yaml'
    path.write_text(yaml.safe_dump(tree, sort_keys=False))
    return path


def spin_until(executor, condition, timeout: float = 30.0, what: str = 'the expected messages') -> None:
    """Spin until ``condition()``; the deadline only turns a hang into a failure."""
    import time
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, f'graph did not deliver {what} within {timeout} s'
        executor.spin_once(timeout_sec=0.1)


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
        for node in reversed(self.nodes):
            node.destroy_node()
        self.rclpy.try_shutdown(context=self.context)


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
        pd.connect()
        dyn.run(graph.executor)
        counts = rec.bag.topics
        graph.spin_until(lambda: all(counts[t].count == c for t, c in expected.items()))
        rec.close()
    return bag_dir, dyn


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
            graph.add(FaultInjectorNode)
        dyn = graph.add(DynamicsNode)
        ctrl = graph.add(controller_class)
        if faults:
            ctrl.wait_for_faults(graph.executor)
        ctrl.connect()
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


def plain_message(value):
    """A deserialised message as nested tuples (numpy arrays as dtype + bytes), comparable with
    ==: message content, not CDR bytes (Fast DDS leaves a serialised message's alignment padding
    uninitialised, so equal messages can differ there)."""
    if hasattr(value, '__dataclass_fields__'):
        return tuple(plain_message(getattr(value, f)) for f in value.__dataclass_fields__)
    if isinstance(value, np.ndarray):
        return (value.dtype.str, value.tobytes())
    if isinstance(value, (list, tuple)):
        return tuple(plain_message(v) for v in value)
    return value
