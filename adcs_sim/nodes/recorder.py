"""Recorder node: every topic of the graph, serialized, into a rosbag2 MCAP bag.

Subscriptions are ``raw`` (CDR bytes; nothing is deserialised). All topics of the interface
(:data:`adcs_msgs_py.topics.TOPICS`, each with its own QoS so transient-local faults are received
too) are subscribed at start; other topics appearing in the node's namespace are picked up by a
periodic graph look-up. The file is flushed every ``flush_period`` wall seconds. Each transform
received on ``frames/*`` is also written on ``/tf`` as a ``tf2_msgs/TFMessage`` (:mod:`adcs_sim.bag.tf`:
why, and what is refused).

On SIGINT / SIGTERM the node stops taking new work, drains what DDS has already delivered, and
closes the bag (summary + ``metadata.yaml``). After SIGKILL, everything up to the last flush is
readable (:func:`adcs_sim.bag.reader.read_raw`). The bag is locked, naming the node, while it is
written (:mod:`adcs_sim.bag.lock`: ``adcs-bag-repair`` refuses it meanwhile). A write that fails (a
full disk) stops the recording: nothing more is written, the bag is readable up to the failure, and
the node exits with :data:`~adcs_msgs_py.node.EXIT_DISK_FULL` (another write error:
``EXIT_RUN_STOPPED``) and one line naming the bag and the error.

Memory: what DDS has delivered and the recorder has not taken yet is bounded (its Fast DDS
profile, ``recorder_fastdds.xml``: :data:`MAX_UNTAKEN` messages a topic; a reader that is full
acknowledges nothing more, so the writers' acknowledgement waits hold the loop until the recorder
catches up). Without it the process kept the memory of the largest backlog it ever had (issue 18).
"""
from __future__ import annotations

import importlib
import os
import signal
import sys
import threading
import time
from datetime import datetime
from pathlib import Path

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.experimental import EventsExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from std_msgs.msg import String

from adcs_msgs_py import conversions as cv
from adcs_msgs_py import names, topics
from adcs_msgs_py.cdr import deserialized
from adcs_msgs_py.guard import UNKNOWN_NODE, Intruder, Unmatchable, full_name
from adcs_msgs_py.node import FASTDDS_PROFILE, AdcsNode, DiskFull, RunStopped, can_deliver, main_for
from adcs_msgs_py.recorded_topics import MAX_PENDING, RecordedTopics, parse_config
from adcs_sim.bag.schema import RECORDER_SCHEMA
from adcs_sim.bag.tf import TF_TYPE, tf_message_cdr
from adcs_sim.bag.writer import STAMP_FIRST_TYPES, BagWriteError, BagWriter, qos_dicts

IGNORED_TOPICS = ('/rosout', '/parameter_events')
STOP_REQUESTED = threading.Event()  # set by SIGINT / SIGTERM in the recorder process
READY_LINE = 'recorder: ready'
DRAIN_MAX_S = 10.0  # < the runner's stop timeout (adcs_sim.app.graph.processes.STOP_TIMEOUT_S)
PROFILES_ENV = 'FASTRTPS_DEFAULT_PROFILES_FILE'
RECORDER_PROFILE = Path(__file__).resolve().parent / 'recorder_fastdds.xml'
# How often the recorder looks at its readers' matches (recorder/matched): the longest a node's
# start-up waits after the recorder has matched it; ~15 matched counts a look, a few µs each.
MATCH_LOOK_S = 0.05
MAX_UNTAKEN = 1000  # messages a topic DDS holds for the recorder (recorder_fastdds.xml's max_samples)


def use_recorder_profile(environ=os.environ) -> None:
    """Make the recorder's Fast DDS profile (its readers bounded: :data:`MAX_UNTAKEN`) the
    process's, in place of the graph's default profile (unset, or set by the runner to
    ``adcs_msgs_py/fastdds_profile.xml``). A profile file the user chose is kept as it is, and so
    is the default when the recorder's file is missing (an incomplete install: Fast DDS would
    refuse a file that is not there and fall back to its own defaults)."""
    current = environ.get(PROFILES_ENV)
    if (not current or Path(current).resolve() == FASTDDS_PROFILE) and RECORDER_PROFILE.is_file():
        environ[PROFILES_ENV] = str(RECORDER_PROFILE)


