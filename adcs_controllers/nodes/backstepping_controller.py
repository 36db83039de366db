"""BacksteppingController: seed 002's quaternion integrator backstepping on the graph.

The law (:class:`adcs_controllers.laws.backstepping.BacksteppingLaw`, eq. 22-35, with the section
4.2 reference: the target relative to the orbit frame at t = 0, then held inertially) and the
actuation (:class:`~adcs_controllers.laws.backstepping.ThrusterActuation`: eq. 20-21 pseudo-inverse
allocation over four thrusters and the pitch wheel, bang-bang firing with a deadzone) are its
family's (:data:`adcs_controllers.families.BACKSTEPPING`), the objects the batch engine runs.

Per step ``t_k`` the allocation needs the state (``state``) and the wheel speed
(``wheels/state``): the node pairs the two messages by stamp, whichever arrives first, then
publishes ``thrusters/cmd`` (on-times for ``[t_k, t_k+1]``) and ``wheels/cmd`` (motor torque),
both stamped ``t_k``, and ``controller/status`` with V1, V2 (eq. 27, 31), W (eq. 33), η̃, the
eigenaxis error, the torque the commands ask for (u_x, u_y, u_z), the number of thrusters firing
and the firing count so far (thruster-periods).
"""
from __future__ import annotations

import math

import numpy as np

from adcs_controllers.families import BACKSTEPPING, state_topic
from adcs_controllers.laws.base import LawOutputRejected, checked_control
from adcs_controllers.laws.failure import answer
from adcs_controllers.nodes.base import FlightSoftwareStop, StampPairs, WheelStatePairing
from adcs_core.faults import FaultTracker
from adcs_msgs_py import cdr
from adcs_msgs_py import conversions as cv
from adcs_msgs_py import topics
from adcs_msgs_py.node import AdcsNode, entry_point


