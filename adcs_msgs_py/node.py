"""What every adcs_sim node shares: validated parameters, startup handshake, process entry point.

* :class:`AdcsNode` declares its parameters from the overrides it was given and validates them
  with its :class:`~adcs_msgs_py.params.Schema`; a bad file stops the node before it publishes
  anything, with a message naming the key (exit status 2).
* :func:`wait_for` blocks until the graph is connected (matched publishers/subscriptions are
  updated by the DDS threads, so no spinning is needed) with a wall-clock deadline, woken by the
  endpoints' matched events (:class:`MatchedWait`: no polling, and no callback of the node runs).
* :func:`main_for` is each executable's ``main``: network hygiene defaults, init on a private
  context, clean shutdown on SIGINT/SIGTERM.
"""
from __future__ import annotations

import array
import ctypes
import os
import signal
import sys
import time
from collections.abc import Callable
from pathlib import Path

import rclpy
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.context import Context
from rclpy.duration import Duration
from rclpy.event_handler import (
    EventHandler,
    PublisherEventCallbacks,
    QoSPublisherEventType,
    QoSSubscriptionEventType,
    SubscriptionEventCallbacks,
)
from rclpy.executors import ExternalShutdownException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions

from adcs_msgs_py import conversions as cv
from adcs_msgs_py import names, topics
from adcs_msgs_py.executor import LockstepExecutor
from adcs_msgs_py.help_text import sentence
from adcs_msgs_py.guard import (
    Intruder,
    IntrusionDetected,
    PublisherVetting,
    RejectCounter,
    Unmatchable,
    parse_publishers,
)
from adcs_msgs_py.params import REQUIRED, ParameterError, Schema
from adcs_msgs_py.params_file import load_params_file

EXIT_BAD_PARAMETERS = 2
EXIT_GRAPH_TIMEOUT = 3
EXIT_INTRUSION = 4   # a publisher the run does not allow was matched on a topic this node applies
INTRUSION_LOG = 'intrusion: '   # the start of the error a node logs for each intruder it finds
UNMATCHABLE_LOG = 'unmatchable publisher: '   # the warning for a publisher of another type on a run topic
EXIT_RUN_STOPPED = 5   # the run cannot go on (e.g. the plant state is no longer finite)
EXIT_FLIGHT_SOFTWARE = 6   # a controller or estimator could not answer a step (FlightSoftwareFailed)
EXIT_DISK_FULL = 7   # the recorder cannot write its bag: no space or quota left (DiskFull)
ACK_POLL_S = 0.001   # wait_acked with an executor: the longest wait before spinning it once


class GraphTimeout(RuntimeError):
    """The graph did not connect within the startup timeout."""


class RunStopped(RuntimeError):
    """The run cannot go on (e.g. the plant state is no longer finite): the node exits with
    :data:`EXIT_RUN_STOPPED` and this message."""


class FlightSoftwareFailed(RunStopped):
    """A flight-software node (controller, estimator) could not answer a step: the node exits with
    :data:`EXIT_FLIGHT_SOFTWARE` and this message (naming the node, the time and the error)."""


class DiskFull(RuntimeError):
    """A node cannot write its output (the recorder, its bag): no space or quota left. The node exits
    with :data:`EXIT_DISK_FULL` and this message (naming the file and the error)."""


FASTDDS_PROFILE = Path(__file__).resolve().parent / 'fastdds_profile.xml'


def network_hygiene_defaults() -> None:
    """Process defaults unless the user explicitly chose otherwise: DDS discovery on this machine
    only, and our Fast DDS profile (short heartbeat period; see fastdds_profile.xml)."""
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    os.environ.setdefault('FASTRTPS_DEFAULT_PROFILES_FILE', str(FASTDDS_PROFILE))


# Set by the runner in the environment of every node it starts: its pid. A node so started dies
# with the runner, however the runner dies (SIGKILL included): Linux's parent-death signal.
RUNNER_PID_ENV = 'ADCS_SIM_RUNNER_PID'
PR_SET_PDEATHSIG = 1   # <linux/prctl.h>


