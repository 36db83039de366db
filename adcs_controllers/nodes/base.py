"""The controller-node template: state in, law out, command stamped with the state's stamp.

A concrete controller is its family (:mod:`adcs_controllers.families`): a schema and a law, a pure
object with ``control(t, q, w) -> (torque, status)`` (``adcs_controllers/laws``), which the batch
engine builds from the same family, so it runs the very same object. The base class

* validates parameters (schema), builds the law and the actuation (allocation over the
  available wheels, saturation: :class:`~adcs_controllers.laws.allocation.Actuation`);
* publishes commands on ``wheels/cmd`` (minimum-norm allocation, saturation) or ``torque_cmd``;
  a law whose ``output`` is ``'wheel_momentum'`` gets wheel SPEED commands instead
  (:meth:`~adcs_controllers.laws.allocation.WheelActuation.command_momentum`);
* before subscribing to ``state``, waits until its command publisher is matched by the dynamics
  node (and the recorder, when one is expected) — so by the time the dynamics node sees this
  controller subscribed, every command it sends will be delivered and recorded;
* rejects, counts and warns about bad messages, and publishes ``controller/status`` each step;
* follows the latched ``faults`` topic (:mod:`adcs_core.faults`): at the state stamped ``t_k`` it
  applies the latest fault state stamped ``<= t_k`` (the dynamics node's rule), re-allocating
  over the wheels that can still produce a commanded torque (not ``failed``, not ``stuck``;
  :meth:`~adcs_controllers.laws.allocation.WheelActuation.set_available`) and restoring a wheel on
  ``recovered``, and telling the law (``law.on_wheels``: a reconfiguring law changes phase
  there, :mod:`adcs_controllers.laws.reconfiguration`). With ``startup.expect_faults`` it waits
  for the complete schedule before it subscribes to the state. ``available_wheels`` and ``late_faults`` are in its status.
* a law with ``needs_wheel_momentum`` (seed 003's pointing laws) is called as
  ``control(t, q, w, h)`` with the wheels' momentum ``h`` of the SAME step: the node also
  subscribes to ``wheels/state`` (before ``state``, so the dynamics node, which publishes the wheel
  state only to matched subscribers, has matched it by the time it sees this controller's state
  subscription: one participant's endpoint announcements are processed in order), keeps the two
  per stamp in a small buffer and computes when both of a stamp are in, with
  ``h = sum_i a_i Js_i Ω_i`` (:meth:`~adcs_controllers.laws.allocation.WheelActuation.wheel_momentum`,
  the batch engine's function). Laws without the flag never see the wheel state.
* stops the run when it cannot answer a step (:class:`FlightSoftwareStop`: exit status 6 naming the
  node, the time and the error, :mod:`adcs_controllers.laws.failure`); a law refusing a state is
  counted, not a failure, unless it refuses three in a row.
"""
from __future__ import annotations

import numpy as np

from adcs_controllers.families import ControllerFamily, state_topic
from adcs_controllers.laws.base import LawOutputRejected
from adcs_controllers.laws.failure import FlightSoftwareError
from adcs_controllers.step import MOMENTUM, FlightStep
from adcs_msgs_py import cdr
from adcs_msgs_py import conversions as cv
from adcs_msgs_py import topics
from adcs_msgs_py.node import AdcsNode, FlightSoftwareFailed


class FlightSoftwareStop:
    """For a flight-software node: a step it cannot answer (:class:`FlightSoftwareError`, raised in
    a subscription callback, where the validation boundary would count it as a bad message) is
    kept, and :meth:`spin` returns from the executor's loop to stop the run with it
    (:class:`~adcs_msgs_py.node.FlightSoftwareFailed`, exit status 6): the lockstep graph then
    stops at once instead of waiting out ``lockstep.timeout`` at every later step."""

    failure: FlightSoftwareError | None = None
    #: A law refusing this many states in a row cannot answer: a refusal is for a singular state (Krstic-
    #: Tsiotras at 180 deg, a two-wheel law on q1^2 + q2^2 = 0), which the plant leaves at the next step
    #: under the timeout policy unless it rests there, and each refusal costs a lockstep timeout.
    MAX_REFUSALS_IN_A_ROW = 3
    refusals_in_a_row = 0

    def refused(self, t_ns: int, reason: str) -> None:
        """A law refused the state of ``t_ns`` (counted under ``law``); the MAX_REFUSALS_IN_A_ROW-th
        in a row is a FlightSoftwareError."""
        self.rejects.reject('law', reason)
        self.refusals_in_a_row += 1
        if self.refusals_in_a_row >= self.MAX_REFUSALS_IN_A_ROW:
            raise FlightSoftwareError(self.get_name(), t_ns, f'the law refused {self.refusals_in_a_row} states '
                                      f'in a row, the last: {reason}')

    def answer_step(self, step: int, answer, recorded) -> None:
        """``answer()`` the node's ``step``-th step (from 1) unless it is stopping; a
        FlightSoftwareError stops it (:meth:`failed`); then, after the answer (off its critical
        path), pace the recorder on the ``recorded`` publishers at the dynamics' pacing steps."""
        if self.failure is not None:   # stopping: no later step is answered
            return
        try:
            answer()
        except FlightSoftwareError as exc:
            self.failed(exc)
        finally:
            self.pace_recorder(step - 1, recorded, self.params['startup.timeout'])

    def failed(self, error: FlightSoftwareError) -> None:
        if self.failure is None:
            self.failure = error
            self.get_logger().error(str(error))

    def spin(self, executor) -> None:
        """Spin until shutdown, or until a step could not be answered (then FlightSoftwareFailed)."""
        while self.failure is None:
            executor.spin_once()
        raise FlightSoftwareFailed(f'{self.failure}; run stopped')


