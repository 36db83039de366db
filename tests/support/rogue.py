"""A rogue on the run's domain, and a fake graph for the publisher vetting: shared by the intruder
tests (tests/test_intruders.py, tests/test_edge_identity.py).

* :class:`FakeGraph` / :class:`FakeSub`: what :class:`adcs_msgs_py.guard.PublisherVetting` asks of a
  node and of a subscription, without DDS.
* :func:`run_with_rogue`: ``adcs-run`` of the PD slew with a participant of this process publishing
  on one of its topics (under its own name, a node name of the run, or another type).
* :func:`first_unclean_step`: where the applied torque recorded stops being the clean run's.
"""
from __future__ import annotations

import signal
import subprocess
import sys
import time
from types import SimpleNamespace

import numpy as np

from adcs_msgs_py import conversions as cv
from adcs_msgs_py import topics
from adcs_msgs_py.guard import subscribed_by
from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.scenario.files import validate_scenario
from adcs_sim.bag.reader import read_messages
from support.paths import ROOT

PD_SLEW = ROOT / 'config/microsat_pd_slew.yaml'


class FakeGraph:
    """What PublisherVetting asks of a node: namespace, name resolution, publishers of a topic, nodes."""

    def __init__(self) -> None:
        self.publishers: dict[str, list] = {}
        self.nodes: list[tuple[str, str]] = []   # (name, namespace) of nodes without a publisher

    def get_namespace(self) -> str:
        return '/'

    def resolve_topic_name(self, name: str) -> str:
        return name if name.startswith('/') else '/' + name

    def get_publishers_info_by_topic(self, topic: str):
        return list(self.publishers.get(topic, []))

    def get_node_names_and_namespaces(self) -> list[tuple[str, str]]:
        """One entry per node (a name twice: two nodes of that name), as rclpy lists them."""
        seen = {(i.node_name, i.node_namespace, i.participant)
                for infos in self.publishers.values() for i in infos}
        return [(name, ns) for name, ns, _ in sorted(seen)] + list(self.nodes)

    def add(self, topic: str, node: str, gid: int, type_name: str | None = None,
            participant: int | None = None) -> None:
        """A publisher of ``node`` (of the process ``participant``, one per GID unless given) on
        ``topic``, of the topic's own type unless ``type_name``."""
        spec = topics.TOPICS.get(topic) or topics.TOPICS.get(topic.lstrip('/'))
        self.publishers.setdefault(topic, []).append(SimpleNamespace(
            node_name=node, node_namespace='/', endpoint_gid=[gid] * 16,
            topic_type=type_name or (spec.type_name if spec else 'std_msgs/msg/String'),
            participant=gid if participant is None else participant))

    def remove(self, topic: str, gid: int) -> None:
        """The publisher of GID ``gid`` left the graph (its process stopped)."""
        self.publishers[topic] = [i for i in self.publishers[topic] if i.endpoint_gid != [gid] * 16]


class FakeSub:
    def __init__(self, graph: FakeGraph, topic: str) -> None:
        self.graph, self.topic_name = graph, topic

    def get_publisher_count(self) -> int:
        """Matched publishers: those of the topic's type (another type never matches)."""
        spec = topics.TOPICS.get(self.topic_name) or topics.TOPICS.get(self.topic_name.lstrip('/'))
        return sum(spec is None or i.topic_type == spec.type_name
                   for i in self.graph.publishers.get(self.topic_name, []))


# --- the rogue publisher ---------------------------------------------------------------------------

MAX_TORQUE = 0.01   # microsat_pd_slew's wheel torque limit (N m)
DURATION_S = 20000  # lockstep runs steps in milliseconds: long enough never to end before the rogue
RUN_LIMIT_S = 240   # wall seconds: the run ends at the detection; this only turns a miss into a failure
# interrupt_after counts only the rogue's messages sent once the run is past this step time: the
# dynamics node has then waited for the recorder's acknowledgement of every step up to
# ACK_INTERVAL, so those steps are in the bag however the interrupt falls
INTERRUPT_PAST_NS = (topics.ACK_INTERVAL + 1) * cv.NS_PER_S


def rogue_message(topic: str, t_ns: int, msg_type=None):
    """What the rogue publishes on ``topic`` at step ``t_ns`` (of ``msg_type``, when not the topic's)."""
    if msg_type is not None:
        return msg_type()
    if topic == topics.APPLIED_TORQUE:
        return cv.vector_to_msg(t_ns, [123.0, 456.0, 789.0])
    if topic == topics.WHEELS_CMD:
        return cv.wheel_cmd_to_msg(t_ns, ['rw_x', 'rw_y', 'rw_z'], effort=[MAX_TORQUE] * 3)
    if topic == topics.STATE:
        return cv.state_to_msg(t_ns, [0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0])
    from adcs_core.faults import FaultState
    return cv.faults_to_msg(0, {w: FaultState('failed') for w in ('rw_x', 'rw_y', 'rw_z')}, 0, 1)


