"""The start-up handshake of a publisher (``AdcsNode.wait_for_publishers``), against a fake graph.

With ``startup.publishers`` a node waits until ``count`` of the run's nodes are subscribed and
every other subscription that can be matched to its publisher is matched too: a foreign
subscriber (an eavesdropper) must not make the count before a node of the run can receive. A
subscription that can never be matched (another type under the same topic name, a transient-local
reader of a volatile writer) never adds to the matched count, so it must not be waited for: counted
among the others it held the start forever (``matched >= count + others`` never true). A timeout
says what the graph listed (node, whose, GID), so that a failed start can be diagnosed from its log.
"""
from __future__ import annotations

from types import SimpleNamespace

from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from adcs_msgs_py import topics
from adcs_msgs_py.guard import UNKNOWN_NODE, PublisherVetting
from adcs_msgs_py.names import RUN_NODES
from adcs_msgs_py.node import AdcsNode, can_match

SPEC = topics.spec(topics.WHEELS_CMD)
LISTED_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)


class FakeGraph:
    """What the handshake asks of a node: namespace, name resolution, subscriptions of a topic."""

    def __init__(self) -> None:
        self.subscriptions: list = []

    def get_namespace(self) -> str:
        return '/'

    def resolve_topic_name(self, name: str) -> str:
        return name if name.startswith('/') else '/' + name

    def get_subscriptions_info_by_topic(self, topic: str):
        return [i for i in self.subscriptions if i.topic == topic]

    def add(self, node: str, gid: int, type_name: str = SPEC.type_name, qos: QoSProfile = LISTED_QOS) -> None:
        self.subscriptions.append(SimpleNamespace(
            topic=SPEC.name, node_name=node, node_namespace='/' if node != UNKNOWN_NODE else '_NODE_NAMESPACE_UNKNOWN_',
            endpoint_gid=[gid] * 16, topic_type=type_name, qos_profile=qos))


class FakePublisher:
    """The controller's command publisher: its type and QoS, and the matched count DDS reports."""

    def __init__(self, matched: int) -> None:
        self.topic_name, self.msg_type, self.qos_profile = SPEC.name, SPEC.msg_type, SPEC.qos
        self.matched = matched

    def get_subscription_count(self) -> int:
        return self.matched


def _node(graph: FakeGraph) -> SimpleNamespace:
    """The part of a controller node the handshake uses (its vetting, from the runner's
    ``startup.publishers``: the run is the dynamics node, the controller and the recorder)."""
    allowed = {RUN_NODES: ['dynamics', 'pd_controller', 'recorder'], 'state': ['dynamics']}
    return SimpleNamespace(vetting=PublisherVetting(graph, allowed))


def _subscribed(graph: FakeGraph, matched: int, count: int = 2) -> bool:
    return AdcsNode._subscribed(_node(graph), FakePublisher(matched), count)


def test_a_subscription_that_can_never_match_does_not_hold_the_start():
    graph = FakeGraph()
    graph.add('dynamics', 1)
    graph.add('recorder', 2)
    graph.add('echo', 3, type_name=String.__module__.split('.')[0] + '/msg/String')   # another type, same name
    graph.add('late_joiner', 4, qos=QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                                               durability=DurabilityPolicy.TRANSIENT_LOCAL))
    graph.add('lossy', 5, qos=QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT,
                                         durability=DurabilityPolicy.VOLATILE))   # can match a reliable writer
    # DDS matched the run's two and the best-effort reader; the other two never will be
    assert _subscribed(graph, matched=3)
    assert not _subscribed(graph, matched=2)   # the best-effort reader may be matched instead of a run node


def test_an_eavesdropper_that_can_match_still_holds_the_start_until_every_run_node_is_matched():
    graph = FakeGraph()
    graph.add('recorder', 2)
    graph.add('eavesdropper', 9)
    assert not _subscribed(graph, matched=2)    # the dynamics node is not even listed
    graph.add('dynamics', 1)
    assert not _subscribed(graph, matched=2)    # listed; two matched may be the recorder and the eavesdropper
    assert _subscribed(graph, matched=3)


def test_a_subscription_whose_node_name_has_not_arrived_counts_as_another_nodes():
    graph = FakeGraph()
    graph.add('recorder', 2)
    graph.add(UNKNOWN_NODE, 1)
    assert not _subscribed(graph, matched=2)
    graph.subscriptions[-1].node_name, graph.subscriptions[-1].node_namespace = 'dynamics', '/'
    assert _subscribed(graph, matched=2)


def test_the_start_up_timeout_says_what_the_graph_listed():
    graph = FakeGraph()
    graph.add('recorder', 2)
    graph.add(UNKNOWN_NODE, 1)
    graph.add('late_joiner', 4, qos=QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    node, pub = _node(graph), FakePublisher(matched=2)
    said = AdcsNode._subscription_state(node, pub)
    assert said.startswith('2 matched; the graph lists ')
    assert f'/recorder (run, GID {"02" * 16})' in said
    assert f'_NODE_NAMESPACE_UNKNOWN_/{UNKNOWN_NODE} (other, GID {"01" * 16})' in said
    assert f'/late_joiner (cannot match, GID {"04" * 16})' in said


def test_can_match_is_the_type_and_the_two_matched_policies():
    pub = FakePublisher(0)
    check = can_match(pub)
    listed = SimpleNamespace(topic_type=SPEC.type_name, qos_profile=LISTED_QOS)
    assert check(listed)
    assert not check(SimpleNamespace(topic_type='std_msgs/msg/String', qos_profile=LISTED_QOS))
    unknown = QoSProfile(depth=1, reliability=ReliabilityPolicy.UNKNOWN, durability=DurabilityPolicy.UNKNOWN)
    assert check(SimpleNamespace(topic_type=SPEC.type_name, qos_profile=unknown))   # cannot tell: may match
