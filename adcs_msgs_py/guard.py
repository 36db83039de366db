"""Reject, count and warn: how a node survives a bad message, and keeps out a foreign publisher.

* :class:`RejectCounter`: a node wraps each conversion of an incoming message in
  :meth:`RejectCounter.accept`; an :class:`~adcs_msgs_py.conversions.InvalidMessage` is counted
  per topic and logged as a throttled warning, and the callback simply returns. Nothing
  downstream ever sees a NaN. :meth:`RejectCounter.guarded` is the last line of every
  subscription callback (:meth:`adcs_msgs_py.node.AdcsNode.subscription`): whatever escapes the
  callback is counted as a rejection of that message, never raised into the executor.
* :class:`PublisherVetting`: the graph knows which node may publish on each topic a node listens
  to (``startup.publishers``, set by the runner from the scenario's sections). Before a message is
  applied, the subscription's matched-publisher count is compared with the last look (an O(1)
  call); when it changed, or the graph did not then list every matched publisher, the graph is
  looked up (node name, namespace and endpoint GID of every publisher; waiting up to
  GRAPH_SETTLE_S for their node names) and a publisher of a node that may not publish there is an
  :class:`Intruder`. A DDS reader matches a writer before it accepts any sample from it, so the
  intruder is found before its first message is applied (but for a writer matched and not yet in
  the graph cache: a window of the discovery's own latency). Node names are not authenticated
  (that needs DDS Security), but they are unique in a run: every node of the run has one publisher
  on a topic, so a second publisher of an allowed node is a second node of that name, a rogue that
  took it: an intruder (the one that came later; both when they came together). The recorder's
  sweep also counts the graph's node names (:meth:`PublisherVetting.sweep`): a second node of a
  run node's name is an intruder even if it publishes nothing vetted (it may subscribe, and be
  counted as the run's by the start-up handshake). A node the runner may start again
  (:data:`~adcs_msgs_py.names.RESTARTABLE`) leaves a predecessor in the graph when it was killed
  (until its participant's lease runs out: 20 s with Fast DDS's defaults): a second node of its
  name holds the topic (nothing applied from it) until one of the two leaves, and is an intruder
  if both are still there after DUPLICATE_GRACE_S.
* A publisher of another type on a vetted topic never matches the node's reader, so it can never
  deliver: it is :class:`Unmatchable`, reported (``on_unmatchable``: logged, and written into the
  bag by the recorder), never an intruder; the topic stays usable.

  rclpy 7.1 (Jazzy) gives a callback the message info without the publisher's GID (added to
  rclpy in ros2/rclpy#1466, not in Jazzy's 7.1.x), so a message cannot be attributed to one
  publisher: once an intruder is matched on a topic, no message on it can be trusted and the topic
  is *compromised* (nothing more is applied from it). Where the info carries ``publisher_gid``,
  messages are filtered one by one instead, and the topic stays usable.
"""
from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable, Iterable, Mapping
from typing import NamedTuple, TypeVar

from adcs_msgs_py import topics
from adcs_msgs_py.conversions import InvalidMessage
from adcs_msgs_py.names import RESTARTABLE, RUN_NODES, format_publishers, parse_publishers  # noqa: F401 (re-exported)

T = TypeVar('T')

WARN_THROTTLE_S = 5.0
GRAPH_SETTLE_S = 5.0   # how long a new publisher may stay unnamed in the graph cache (discovery, under load)
UNKNOWN_NODE = '_NODE_NAME_UNKNOWN_'  # what rmw reports before a participant's node names arrive
# How long a second node of a restartable node's name is held before it is an intruder: a SIGKILLed
# node stays in the graph until its participant's lease runs out (Fast DDS's default: 20 s).
DUPLICATE_GRACE_S = 30.0


class RejectCounter:
    """Per-topic count of rejected messages, with a throttled warning through a ROS logger."""

    def __init__(self, logger, throttle_s: float = WARN_THROTTLE_S) -> None:
        self._logger = logger
        self._throttle_s = throttle_s
        self.counts: Counter[str] = Counter()

    @property
    def total(self) -> int:
        return sum(self.counts.values())

    def reject(self, topic: str, reason: str) -> None:
        """Count a rejected message on ``topic`` and warn (throttled)."""
        self.counts[topic] += 1
        self._logger.warning(
            f'rejected message on {topic!r} ({self.counts[topic]} so far): {reason}',
            throttle_duration_sec=self._throttle_s)

    def accept(self, topic: str, convert: Callable[[], T]) -> T | None:
        """Run ``convert()``; on InvalidMessage count and warn, and return None."""
        try:
            return convert()
        except InvalidMessage as exc:
            self.reject(topic, str(exc))
            return None

    def guarded(self, topic: str, callback: Callable[[object], None], msg) -> None:
        """``callback(msg)``; any exception it raises is a rejection of ``msg`` (counted, warned),
        never an exception out of the executor. (KeyboardInterrupt and the executor's shutdown
        are BaseExceptions: they go through.)"""
        try:
            callback(msg)
        except Exception as exc:  # noqa: BLE001 - the validation boundary: nothing escapes a callback
            self.reject(topic, f'{type(exc).__name__}: {exc}')