def die_with_runner(death_signal: int = signal.SIGKILL) -> None:
    """If started by the runner (:data:`RUNNER_PID_ENV`), ask the kernel for ``death_signal`` when
    the runner exits, then check that the runner is still the parent (it may have died between
    the fork and here: then exit at once, as the signal would have made us)."""
    runner = os.environ.get(RUNNER_PID_ENV)
    if not runner or not sys.platform.startswith('linux'):
        return
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.prctl(PR_SET_PDEATHSIG, int(death_signal), 0, 0, 0) != 0:
        raise OSError(ctypes.get_errno(), 'prctl(PR_SET_PDEATHSIG) failed')
    if os.getppid() != int(runner):
        os._exit(128 + int(death_signal))


def _plain(value):
    if isinstance(value, array.array):
        return value.tolist()
    if isinstance(value, (list, tuple)):
        return list(value)
    return value


# What the matched events do not signal is re-checked this often while waiting: a matched endpoint
# whose node name is not yet in the graph cache (the run's own subscribers are counted by name,
# PublisherVetting.subscribers), which rclpy gives no event for (ros2/rclpy#929).
MATCH_RECHECK_S = 0.02


def _can_meet(offered, requested) -> bool:
    """Whether a writer's ``offered`` QoS can meet a reader's ``requested`` one on the two policies DDS
    matches that the interface sets: not a reliable reader of a best-effort writer, nor a
    transient-local reader of a volatile one. Anything else (an unknown policy included) may match.
    (rclpy's ``qos_check_compatible`` is no use here: an endpoint's own profile holds "default"
    durations where the graph lists "infinite", which it reports as incompatible.)"""
    best_effort = offered.reliability == ReliabilityPolicy.BEST_EFFORT
    volatile = offered.durability == DurabilityPolicy.VOLATILE
    return not ((best_effort and requested.reliability == ReliabilityPolicy.RELIABLE)
                or (volatile and requested.durability == DurabilityPolicy.TRANSIENT_LOCAL))


def can_match(pub) -> Callable[[object], bool]:
    """Whether a subscription the graph lists (a topic endpoint info) can ever be matched to the
    publisher ``pub``: the same type and a request its offer can meet (:func:`_can_meet`)."""
    name, qos = topics.type_name(pub.msg_type), pub.qos_profile
    return lambda info: info.topic_type == name and _can_meet(qos, info.qos_profile)


def can_deliver(sub) -> Callable[[object], bool]:
    """Whether a publisher the graph lists can ever be matched to the subscription ``sub``: the
    same type and an offer that can meet its request (:func:`_can_meet`)."""
    name, qos = topics.type_name(sub.msg_type), sub.qos_profile
    return lambda info: info.topic_type == name and _can_meet(info.qos_profile, qos)


class MatchedWait:
    """Wait for the matching of some endpoints to change: their rmw matched events
    (``RCL_PUBLISHER_MATCHED`` / ``RCL_SUBSCRIPTION_MATCHED``) in a wait set of their own. Nothing
    else is in it, so no callback of the node runs while it waits (an executor would run them,
    e.g. a controller answering a state before its recorder is matched). The events are not
    attached to the node: once the graph is connected (:meth:`destroy`), the lockstep loop's spins
    do not wait on them."""

    def __init__(self, context: Context, endpoints) -> None:
        self._context = context
        self._group = MutuallyExclusiveCallbackGroup()
        self._handlers = [
            EventHandler(callback_group=self._group, callback=lambda _info: None, parent_impl=e.handle,
                         event_type=QoSPublisherEventType.RCL_PUBLISHER_MATCHED if isinstance(e, Publisher)
                         else QoSSubscriptionEventType.RCL_SUBSCRIPTION_MATCHED)
            for e in endpoints]

    def wait(self, timeout: float) -> None:
        """Return when an endpoint's matching changed (since the last wait or the construction)
        or after ``timeout`` s."""
        if not self._handlers:
            return
        with self._context.handle:
            wait_set = _rclpy.WaitSet(0, 0, 0, 0, 0, len(self._handlers), self._context.handle)
            for h in self._handlers:
                h.add_to_wait_set(wait_set)
            wait_set.wait(max(0, int(timeout * 1e9)))
            for h in self._handlers:
                if h.is_ready(wait_set):
                    h.take_data()  # reset the event: the next wait waits for the next change

    def destroy(self) -> None:
        for h in self._handlers:
            h.destroy()
        self._handlers = []