class StampPairs:
    """Pairs two messages of the same step by stamp, whichever arrives first (``state`` and
    ``wheels/state``): :meth:`add` returns the pair once both are here and drops the older
    stamps (they can no longer be answered); unpaired stamps are kept up to ``keep`` a side."""

    def __init__(self, keep: int = 8) -> None:
        self.keep = keep
        self.sides: tuple[dict, dict] = ({}, {})  # stamp -> value, side 0 and side 1

    def add(self, side: int, t_ns: int, value) -> tuple | None:
        self.sides[side][t_ns] = value
        if t_ns in self.sides[1 - side]:
            pair = (self.sides[0].pop(t_ns), self.sides[1].pop(t_ns))
            for pending in self.sides:
                for old in [s for s in pending if s < t_ns]:
                    del pending[old]
            return pair
        for pending in self.sides:
            while len(pending) > self.keep:
                del pending[min(pending)]
        return None


class WheelStatePairing:
    """For a node that needs the state and the wheel speeds of the same step: pairs ``state`` and
    ``wheels/state`` by stamp, whichever arrives first, and calls ``self.on_pair(t_ns, q, w,
    speed)`` once both are here. The node provides ``rejects``, ``wheel_names``, ``pairs`` (a
    :class:`StampPairs`) and ``wheel_state_cdr`` (a :class:`~adcs_msgs_py.cdr.JointStateCodec`:
    ``wheels/state`` is subscribed as bytes)."""

    def _pair_state(self, t_ns: int, q: np.ndarray, w: np.ndarray) -> None:
        self._paired(t_ns, self.pairs.add(0, t_ns, (q, w)))

    def _on_wheel_state(self, data: bytes) -> None:
        parsed = self.rejects.accept(topics.WHEELS_STATE, lambda: cv.wheel_speeds_from_msg(
            self.wheel_state_cdr.message(data), self.wheel_names))
        if parsed is not None:
            self._paired(parsed[0], self.pairs.add(1, *parsed))

    def _paired(self, t_ns: int, pair) -> None:
        if pair is not None:
            (q, w), speed = pair
            self.on_pair(t_ns, q, w, speed)