def run_with_rogue(tmp_path, monkeypatch, topic: str, start_s: float = 2.0, duration_s: float = DURATION_S,
                   interrupt_after: int = 0, name: str = 'rogue', msg_type=None):
    """adcs-run of the PD slew (long enough never to end first: DURATION_S) and, once its clock passes
    ``start_s``, a rogue node in this process publishing on ``topic`` for every state.
    ``interrupt_after`` > 0: once the run is past INTERRUPT_PAST_NS and the recorder, matched with the
    rogue, has acknowledged that many more of its messages, SIGINT the runner (a topic nobody
    applies: nothing else ends the run early, and no wall-clock race decides whether the recorder
    saw the rogue). ``name``: the node that publishes (another than ``rogue``, which subscribes: a
    node of that name joins the graph with the publisher); ``msg_type``: a type other than the
    topic's (its default message). Returns ``(exit status, stderr, output folder)``."""
    import rclpy
    from nav_msgs.msg import Odometry
    from rclpy.context import Context
    from rclpy.duration import Duration
    from rclpy.executors import SingleThreadedExecutor
    from rosgraph_msgs.msg import Clock

    out = tmp_path / 'run'
    runner = subprocess.Popen([sys.executable, '-m', 'adcs_sim.app.graph.runner', str(PD_SLEW),
                               '--out', str(out), '--duration', str(duration_s), '--no-progress'],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    try:
        line = ''
        while 'ROS_DOMAIN_ID=' not in line:
            line = runner.stdout.readline()
            assert line, runner.communicate()[1]
        monkeypatch.setenv('ROS_DOMAIN_ID', line.split('ROS_DOMAIN_ID=')[1].split(',')[0])
        monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
        context = Context()
        rclpy.init(context=context)
        try:
            node = rclpy.create_node('rogue', context=context)
            executor = SingleThreadedExecutor(context=context)
            executor.add_node(node)
            rogue = {}

            def publisher():
                """The rogue's publisher (with its node, when it has a name of its own)."""
                owner = node
                if name != 'rogue':
                    owner = rogue['node'] = rclpy.create_node(name, context=context)
                    executor.add_node(owner)
                s = topics.spec(topic)
                return owner.create_publisher(msg_type or s.msg_type, s.name, s.qos)

            if start_s <= 0:   # there before the run's nodes
                rogue['pub'] = publisher()

            def on_clock(msg):
                t_ns = cv.ns_from_stamp(msg.clock)
                if t_ns >= start_s * cv.NS_PER_S and 'pub' not in rogue:
                    rogue['pub'] = publisher()
                    if topic == topics.FAULTS:
                        rogue['pub'].publish(rogue_message(topic, 0, msg_type))
                elif 'pub' in rogue and topic == topics.STATE:   # a spoofed state every step
                    rogue['pub'].publish(rogue_message(topic, t_ns, msg_type))

            def on_state(msg):   # a maximum-torque command (or a record) answering every state, stamped with it
                rogue['t_ns'] = cv.ns_from_stamp(msg.header.stamp)
                if 'pub' in rogue and topic in (topics.WHEELS_CMD, topics.APPLIED_TORQUE):
                    rogue['pub'].publish(rogue_message(topic, rogue['t_ns'], msg_type))
            node.create_subscription(Clock, topics.CLOCK, on_clock, topics.QOS_CLOCK)
            node.create_subscription(Odometry, topics.STATE, on_state, topics.QOS_LOCKSTEP)
            deadline = time.monotonic() + RUN_LIMIT_S
            sent_matched = 0   # messages sent once the recorder was matched
            while runner.poll() is None and time.monotonic() < deadline:
                executor.spin_once(timeout_sec=0.1)
                if topic == topics.APPLIED_TORQUE and 'pub' in rogue:   # a stream, states or not
                    rogue['pub'].publish(rogue_message(topic, rogue.get('t_ns', 0), msg_type))
                    if (interrupt_after and rogue.get('t_ns', 0) > INTERRUPT_PAST_NS
                            and subscribed_by(node, rogue['pub'], 'recorder')):
                        sent_matched += 1
                        if sent_matched == interrupt_after:
                            assert rogue['pub'].wait_for_all_acked(Duration(seconds=60))
                            runner.send_signal(signal.SIGINT)
            if 'node' in rogue:
                rogue['node'].destroy_node()
            node.destroy_node()
        finally:
            rclpy.try_shutdown(context=context)
        _, err = runner.communicate(timeout=60)
    finally:
        if runner.poll() is None:
            runner.kill()
            runner.wait()
    return runner.returncode, err, out


def has_messages(bag, topic: str) -> bool:
    return next(read_messages(bag, {topic}), None) is not None


def first_unclean_step(u: np.ndarray) -> int | None:
    """The first step whose applied torque ``u`` recorded is not the clean run's (the batch
    engine's, bit for bit), or None; from that step on, only the last command held (missed steps,
    the hold policy, once the node that applies the rogue's topic stopped) until the runner stops
    the graph: never a command the rogue caused."""
    clean = BatchSimulation.from_runs([validate_scenario(PD_SLEW, float(len(u)))]).run()
    clean_u = clean.run_data(0).u[:len(u)]
    differs = [k for k in range(len(u)) if not np.array_equal(u[k], clean_u[k])]
    if not differs:
        return None
    first = differs[0]
    np.testing.assert_array_equal(u[first:], np.broadcast_to(u[first - 1], u[first:].shape))
    return first