def _take_matched(_info) -> None:
    """A subscription's matched event, taken so that it is reset; nothing else to do.

    rmw_fastrtps' ``rmw_wait`` waits on each reader's status condition, which stays triggered while
    one of its enabled statuses is changed and unread. A matched-event handler enables "subscription
    matched" on that condition (the start-up's :class:`MatchedWait` makes one per waited-for
    subscription), and destroying the handler does not disable it again: after the start-up, a
    match that nobody read (the publisher found before the wait began, a restarted controller, an
    intruder) left the condition triggered, every wait returned at once with nothing ready, and
    rclpy's executor rebuilt its wait set and waited again, a busy loop through every wait for a
    message (the showcase's dynamics node woke 20-60 times a step waiting for the wheel command;
    ros2/rmw_fastrtps#833 describes the same loop). With this handler in the node's wait set the
    executor takes the event and the next wait blocks (tests/test_executor_wakeups.py)."""


class AdcsNode(Node):
    """A node whose parameters are checked against a schema at construction."""

    schema: Schema
    #: The executor its process spins (:func:`main_for`): rclpy's single-threaded one with a lean
    #: ``spin_once`` (:class:`~adcs_msgs_py.executor.LockstepExecutor`).
    executor_class = LockstepExecutor
    #: Whether subscription callbacks take the message info (for the vetting's per-message publisher
    #: GID, which Jazzy's MessageInfo does not carry yet: the vetting then looks the graph up).
    message_info = True

    def __init__(self, context: Context, schema: Schema | None = None, **kwargs) -> None:
        schema = schema or self.schema
        # Parameters are read once at start (validated as a whole), so the parameter services
        # would only advertise a set that cannot take effect; without them every spin of the
        # lockstep loop waits on 6 fewer entities.
        kwargs.setdefault('start_parameter_services', False)
        kwargs.setdefault('parameter_overrides', [Parameter('start_type_description_service', value=False)])
        super().__init__(schema.node, context=context,
                         automatically_declare_parameters_from_overrides=True, **kwargs)
        given = {name: _plain(p.value) for name, p in self.get_parameters_by_prefix('').items()
                 if p.type_ != p.Type.NOT_SET}
        self.params = schema.validate(given)
        self.rejects = RejectCounter(self.get_logger())
        self.vetting = PublisherVetting(self, parse_publishers(self.params.get('startup.publishers', [])),
                                        self.on_intrusion, self.on_unmatchable)
        self._matched_names_sub = None     # recorder/matched, once a start-up waits for it
        self._matched_names: dict[str, frozenset[str]] = {}

    # --- the validation boundary of every incoming message ----------------------------------

    #: A node that acts on what it receives stops (exit status EXIT_INTRUSION) when an intruder is
    #: matched on one of its topics: without the publisher's GID in the message info (rclpy 7.1)
    #: no further message on that topic can be attributed. The recorder records instead.
    stop_on_intrusion = True

    def on_intrusion(self, intruders: list[Intruder]) -> None:
        """An intruder was matched on a vetted topic (before any of its messages was applied)."""
        for intruder in intruders:
            self.get_logger().error(f'{INTRUSION_LOG}{intruder.describe()} may not publish there; '
                                    'its messages are not applied')
        if self.stop_on_intrusion:
            topic = intruders[0].topic
            raise IntrusionDetected(intruders, self.vetting.allowed.get(topic, ()))

    def on_unmatchable(self, publishers: list[Unmatchable]) -> None:
        """A publisher of another type on a vetted topic: it can never deliver, the run goes on."""
        for publisher in publishers:
            self.get_logger().warning(f'{UNMATCHABLE_LOG}{publisher.describe()}')

    def on_refused(self, topic: str, msg) -> None:  # noqa: ARG002
        """A message on a compromised topic (or from an intruder's GID), or on a held one (a restarted
        node's predecessor still in the graph): not applied."""
        how = 'held' if topic in self.vetting.held else 'compromised'
        self.get_logger().warning(f'message on {how} topic {topic} not applied '
                                  f'({self.vetting.refused[topic]} so far)', throttle_duration_sec=5.0)

    #: Whether each subscription carries a handler of its matched event (see :func:`_take_matched`):
    #: needed under a wait-set executor; the recorder's events executor consumes statuses itself.
    take_matched_events = True

    # Endpoints are created without rclpy's default QoS-event handlers: each adds a waitable to
    # every spin of the lockstep loop (a lean node spins in ~140 us instead of ~250 us). A QoS
    # mismatch still shows: the graph never connects and start-up fails naming the topic.
    def publisher(self, name: str):
        """Publisher of a graph topic with the interface's type and QoS."""
        s = topics.spec(name)
        return self.create_publisher(s.msg_type, s.name, s.qos,
                                     event_callbacks=PublisherEventCallbacks(use_default_callbacks=False))

    def subscription(self, name: str, callback, qos=None, msg_type=None, raw: bool = False):
        """Subscription to a graph topic (the interface's type and subscriber QoS unless given).

        ``callback(msg)`` runs behind the validation boundary: only messages of admitted
        publishers (:class:`~adcs_msgs_py.guard.PublisherVetting`) reach it, and whatever it
        raises is counted as a rejected message (:meth:`~adcs_msgs_py.guard.RejectCounter.guarded`)."""
        s = topics.TOPICS.get(name)
        sub = None
        vetting, rejects = self.vetting, self.rejects
        resolved = self.resolve_topic_name(name)
        vetted = resolved in vetting.allowed

        def on_message(msg, info) -> None:   # two parameters: rclpy then passes the message info
            if vetted and not vetting.admit(sub, info, resolved):
                self.on_refused(resolved, msg)
                return
            rejects.guarded(name, callback, msg)

        sub = self.create_subscription(
            msg_type or s.msg_type, name,
            on_message if self.message_info else (lambda msg, info=None: on_message(msg, info)),  # message only
            qos or topics.subscriber_qos(s.qos), raw=raw,
            event_callbacks=SubscriptionEventCallbacks(
                use_default_callbacks=False, matched=_take_matched if self.take_matched_events else None))
        return sub

    def wait_for(self, what: str, ready: Callable[[], bool], timeout: float, endpoints=(),
                 state: Callable[[], str] | None = None) -> None:
        """Block until ``ready()`` or raise GraphTimeout naming ``what`` (and ``state()``: what the
        graph held then) after ``timeout`` s. ``ready()`` is tested again whenever the matching of
        one of ``endpoints`` (publishers, subscriptions) changes (:class:`MatchedWait`), and at
        least every MATCH_RECHECK_S."""
        deadline = time.monotonic() + timeout
        waiter = MatchedWait(self.context, endpoints)  # before the first test: no change is missed
        try:
            while not ready():
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    held = f' ({state()})' if state is not None else ''
                    raise GraphTimeout(f'{self.get_name()}: timed out after {timeout:g} s waiting for {what}{held}')
                waiter.wait(min(remaining, MATCH_RECHECK_S))
        finally:
            waiter.destroy()

    def spin_until(self, executor, what: str, ready: Callable[[], bool], timeout: float) -> None:
        """Spin ``executor`` until ``ready()`` (a message-borne condition), or raise GraphTimeout
        naming ``what`` after ``timeout`` s."""
        deadline = time.monotonic() + timeout
        while not ready():
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise GraphTimeout(f'{self.get_name()}: timed out after {timeout:g} s waiting for {what}')
            executor.spin_once(timeout_sec=min(remaining, 0.1))

    def wait_acked(self, publishers, timeout: float, executor=None) -> None:
        """Block until every reader has acknowledged what ``publishers`` (None entries skipped)
        sent, or ``timeout`` wall seconds per publisher. With ``executor`` (a caller outside any
        callback), spin it between waits of ACK_POLL_S: a reader in this process (an in-process
        graph) then takes what it holds, instead of a full reader never acknowledging while this
        thread waits for it; an acknowledgement still ends the wait at once."""
        for pub in publishers:
            if pub is not None and not self._acked(pub, timeout, executor):
                self.get_logger().warning(
                    f'{pub.topic_name}: not every reader acknowledged within {timeout:g} s; a reader '
                    'that stays this far behind may miss messages (adcs_msgs_py.topics)',
                    throttle_duration_sec=5.0)

    @staticmethod
    def _acked(pub, timeout: float, executor) -> bool:
        if executor is None:
            return pub.wait_for_all_acked(Duration(seconds=timeout))
        deadline = time.monotonic() + timeout
        while not pub.wait_for_all_acked(Duration(seconds=min(ACK_POLL_S, max(deadline - time.monotonic(), 0.0)))):
            if time.monotonic() >= deadline:
                return False
            executor.spin_once(timeout_sec=0.0)
        return True

    def pace_recorder(self, step: int, publishers, timeout: float) -> None:
        """Every :data:`~adcs_msgs_py.topics.ACK_INTERVAL` steps, when a recorder is expected,
        :meth:`wait_acked`: the recorder never falls the writers' history depth behind and loses
        messages (adcs_msgs_py.topics)."""
        if self.params['startup.expect_recorder'] and step % topics.ACK_INTERVAL == 0:
            self.wait_acked(publishers, timeout)

    def wait_recorder_matched(self, publishers, executor) -> None:
        """With a recorder expected: spin ``executor`` until the recorder's latest ``recorder/matched``
        names this node on the topic of each of ``publishers`` (None entries skipped), i.e. until the
        recorder's *readers* have matched them; GraphTimeout after ``startup.timeout``.

        :meth:`wait_for_publishers` sees the writer's side of a match only. DDS matches the two
        sides on their own, and a VOLATILE reader that matches a writer late takes only what is
        written after that: seen as a bag without the first 59 steps of every topic on a loaded
        machine. Hence every node writing a recorded topic waits for this before its first message."""
        if not self.params['startup.expect_recorder']:
            return
        wanted = {pub.topic_name for pub in publishers if pub is not None}
        if self._matched_names_sub is None:
            self._matched_names_sub = self.subscription(names.RECORDER_MATCHED, self._on_matched_names)
        me = self.get_fully_qualified_name()
        self.spin_until(executor, f'the recorder matching its publishers on {", ".join(sorted(wanted))}',
                        lambda: all(me in self._matched_names.get(t, ()) for t in wanted),
                        self.params['startup.timeout'])

    def _on_matched_names(self, msg) -> None:
        self._matched_names = cv.matched_from_msg(msg, self._matched_names_sub.topic_name)

    def wait_for_publishers(self, required: dict, timeout: float) -> None:
        """Wait until each publisher has at least the given number of matched subscriptions. When
        the node knows the run's nodes (``startup.publishers``), of THEIR subscriptions: a
        foreign subscriber (an eavesdropper) must not make the count and start the run before a
        node of it can receive (it would miss the first state)."""
        for pub, count in required.items():
            if count > 0:
                self.wait_for(f'{count} subscriber(s) on {pub.topic_name}',
                              lambda p=pub, c=count: self._subscribed(p, c), timeout, endpoints=[pub],
                              state=lambda p=pub: self._subscription_state(p))

    def _subscribed(self, pub, count: int) -> bool:
        """At least ``count`` subscriptions matched to ``pub``; with ``startup.publishers``, at least
        ``count`` of the run's nodes among those that can match it, and every other one that can
        match it matched too (the matched count alone does not say whose they are)."""
        matched = pub.get_subscription_count()
        if matched < count or self.vetting.run_nodes is None:
            return matched >= count
        own, others = self.vetting.subscribers(pub.topic_name, can_match(pub))
        return own >= count and matched >= count + others

    def _subscription_state(self, pub) -> str:
        return (f'{pub.get_subscription_count()} matched; the graph lists '
                f'{self.vetting.describe_subscribers(pub.topic_name, can_match(pub))}')

    def close(self) -> None:
        """Release resources (files); called once on the way out, whatever happened."""

    def run(self, executor) -> None:
        """Default behaviour: spin until shutdown."""
        executor.spin()