class BacksteppingController(FlightSoftwareStop, WheelStatePairing, AdcsNode):
    family = BACKSTEPPING  # law: BacksteppingLaw, actuation: ThrusterActuation
    schema = BACKSTEPPING.schema

    def __init__(self, context) -> None:
        super().__init__(context)
        p = self.params
        self.law, self.actuation = self.family.build(p)
        self.thruster_names = self.actuation.thruster_names
        self.wheel_names = self.actuation.wheel_names
        self.pub_thrusters = self.publisher(topics.THRUSTERS_CMD)
        self.pub_wheels = self.publisher(topics.WHEELS_CMD)
        self.pub_status = self.publisher(topics.CONTROLLER_STATUS)
        self.sub_state = self.sub_wheel_state = None
        self.state_topic = state_topic(p)   # state, or estimate/state (feedback: estimate)
        # Messages in and out as CDR bytes (adcs_msgs_py.cdr), through the same conversions' checks.
        self.state_cdr = cdr.StateCodec(self.state_topic)
        self.wheel_state_cdr = cdr.JointStateCodec(topics.WHEELS_STATE)
        self.thrusters_cdr = cdr.JointStateCodec(topics.THRUSTERS_CMD)
        self.wheels_cdr = cdr.JointStateCodec(topics.WHEELS_CMD)
        self.pairs = StampPairs()  # (q, w) and the wheel speed of one stamp
        self.firings = 0        # thruster-periods fired so far
        self.steps = 0          # steps answered (the acknowledgement pacing counts them)
        # Faults name wheels only (the fault injector's actuators); followed for the late count.
        self.faults = FaultTracker()
        self.sub_faults = self.subscription(topics.FAULTS, self._on_faults)

    def _on_faults(self, msg) -> None:
        known = {n: i for i, n in enumerate(self.wheel_names)}
        parsed = self.rejects.accept(topics.FAULTS, lambda: cv.faults_from_msg(msg, known))
        if parsed is not None:
            self.faults.add(*parsed)

    def connect(self) -> None:
        """Wait for both command publishers to be matched, then subscribe to the state and the
        wheel state."""
        recorder = 1 if self.params['startup.expect_recorder'] else 0
        self.wait_for_publishers({self.pub_thrusters: 1 + recorder, self.pub_wheels: 1 + recorder,
                                  self.pub_status: recorder}, self.params['startup.timeout'])
        self.sub_wheel_state = self.subscription(topics.WHEELS_STATE, self._on_wheel_state, raw=True)
        self.sub_state = self.subscription(self.state_topic, self._on_state, raw=True)

    def run(self, executor) -> None:
        if self.params['startup.expect_faults']:
            self.spin_until(executor, f'the fault schedule on {self.sub_faults.topic_name}',
                            lambda: self.faults.complete, self.params['startup.timeout'])
        self.connect()
        self.spin(executor)

    # --- pairing ------------------------------------------------------------------------------

    def _on_state(self, data: bytes) -> None:
        parsed = self.rejects.accept(self.state_topic, lambda: self.state_cdr.decode(data))
        if parsed is not None:
            self._pair_state(*parsed)

    def on_pair(self, t_ns: int, q: np.ndarray, w: np.ndarray, speed: np.ndarray) -> None:
        self.step(t_ns, q, w, speed)

    # --- state -> commands ----------------------------------------------------------------

    def step(self, t_ns: int, q: np.ndarray, w: np.ndarray, speed: np.ndarray) -> None:
        self.steps += 1
        self.answer_step(self.steps, lambda: self._answer(t_ns, q, w, speed),
                         (self.pub_thrusters, self.pub_wheels, self.pub_status))

    def _answer(self, t_ns: int, q: np.ndarray, w: np.ndarray, speed: np.ndarray) -> None:
        """Compute and publish the commands (and the status) of the state stamped ``t_ns``."""
        # Faults name wheels only and the law does not reconfigure: the snapshot due at t_ns is
        # only taken (FaultTracker.due), so that one arriving after its step counts as late.
        self.faults.due(t_ns)
        name = self.get_name()
        try:  # a law refusing the state or giving a non-finite output: counted, nothing published
            tau, status = answer(name, t_ns, lambda: checked_control(self.law, name, t_ns / cv.NS_PER_S, q, w),
                                 refusals=(LawOutputRejected,))
        except LawOutputRejected as exc:
            self.refused(t_ns, str(exc))
            return
        self.refusals_in_a_row = 0
        on_time, wheel_torque, info = answer(name, t_ns, lambda: self.actuation.command(tau, w, speed))
        # the bytes of thruster_cmd_to_msg and wheel_cmd_to_msg(..., effort=...)
        self.pub_thrusters.publish(self.thrusters_cdr.encode(t_ns, self.thruster_names, effort=on_time))
        self.pub_wheels.publish(self.wheels_cdr.encode(t_ns, self.wheel_names, effort=wheel_torque))
        fired = int(np.count_nonzero(on_time > 0.0))
        self.firings += fired
        if self.pub_status.get_subscription_count():  # after the commands: off the critical path
            qe = status['q_err']
            alloc = self.actuation.allocation
            # the torque the firing and the wheel command ask of the actuators (as if each fired
            # thruster gave its full force over the period): u_x.. of the torque figure
            u = alloc.B[:, :alloc.n] @ (on_time / alloc.period * alloc.max_force) \
                - alloc.wheel_axis * wheel_torque[0]
            values = {'mode': self.law.mode_names[int(status['mode'])],
                      'V1': float(status['V1']), 'V2': float(status['V2']), 'W': float(status['W']),
                      'eta_err': float(qe[3]), 'angle_deg': math.degrees(float(status['angle'])),
                      'u_x': float(u[0]), 'u_y': float(u[1]), 'u_z': float(u[2]),
                      'demand_max': float(np.max(np.abs(tau))),
                      'wheel_torque': float(wheel_torque[0]), 'wheel_free': str(bool(info['wheel_free'])).lower(),
                      'firing_now': fired, 'firing_count': self.firings,
                      'rejected_messages': self.rejects.total, 'late_faults': self.faults.late}
            self.pub_status.publish(cdr.status_bytes(t_ns, self.get_name(), values))


main = entry_point(BacksteppingController)

if __name__ == '__main__':
    main()