# --- publishers -----------------------------------------------------------------------------

class Intruder(NamedTuple):
    """A publisher on a topic that its node may not publish on, or a second node of a run node's
    name (``duplicate``; ``topic`` and ``gid`` empty: found in the graph's node names)."""

    topic: str
    node: str          # fully qualified node name (namespace/name)
    gid: str           # endpoint GID, hex
    duplicate: bool = False

    def describe(self) -> str:
        who = f'a second node named {self.node}' if self.duplicate else f'node {self.node}'
        if not self.topic:
            return f'{who} in the graph'
        return f'{who} (publisher GID {self.gid}) on {self.topic}'


class Unmatchable(NamedTuple):
    """A publisher of another type on a vetted topic: never matched with the node's reader, it can
    never deliver there (reported, not an intruder)."""

    topic: str
    node: str
    gid: str
    type_name: str     # what it publishes
    expected: str      # the topic's type in the run

    def describe(self) -> str:
        return (f'node {self.node} (publisher GID {self.gid}) publishes {self.type_name} on {self.topic}, '
                f'which carries {self.expected}: it can never deliver there; ignored')


class IntrusionDetected(RuntimeError):
    """Raised by :meth:`PublisherVetting.admit` when the node stops on an intrusion."""

    def __init__(self, intruders: list[Intruder], allowed: Iterable[str]) -> None:
        self.intruders = intruders
        names = ', '.join(sorted(allowed)) or 'no node'
        super().__init__('; '.join(i.describe() for i in intruders) + f' (allowed: {names})')


def _gid_hex(gid) -> str:
    if isinstance(gid, Mapping):   # a future rclpy may give {'implementation_identifier', 'data'}
        gid = gid.get('data', b'')
    return bytes(gid).hex()


def full_name(namespace: str, name: str) -> str:
    """A node's fully qualified name (``/ns/name``; ``/name`` in the root namespace), as the graph's
    endpoint infos and ``Node.get_fully_qualified_name`` give it."""
    return f'{namespace.rstrip("/")}/{name}'


def subscribed_by(node, pub, name: str) -> bool:
    """Whether node ``name`` (in ``node``'s namespace) is listed with a subscription on ``pub``'s
    topic and ``pub`` is matched with every subscription listed there (that one among them): e.g.
    the fault injector publishing its schedule once the recorder is matched."""
    infos = node.get_subscriptions_info_by_topic(pub.topic_name)
    wanted = full_name(node.get_namespace(), name)
    return (any(full_name(i.node_namespace, i.node_name) == wanted for i in infos)
            and pub.get_subscription_count() >= len(infos))