def check_params_files(argv: list[str]) -> None:
    """Read every ``--params-file`` as the runner does first (:func:`load_params_file`: its size
    and complexity limits, then rcl's parser): a file over a limit or refused by rcl stops the
    node with a one-line message naming the file, before rclpy.init parses it again."""
    for i, arg in enumerate(argv[:-1]):
        if arg == '--params-file':
            load_params_file(argv[i + 1])


HELP_FLAGS = ('-h', '--help')


def wants_help(argv: list[str]) -> bool:
    """``-h``/``--help`` among the program's own arguments (before any ``--ros-args``)."""
    own = argv[1:argv.index('--ros-args')] if '--ros-args' in argv else argv[1:]
    return any(a in HELP_FLAGS for a in own)


def usage(schema: Schema) -> str:
    """What ``<node> --help`` prints: how to start it and its parameters, one line each."""
    lines = [f'usage: {schema.node} [-h] [--ros-args --params-file FILE] [--ros-args -p NAME:=VALUE ...]', '']
    if schema.doc:
        lines += [sentence(schema.doc), '']
    lines += [f'parameters (section {schema.node}.ros__parameters of a scenario file):']
    width = max((len(p.name) for p in schema.params), default=0)
    for p in schema.params:
        default = 'required' if p.default is REQUIRED else f'default {p.default!r}'
        doc = f' {sentence(p.doc)}' if p.doc else ''
        lines.append(f'  {p.name:<{width}}  {p.kind}, {default}.{doc}')
    return '\n'.join(lines)