def message_class(type_name: str):
    """``pkg/msg/Name`` -> the Python message class, or None if it is not installed (or what the
    name leads to is not a generated ROS message class: a graph's type names are not trusted)."""
    try:
        pkg, kind, name = type_name.split('/')
        if kind != 'msg' or not (pkg.isidentifier() and name.isidentifier()):
            return None
        cls = getattr(importlib.import_module(f'{pkg}.{kind}'), name)
    except (ValueError, ImportError, AttributeError):
        return None
    return cls if hasattr(type(cls), '__import_type_support__') else None


class RecorderNode(AdcsNode):
    schema = RECORDER_SCHEMA
    # The recorder applies nothing: an intruder is written into the bag (INTRUSIONS) and the
    # messages of a compromised topic are kept under quarantine/<topic>, so nothing is lost and
    # nothing unattributed is analysed as the run's.
    stop_on_intrusion = False
    take_matched_events = False   # the events executor reads the statuses from its listeners
    # rclpy's C++ events executor: 53-56 µs of CPU a message against 180-200 µs for the
    # single-threaded executor (raw Odometry on four topics, measured back to back, 2026-12-02). The
    # recorder takes every message of the run, about a dozen a step, on a machine it shares with
    # the lockstep loop. Jazzy's events executor fails on callbacks that take the message info
    # ("SystemError: null argument to internal routine"); that info has no publisher GID in Jazzy
    # anyway, so the vetting of the recorder's topics is the same without it (graph lookups).
    executor_class = staticmethod(EventsExecutor)
    message_info = False

    def __init__(self, context) -> None:
        super().__init__(context)
        p = self.params
        output = p['output'] or f'runs/{datetime.now():%Y%m%d-%H%M%S}'
        metadata = {}
        if p['scenario_file']:
            try:
                metadata['scenario'] = Path(p['scenario_file']).read_text()
            except OSError as exc:
                from adcs_msgs_py.params import ParameterError
                raise ParameterError('scenario_file', f'cannot read {p["scenario_file"]}: {exc.strerror}',
                                     'recorder') from None
        try:
            self.bag = BagWriter(Path(output), chunk_size=p['chunk_size'], metadata=metadata,
                                 process=f'recorder node {self.get_fully_qualified_name()}')
        except (FileExistsError, OSError) as exc:
            from adcs_msgs_py.params import ParameterError
            raise ParameterError('output', str(exc), 'recorder') from None
        self.stopping = False
        self.received = 0
        self.subs = {}
        self.skipped: set[str] = set()   # discovered topics that cannot be recorded (said once)
        self.tf_topic = self.resolve_topic_name(names.TF)   # written from frames/* (adcs_sim.bag.tf)
        wanted = p['topics']
        self.record_all = 'all' in wanted
        # /clock and the per-step viewer topics are written from the recorded state and the dynamics
        # node's dynamics/recording (adcs_msgs_py/recorded_topics.py): not subscribed, so that the
        # dynamics node sends them only to live subscribers.
        self.recorded: RecordedTopics | None = None
        self._own: dict[str, str] = {}   # the topics it writes: relative -> resolved name
        self._written: set[str] = set()   # their resolved names, once the config has come
        self.own_topics = {t for t in names.RECORDED_TOPICS if self.record_all or t in wanted}
        self.derived = {self.resolve_topic_name(t) for t in names.RECORDED_VISUAL_TOPICS}
        self.not_taken = {self.resolve_topic_name(t) for t in names.RECORDED_TOPICS}   # watched for intruders
        self.config_topic = self.resolve_topic_name(names.RECORDING_CONFIG)
        # the config first: an executor that takes ready subscriptions in their order takes it
        # before a state that arrived with it (the events executor takes them as they arrive)
        for spec in sorted(topics.TOPICS.values(), key=lambda s: s.name != names.RECORDING_CONFIG):
            if spec.name in names.RECORDED_TOPICS or spec.name == names.RECORDER_MATCHED:
                continue
            if self.record_all or spec.name in wanted or (spec.name == names.RECORDING_CONFIG and self.own_topics):
                self._subscribe(spec.name, spec.msg_type, topics.recorder_qos(spec.qos), spec.qos)
        self.create_timer(p['flush_period'], self._unless_unwritable(self.bag.flush))
        # the start-up handshake (AdcsNode.wait_recorder_matched): whose publishers it has matched
        self.pub_matched = self.publisher(names.RECORDER_MATCHED)
        self._matched_looked: dict[str, int] | None = None   # the matched counts last accounted for
        self._matched_sent: dict[str, set[str]] | None = None
        self.create_timer(MATCH_LOOK_S, self._announce_matched)
        if self.record_all:
            self.create_timer(p['discovery_period'], self._unless_unwritable(self._discover))
        if self.vetting.active:   # an intruder is recorded even if nothing it sends comes through
            self.create_timer(p['discovery_period'], self._unless_unwritable(self._sweep))
        print(READY_LINE, flush=True)

    def _subscribe(self, name: str, msg_type, qos: QoSProfile, offered: QoSProfile, record: bool = True) -> None:
        """Record topic ``name`` (``record`` False: only take it, as a source of what the recorder writes)."""
        resolved = self.resolve_topic_name(name)
        if resolved in self.subs:
            return
        type_name = topics.type_name(msg_type)
        if record:
            self.bag.add_topic(resolved, type_name, qos_dicts(offered))
        stamped = type_name in STAMP_FIRST_TYPES
        derive_tf = name in names.FRAME_TOPICS

        def on_message(data: bytes, topic=resolved) -> None:
            # the stamp is the log time: a negative or out-of-range one is rejected (counted)
            if stamped and self.rejects.accept(topic, lambda: cv.checked_cdr_stamp(topic, data)) is None:
                return
            if topic in self._written:   # a /clock discovered before the config: the recorder writes it
                return
            if record:
                self.bag.write(topic, data)
                self.received += 1
                if derive_tf:
                    self._write_tf(topic, data)
            # a topic of the interface by its relative name (a discovered one's name is resolved)
            if name == names.RECORDING_CONFIG:
                self._on_recording_config(topic, data)
            elif self.recorded is not None and name in self.recorded.sources:
                self._write_own(topic, name, data)

        self.subs[resolved] = self.subscription(name, self._unless_unwritable(on_message), qos=qos,
                                                msg_type=msg_type, raw=True)

    def _announce_matched(self) -> None:
        """Publish ``recorder/matched`` when the readers' matched counts change: for each topic
        whose matched publishers are at least those the graph lists (each listed one is then
        matched; the graph can list a writer a moment before or after its match), their nodes.
        Counts the graph does not account for yet (or whose node names have not arrived) are looked
        at again next time."""
        counts = {topic: sub.get_publisher_count() for topic, sub in self.subs.items()}
        if counts == self._matched_looked:
            return
        matched, settled = {}, True
        for topic, count in counts.items():
            if not count:
                continue
            infos = [i for i in self.get_publishers_info_by_topic(topic) if can_deliver(self.subs[topic])(i)]
            # a node name arrives after its endpoints (UNKNOWN_NODE until then): looked at again
            settled &= len(infos) == count and all(i.node_name != UNKNOWN_NODE for i in infos)
            if count >= len(infos):
                matched[topic] = {full_name(i.node_namespace, i.node_name) for i in infos}
        if matched != self._matched_sent:
            self.pub_matched.publish(cv.matched_to_msg(matched))
            self._matched_sent = matched
        self._matched_looked = counts if settled else None

    def _unless_unwritable(self, callback):
        """``callback``, doing nothing once the bag cannot be written, and stopping the recorder
        (:meth:`run`) when it is the one that finds so (a full disk): not a rejected message, not an
        exception out of the executor."""
        def call(*args) -> None:
            if self.bag.failed is None:
                try:
                    callback(*args)
                except BagWriteError:
                    self.stopping = True
        return call

    def _on_recording_config(self, topic: str, data: bytes) -> None:
        """The dynamics node's dynamics/recording: from now on /clock and the viewer topics are
        written from the recorded messages (a repeat of the same config changes nothing; a
        different one is refused)."""
        def parse():
            text = deserialized(data, String, topic).data
            if self.recorded is not None:
                if text != self.recording_text:
                    raise cv.InvalidMessage(f'{topic}: a second, different config (the first one stays)')
                return None
            return text, RecordedTopics(parse_config(text), on_lost=self._viewer_step_lost)
        parsed = self.rejects.accept(topic, parse)
        if not parsed:
            return
        self.recording_text, self.recorded = parsed
        self._own = {name: self.resolve_topic_name(name) for name in self.recorded.topics if name in self.own_topics}
        for name, resolved in self._own.items():
            spec = topics.TOPICS[name]
            self.bag.add_topic(resolved, spec.type_name, qos_dicts(spec.qos))
        self._written = set(self._own.values())
        for name in self.recorded.sources:   # what the config needs and this recorder does not record
            spec = topics.TOPICS[name]
            self._subscribe(name, spec.msg_type, topics.recorder_qos(spec.qos), spec.qos, record=False)

    def _write_own(self, topic: str, relative: str, data: bytes) -> None:
        """What ``data`` (recorded on ``topic``) completes of the recorder's own topics, into the bag."""
        derived = self.rejects.accept(topic, lambda: self.recorded.derive(relative, data))
        for name, message in derived or ():
            resolved = self._own.get(name)
            if resolved is not None:
                self.bag.write(resolved, message)
                if name in names.FRAME_TOPICS:
                    self._write_tf(resolved, message)

    def _viewer_step_lost(self, t_ns: int) -> None:
        """A step's markers given up: more incomplete steps than the acknowledgement pacing allows
        (adcs_msgs_py.recorded_topics.MAX_PENDING), a broken invariant: said, and counted in the bag."""
        self.get_logger().error(
            f'markers of t = {t_ns / cv.NS_PER_S:g} s not written: more than {MAX_PENDING} steps waited '
            f'for an input at once ({self.recorded.lost} step(s) lost so far; adcs_msgs_py.recorded_topics)',
            throttle_duration_sec=5.0)

    def _write_tf(self, topic: str, data: bytes) -> None:
        """The transform just recorded on ``topic``, also on ``/tf`` as a TFMessage (a malformed one
        is rejected and counted under ``topic``; its raw message stays recorded)."""
        def convert() -> bytes:
            try:
                return tf_message_cdr(data)
            except ValueError as exc:
                raise cv.InvalidMessage(f'{topic}: not written on {self.tf_topic}: {exc}') from None
        tf = self.rejects.accept(topic, convert)
        if tf is not None:
            self.bag.add_topic(self.tf_topic, TF_TYPE, qos_dicts(topics.QOS_LOCKSTEP))
            self.bag.write(self.tf_topic, tf)

    def _discover(self) -> None:
        """Subscribe to topics that appeared in the graph (in this namespace) since the last look."""
        ns = self.get_namespace().rstrip('/') + '/'
        reserved = (self.resolve_topic_name(names.INTRUSIONS), ns + names.QUARANTINE_PREFIX + '/',
                    self.resolve_topic_name(names.RECORDER_MATCHED))
        for name, types in self.get_topic_names_and_types():
            if (name in self.subs or name in self.skipped or name in IGNORED_TOPICS or name in self.derived
                    or (name == names.CLOCK and (self.recorded.config.clock if self.recorded
                                                 else self.count_publishers(self.config_topic)))
                    or not name.startswith(ns)
                    or len(types) != 1 or name.startswith(reserved) or name == self.tf_topic):
                continue
            try:
                self._subscribe_discovered(name, types[0])
            except Exception as exc:  # noqa: BLE001 - a topic the graph advertises is untrusted input
                self.skipped.add(name)
                self.rejects.reject(name, f'cannot record {types[0]}: {type(exc).__name__}: {exc}')

    def _subscribe_discovered(self, name: str, type_name: str) -> None:
        msg_type = message_class(type_name)
        if msg_type is None:
            self.skipped.add(name)
            return
        infos = self.get_publishers_info_by_topic(name)
        reliable = infos and all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in infos)
        qos = topics.recorder_qos(QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE
                                             if reliable else ReliabilityPolicy.BEST_EFFORT))
        self._subscribe(name, msg_type, qos, infos[0].qos_profile if infos else qos)

    def run(self, executor) -> None:
        while not (self.stopping or STOP_REQUESTED.is_set()):
            self._spin(executor, 0.1)
        # Drain: keep taking what DDS already delivered until a quiet period, but never longer
        # than DRAIN_MAX_S (a publisher that floods, an intruder, would keep it from closing the bag
        # before the runner's stop timeout kills it).
        quiet_until = time.monotonic() + 0.3
        give_up = time.monotonic() + DRAIN_MAX_S
        while self.bag.failed is None and time.monotonic() < min(quiet_until, give_up):
            before = self.received
            self._spin(executor, 0.05)
            if self.received != before:
                quiet_until = time.monotonic() + 0.3
        self.close()   # here, not only at exit: a bag that cannot be written stops the node with its reason
        if self.bag.failed is not None:
            error = self.bag.failed
            line = (f'{"disk full: " if error.disk_full else ""}{error}; recording stopped, the bag is '
                    f'readable up to there (adcs-bag-repair completes it)')
            raise DiskFull(line) if error.disk_full else RunStopped(line)

    def _spin(self, executor, timeout: float) -> None:
        """One spin; a bag write error out of a callback the node's base calls (intruders, refused
        messages) stops the recorder too."""
        try:
            executor.spin_once(timeout_sec=timeout)
        except BagWriteError:
            self.stopping = True

    # --- intruders (adcs_msgs_py.guard.PublisherVetting) ----------------------------------------

    def on_intrusion(self, intruders: list[Intruder]) -> None:
        """Log them, and write them into the bag: one ``intrusions`` message (one status per
        intruder) stamped with the latest ``/clock``."""
        super().on_intrusion(intruders)
        self._write_intrusions([
            ('ERROR', i.topic, {'topic': i.topic, 'node': i.node, 'gid': i.gid,
                                'allowed': ','.join(sorted(self.vetting.allowed.get(i.topic, ()))) or 'none',
                                **({'duplicate': 'true'} if i.duplicate else {})},
             i.describe() if i.duplicate else f'publisher {i.node} may not publish on {i.topic}', i.node)
            for i in intruders])

    def on_unmatchable(self, publishers: list[Unmatchable]) -> None:
        """Log them, and write them into the bag as warnings on ``intrusions`` (``unmatchable``:
        the run's messages are not affected, nothing is quarantined)."""
        super().on_unmatchable(publishers)
        self._write_intrusions([
            ('WARN', p.topic, {'topic': p.topic, 'node': p.node, 'gid': p.gid, 'type': p.type_name,
                               'expected': p.expected, 'unmatchable': 'true'}, p.describe(), p.node)
            for p in publishers])

    def _write_intrusions(self, statuses: list[tuple]) -> None:
        """One ``intrusions`` message of ``(level, name, values, message, hardware id)`` statuses,
        stamped with the latest ``/clock``, flushed at once."""
        topic = self.resolve_topic_name(names.INTRUSIONS)
        self.bag.add_topic(topic, 'diagnostic_msgs/msg/DiagnosticArray', qos_dicts(topics.QOS_LATCHED))
        msg = DiagnosticArray()
        msg.header.stamp = cv.stamp_from_ns(self.bag.clock_ns)
        for level, name, values, message, hardware_id in statuses:
            msg.status.extend(cv.status_to_msg(self.bag.clock_ns, name, values, level, message,
                                               hardware_id=hardware_id).status)
        self.bag.write(topic, serialize_message(msg))
        self.bag.flush()

    def on_refused(self, topic: str, data) -> None:
        """A message of a compromised topic: kept, under ``quarantine/<topic>``."""
        quarantine = names.quarantine_topic(topic, self.get_namespace())
        original = self.bag.topics[topic]
        self.bag.add_topic(quarantine, original.type_name, original.qos)
        if not original.stamped or self.rejects.accept(topic, lambda: cv.checked_cdr_stamp(topic, data)) is not None:
            self.bag.write(quarantine, data)
            self.received += 1

    def _sweep(self) -> None:
        self.vetting.sweep(self.subs.values(), [t for t in self.not_taken if t not in self.subs])

    def close(self) -> None:
        """Close the bag, once (:meth:`run` does at the end of a run; a write error is said there)."""
        if self.bag.closed:
            return
        try:   # a last look before the bag is closed
            if self.bag.failed is None:
                self._sweep()
        except Exception as exc:  # noqa: BLE001 - closing the bag comes first
            self.get_logger().error(f'last look for intruders failed: {exc}')
        summary = {}
        if self.rejects.total:
            summary['recorder.rejected_messages'] = str(self.rejects.total)
        if self.vetting.intruders:
            summary['recorder.intrusions'] = '; '.join(i.describe() for i in self.vetting.intruders.values())
        if self.recorded is not None and self.recorded.lost:
            summary['recorder.viewer_steps_lost'] = str(self.recorded.lost)
        if self.vetting.unmatchable:
            summary['recorder.unmatchable_publishers'] = '; '.join(
                p.describe() for p in self.vetting.unmatchable.values())
        try:
            self.bag.close(summary or None)
        except BagWriteError:
            return
        if self.bag.failed is None:
            print(f'recorder: wrote {sum(t.count for t in self.bag.topics.values())} messages to '
                  f'{self.bag.path}', file=sys.stderr, flush=True)


def _request_stop(signum, frame) -> None:
    STOP_REQUESTED.set()


def main(args=None) -> None:
    # Handle SIGINT/SIGTERM before the node exists (and so before it announces ready): a signal
    # at any moment stops the recorder cleanly instead of killing it with the bag unclosed.
    signal.signal(signal.SIGINT, _request_stop)
    signal.signal(signal.SIGTERM, _request_stop)
    use_recorder_profile()   # before rclpy.init: Fast DDS reads its profiles once per process
    raise SystemExit(main_for(RecorderNode, args, handle_signals=False))


if __name__ == '__main__':
    main()