class ControllerNode(FlightSoftwareStop, WheelStatePairing, AdcsNode):
    """Base class of the controller nodes. Subclasses set ``family``
    (:class:`~adcs_controllers.families.ControllerFamily`): its schema validates the section, its law
    and actuation are built from it, the objects the batch engine builds too."""

    family: ControllerFamily

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        cls.schema = cls.family.schema

    def __init__(self, context) -> None:
        super().__init__(context)
        p = self.params
        # the flight step (adcs_controllers/step.py): the objects the batch engine drives too
        self.flight = FlightStep.build(self.get_name(), self.family, p)
        self.law, self.actuation = self.flight.law, self.flight.actuation
        self.wheel_names = self.actuation.wheel_names
        # one publisher and codec per command topic of the actuation (its command_messages)
        self.pub_cmds = {t: self.publisher(t) for t in self.actuation.command_topics}
        self.cmd_cdr = {t: cdr.command_codec(t) for t in self.actuation.command_topics}
        self.pub_status = self.publisher(topics.CONTROLLER_STATUS)
        self.state_topic = state_topic(p)   # state, or estimate/state (feedback: estimate)
        # Messages in and out as CDR bytes (adcs_msgs_py.cdr), through the same conversions' checks.
        self.state_cdr = cdr.StateCodec(self.state_topic)
        self.wheel_state_cdr = cdr.JointStateCodec(topics.WHEELS_STATE)
        self.sub_state = None
        self.states = 0  # steps computed (the acknowledgement pacing counts them)
        self.sub_wheels = None
        # the state paired with the wheel speeds of its step: for the law's h, or the allocation's
        self.pairs_wheels = self.flight.needs_wheel_speed
        self.pairs = StampPairs()  # (q, w) and the wheel speeds of one stamp
        self.faults = self.flight.faults   # fed from the wire; the flight step applies what is due
        self.wheel_index = {n: i for i, n in enumerate(self.wheel_names)}
        self.sub_faults = self.subscription(topics.FAULTS, self._on_faults)
        self._note(self.flight.note)

    def _note(self, note: str | None) -> None:
        if note:
            self.get_logger().info(note)

    # --- plumbing ---------------------------------------------------------------------------

    def connect(self, executor) -> None:
        """Wait for the command publishers to be matched (by the recorder's readers too: spinning
        ``executor``), then subscribe to the state."""
        recorder = 1 if self.params['startup.expect_recorder'] else 0
        self.wait_for_publishers({**{pub: 1 + recorder for pub in self.pub_cmds.values()},
                                  self.pub_status: recorder}, self.params['startup.timeout'])
        self.wait_recorder_matched([*self.pub_cmds.values(), self.pub_status], executor)
        if self.pairs_wheels:
            self.sub_wheels = self.subscription(topics.WHEELS_STATE, self._on_wheel_state, raw=True)
        self.sub_state = self.subscription(self.state_topic, self._on_state, raw=True)

    def run(self, executor) -> None:
        if self.params['startup.expect_faults']:
            self.wait_for_faults(executor)
        self.connect(executor)
        self.spin(executor)

    # --- faults -----------------------------------------------------------------------------

    def _on_faults(self, msg) -> None:
        parsed = self.rejects.accept(topics.FAULTS, lambda: cv.faults_from_msg(msg, self.wheel_index))
        if parsed is not None:
            self.faults.add(*parsed)

    def wait_for_faults(self, executor) -> None:
        """Spin until the complete fault schedule is here (before subscribing to the state)."""
        self.spin_until(executor, f'the fault schedule on {self.sub_faults.topic_name}',
                        lambda: self.faults.complete, self.params['startup.timeout'])

    # --- state -> command -------------------------------------------------------------------


    def _on_state(self, data: bytes) -> None:
        parsed = self.rejects.accept(self.state_topic, lambda: self.state_cdr.decode(data))
        if parsed is None:
            return
        t_ns, q, w = parsed
        if not self.pairs_wheels:
            self._step(t_ns, q, w)
            return
        self._pair_state(t_ns, q, w)

    def on_pair(self, t_ns: int, q: np.ndarray, w: np.ndarray, speed: np.ndarray) -> None:
        """Compute the step ``t_ns`` once its state and wheel speeds are both here (the flight step
        makes ``h = sum_i a_i Js_i Ω_i`` of them for a law that needs it)."""
        self._step(t_ns, q, w, speed)

    def _step(self, t_ns: int, q: np.ndarray, w: np.ndarray, speed: np.ndarray | None = None) -> None:
        self.states += 1
        self.answer_step(self.states, lambda: self._answer(t_ns, q, w, speed),
                         (*self.pub_cmds.values(), self.pub_status))

    def _answer(self, t_ns: int, q: np.ndarray, w: np.ndarray, speed: np.ndarray | None = None) -> None:
        """The flight step's answer to the state stamped ``t_ns`` (:meth:`FlightStep.step`), published:
        the commands, then the status."""
        try:  # a law refusing the state or giving a non-finite output: counted, nothing published
            out = self.flight.step(t_ns, q, w, speed, log=self.get_logger().info)
        except LawOutputRejected as exc:
            self.refused(t_ns, str(exc))
            return
        self.refusals_in_a_row = 0
        output, value, status, values, applied, extra = out
        if output == MOMENTUM:
            self.publish_commands(t_ns, self.actuation.momentum_messages(values))
        else:
            self.publish_commands(t_ns, self.actuation.command_messages(values))
        if self.pub_status.get_subscription_count():  # after the command: off the critical path
            status = self.law.with_mode_index(self.law.published_status(status))
            if output == MOMENTUM:  # h_x..: the wheel momentum commanded (speed mode)
                status.update({'h_x': value[0], 'h_y': value[1], 'h_z': value[2]})
            else:  # u_x.. what the actuators are commanded (saturated); demand_max: the law's |u|_inf
                status.update({'u_x': applied[0], 'u_y': applied[1], 'u_z': applied[2],
                               'demand_max': float(np.max(np.abs(value)))})
            status.update(extra)   # the actuation's own (seed 002: the wheel, the firings)
            status['rejected_messages'] = self.rejects.total
            status.update(self.actuation.usable_status())
            status['late_faults'] = self.faults.late
            self.pub_status.publish(cdr.status_bytes(t_ns, self.get_name(), status))

    def publish_commands(self, t_ns: int, messages) -> None:
        """Send the actuation's command messages (:meth:`~adcs_controllers.laws.allocation.Actuation.command_messages`
        ``(topic, joint names or None, field, values)``) stamped ``t_ns``: the bytes of
        ``wheel_cmd_to_msg`` / ``thruster_cmd_to_msg`` (joint names) or ``vector_to_msg``."""
        for topic, joints, field, values in messages:
            codec = self.cmd_cdr[topic]
            data = codec.encode(t_ns, values) if joints is None else codec.encode(t_ns, joints, **{field: values})
            self.pub_cmds[topic].publish(data)