class PublisherVetting:
    """Which publishers a node admits on each of its vetted topics (see the module doc).

    ``allowed``: ``{topic: node names}`` with topics as the node names them (relative names are
    resolved in the node's namespace, as are the allowed node names). ``on_intrusion(intruders)``
    is called once per newly found intruder set (the recorder records it; the other nodes stop);
    ``on_unmatchable(publishers)`` once per newly found publisher of another type.
    """

    def __init__(self, node, allowed: Mapping[str, Iterable[str]],
                 on_intrusion: Callable[[list[Intruder]], None] | None = None,
                 on_unmatchable: Callable[[list[Unmatchable]], None] | None = None) -> None:
        self._node = node
        ns = node.get_namespace()
        special = (RUN_NODES, RESTARTABLE)
        self.allowed = {node.resolve_topic_name(t): frozenset(full_name(ns, n) for n in names)
                        for t, names in allowed.items() if t not in special}
        # the type of each vetted topic: a publisher of another type can never deliver there
        self.types = {node.resolve_topic_name(t): topics.TOPICS[t].type_name
                      for t in allowed if t in topics.TOPICS}
        # every node of the run (RUN_NODES entry): whose subscriptions the start-up handshake counts
        self.run_nodes = (frozenset(full_name(ns, n) for n in allowed[RUN_NODES])
                          if RUN_NODES in allowed else None)
        self.restartable = frozenset(full_name(ns, n) for n in allowed.get(RESTARTABLE, ()))
        self.on_intrusion = on_intrusion
        self.on_unmatchable = on_unmatchable
        self.vetted: dict[str, set[str]] = {}      # topic -> GIDs of admitted publishers
        self.owners: dict[str, dict[str, str]] = {}   # topic -> {allowed node: GID of its publisher}
        self.matched: dict[str, int] = {}          # topic -> matched publishers at the last look
        self.listed: dict[str, int] = {}           # topic -> publishers of its type the graph listed then
        self.compromised: set[str] = set()         # topics with an intruder and no per-message GID
        self.held: set[str] = set()                # topics with a restartable node's name twice
        self.twice_since: dict[tuple[str, str], float] = {}   # (topic or '', node) -> first seen twice
        self.intruders: dict[str, Intruder] = {}   # gid (a node's name: found by name) -> intruder
        self.unmatchable: dict[str, Unmatchable] = {}   # gid -> publisher of another type
        self.refused: Counter[str] = Counter()     # messages not applied, per topic

    @property
    def active(self) -> bool:
        return bool(self.allowed)

    def admit(self, sub, info: Mapping | None = None, topic: str | None = None) -> bool:
        """Whether the message just taken on ``sub`` (with message info ``info``) may be applied
        (``topic``: its resolved name, if the caller has it at hand)."""
        topic = topic or sub.topic_name
        allowed = self.allowed.get(topic)
        if allowed is None:
            return True
        gid = info.get('publisher_gid') if info else None
        matched = sub.get_publisher_count()
        if gid is not None:   # per-message attribution (rclpy with MessageInfo.publisher_gid)
            gid = _gid_hex(gid)
            if topic in self.held or (gid not in self.vetted.get(topic, ()) and gid not in self.intruders):
                self._inspect(topic, allowed, matched)
            ok = gid in self.vetted.get(topic, ()) and topic not in self.held
        else:   # a publisher came or went since the last look: look again
            # (or the graph did not list every matched one then: one may have been discovered
            # since, an intruder among them; or a node's name is held twice: until one leaves)
            if topic not in self.compromised and (topic in self.held or matched != self.matched.get(topic)
                                                  or self.listed.get(topic, 0) < matched):
                self._inspect(topic, allowed, matched)
            ok = topic not in self.compromised and topic not in self.held
        if not ok:
            self.refused[topic] += 1
        return ok

    def subscribers(self, topic: str, can_match: Callable[[object], bool] | None = None) -> tuple[int, int]:
        """``(of the run, others)``: the subscriptions to ``topic`` in the graph, by node (one
        whose node name has not arrived yet counts as another's), of those that can match the
        caller's publisher (``can_match(info)``; all when None). One that never can (another type
        under the same name, a QoS rmw calls incompatible) never adds to the publisher's matched
        count: counted among the others, it would keep the start-up handshake waiting forever."""
        infos = [i for i in self._node.get_subscriptions_info_by_topic(topic) if can_match is None or can_match(i)]
        own = sum(full_name(i.node_namespace, i.node_name) in self.run_nodes for i in infos)
        return own, len(infos) - own

    def describe_subscribers(self, topic: str, can_match: Callable[[object], bool] | None = None) -> str:
        """What the graph lists on ``topic`` (for a start-up timeout's message): each subscription's
        node, whether it counts as the run's, another's or cannot match, and its endpoint GID."""
        rows = []
        for info in self._node.get_subscriptions_info_by_topic(topic):
            node = full_name(info.node_namespace, info.node_name)
            kind = ('cannot match' if can_match is not None and not can_match(info)
                    else 'run' if self.run_nodes is not None and node in self.run_nodes else 'other')
            rows.append(f'{node} ({kind}, GID {_gid_hex(info.endpoint_gid)})')
        return '; '.join(rows) or 'none'

    def sweep(self, subs, unsubscribed=()) -> None:
        """Look every vetted subscription of ``subs`` up in the graph, message or not, count
        changed or not (one publisher leaving as another joins keeps the count): for a node that
        must record an intruder that sent nothing through it (the recorder, periodically). Also
        the vetted topics ``unsubscribed`` (resolved names) that the node watches without a
        subscription (the recorder writes /clock and the viewer topics itself), and the graph's
        node names: a second node of a run node's name."""
        looks = [(sub.topic_name, sub.get_publisher_count) for sub in subs]
        looks += [(topic, lambda t=topic: self._node.count_publishers(t)) for topic in unsubscribed]
        for topic, count in looks:
            allowed = self.allowed.get(topic)
            if allowed is not None and topic not in self.compromised:
                self._inspect(topic, allowed, count())
        self._count_names()

    def _twice(self, topic: str, node: str) -> bool:
        """``node`` is there twice (on ``topic``; '': in the node names): whether that is an
        intrusion now, rather than a restarted node beside its predecessor, held until one leaves."""
        first = self.twice_since.setdefault((topic, node), time.monotonic())
        return node not in self.restartable or time.monotonic() - first > DUPLICATE_GRACE_S

    def _count_names(self) -> None:
        """A second node of a run node's name in the graph: an intruder (once per name), unless a
        publisher of it was already found so."""
        if self.run_nodes is None:
            return
        counts = Counter(full_name(ns, name) for name, ns in self._node.get_node_names_and_namespaces())
        new = []
        for node in sorted(self.run_nodes):
            if counts[node] < 2:
                self.twice_since.pop(('', node), None)
            elif (self._twice('', node) and node not in self.intruders
                  and not any(i.duplicate and i.node == node for i in self.intruders.values())):
                self.intruders[node] = Intruder('', node, '', duplicate=True)
                new.append(self.intruders[node])
        if new and self.on_intrusion is not None:
            self.on_intrusion(new)

    def _inspect(self, topic: str, allowed: frozenset[str], matched: int) -> None:
        """Look the topic's publishers up in the graph (waiting up to GRAPH_SETTLE_S for every
        matched one to be listed with its node name) and sort them into vetted, intruders (another
        node, or a second node of an allowed name) and unmatchable (another type)."""
        deadline = time.monotonic() + GRAPH_SETTLE_S
        while True:
            infos = self._node.get_publishers_info_by_topic(topic)
            # The graph lists an endpoint when it is discovered (as a reader matches it), its node
            # name when the participant's ros_discovery_info arrives. (Matched counts are no guide:
            # a stopped node stays matched for a while after it left the graph.)
            if all(i.node_name != UNKNOWN_NODE for i in infos) or time.monotonic() > deadline:
                break
            # Not a synchronisation on our own messages: the graph cache is filled by rmw's
            # discovery threads and rclpy gives no event when a node name arrives (no graph guard
            # condition in its API, ros2/rclpy#929; rclpy's own Node.wait_for_node polls too).
            time.sleep(0.005)
        expected = self.types.get(topic)
        other_type = [i for i in infos if expected is not None and i.topic_type != expected]
        infos = [i for i in infos if expected is None or i.topic_type == expected]
        self.matched[topic], self.listed[topic] = matched, len(infos)
        self._report_unmatchable(topic, other_type, expected)
        by_node: dict[str, list[str]] = {}
        new = []
        for info in infos:
            gid, node = _gid_hex(info.endpoint_gid), full_name(info.node_namespace, info.node_name)
            if node in allowed:
                by_node.setdefault(node, []).append(gid)
            elif gid not in self.intruders:
                self.intruders[gid] = Intruder(topic, node, gid)
                new.append(self.intruders[gid])
        vetted = self.vetted[topic] = set()
        owners = self.owners.setdefault(topic, {})
        held = False
        for node, gids in by_node.items():
            if len(gids) == 1:   # the node's one publisher on the topic
                self.twice_since.pop((topic, node), None)
                vetted.add(gids[0])
                owners[node] = gids[0]
            elif not self._twice(topic, node):
                held = True
            else:   # two nodes of that name: the one vetted before stays (with per-message GIDs)
                first = owners.get(node)
                vetted.update(g for g in gids if g == first)
                for gid in gids:
                    if gid != first and gid not in self.intruders:
                        self.intruders[gid] = Intruder(topic, node, gid, duplicate=True)
                        new.append(self.intruders[gid])
        if held:
            self.held.add(topic)
        else:
            self.held.discard(topic)
        if new:
            self.compromised.add(topic)
            if self.on_intrusion is not None:
                self.on_intrusion(new)

    def _report_unmatchable(self, topic: str, infos, expected: str | None) -> None:
        """Publishers of another type than the topic's (each reported once)."""
        new = []
        for info in infos:
            gid = _gid_hex(info.endpoint_gid)
            if gid not in self.unmatchable:
                self.unmatchable[gid] = Unmatchable(topic, full_name(info.node_namespace, info.node_name),
                                                    gid, info.topic_type, expected)
                new.append(self.unmatchable[gid])
        if new and self.on_unmatchable is not None:
            self.on_unmatchable(new)