def main_for(node_class: type[AdcsNode], args=None, handle_signals: bool = True) -> int:
    """Entry point of a node executable. Returns the process exit status.

    ``handle_signals=False`` leaves SIGINT/SIGTERM to the node (the recorder drains its queues
    before closing the bag); otherwise rclpy's handler turns them into a clean shutdown. Started
    by the runner, the node dies with it (:func:`die_with_runner`): SIGKILL, or SIGTERM for a node
    that handles it (the recorder closes its bag, then exits).
    """
    argv = list(args if args is not None else sys.argv)
    if wants_help(argv):
        print(usage(node_class.schema), flush=True)
        return 0
    die_with_runner(signal.SIGKILL if handle_signals else signal.SIGTERM)
    network_hygiene_defaults()
    try:
        check_params_files(argv)
    except ParameterError as exc:
        print(f'[{node_class.schema.node}] error: {exc}', file=sys.stderr, flush=True)
        return EXIT_BAD_PARAMETERS
    context = Context()
    options = SignalHandlerOptions.ALL if handle_signals else SignalHandlerOptions.NO
    rclpy.init(args=argv, context=context,
               signal_handler_options=options)
    node = None
    status = 0
    try:
        try:
            node = node_class(context)
        except ParameterError as exc:
            print(f'[{node_class.schema.node}] error: {exc}', file=sys.stderr, flush=True)
            return EXIT_BAD_PARAMETERS
        executor = node_class.executor_class(context=context)
        executor.add_node(node)
        node.run(executor)
    except GraphTimeout as exc:
        print(f'error: {exc}', file=sys.stderr, flush=True)
        status = EXIT_GRAPH_TIMEOUT
    except IntrusionDetected as exc:
        print(f'error: run compromised: {exc}', file=sys.stderr, flush=True)
        status = EXIT_INTRUSION
    except RunStopped as exc:
        print(f'[{node_class.schema.node}] error: {exc}', file=sys.stderr, flush=True)
        status = EXIT_FLIGHT_SOFTWARE if isinstance(exc, FlightSoftwareFailed) else EXIT_RUN_STOPPED
    except DiskFull as exc:
        print(f'[{node_class.schema.node}] error: {exc}', file=sys.stderr, flush=True)
        status = EXIT_DISK_FULL
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.close()
            node.destroy_node()
        rclpy.try_shutdown(context=context)
    return status


def entry_point(node_class: type[AdcsNode], **kwargs):
    """``main(args=None)`` of a node executable: :func:`main_for` ``node_class``, exit with its status."""
    def main(args=None) -> None:
        raise SystemExit(main_for(node_class, args, **kwargs))
    main.__doc__ = f'Run the {node_class.__name__} executable.'
    return main
