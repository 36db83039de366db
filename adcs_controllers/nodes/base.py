"""The controller-node template: state in, law out, command stamped with the state's stamp.

A concrete controller implements :meth:`ControllerNode.control` (arrays in, body torque out,
plus status values) and nothing ROS-specific. The base class

* validates parameters (schema), builds the wheel allocation over the available wheels;
* publishes commands on ``wheels/cmd`` (minimum-norm allocation, saturation) or ``torque_cmd``;
* before subscribing to ``state``, waits until its command publisher is matched by the dynamics
  node (and the recorder, when one is expected) — so by the time the dynamics node sees this
  controller subscribed, every command it sends will be delivered and recorded;
* rejects, counts and warns about bad messages, and publishes ``controller/status`` each step.
"""
from __future__ import annotations

import numpy as np

from adcs_msgs_py import conversions as cv
from adcs_msgs_py import topics
from adcs_msgs_py.guard import RejectCounter
from adcs_controllers.laws.allocation import saturate, wheel_allocation_matrix
from adcs_sim.nodes.base import AdcsNode
from adcs_sim.scenario import inertia_matrix


class ControllerNode(AdcsNode):
    """Base class of the controller nodes. Subclasses set ``schema`` and implement ``control``."""

    def __init__(self, context) -> None:
        super().__init__(context)
        p = self.params
        self.inertia = inertia_matrix(p['inertia']) if 'inertia' in p else None
        self.actuator = p['actuator']
        self.rejects = RejectCounter(self.get_logger())
        if self.actuator == 'wheels':
            names = p['wheels.names']
            self.wheel_names = list(names)
            self.wheel_axes = np.asarray(p['wheels.axes'], dtype=float).reshape(len(names), 3)
            self.wheel_axes /= np.linalg.norm(self.wheel_axes, axis=1, keepdims=True)
            self.wheel_limit = np.asarray(p['wheels.max_torque'], dtype=float)
            self.available = np.ones(len(names), dtype=bool)
            self.allocation = wheel_allocation_matrix(self.wheel_axes, self.available)
        self.pub_cmd = self.publisher(topics.WHEELS_CMD if self.actuator == 'wheels' else topics.TORQUE_CMD)
        self.pub_status = self.publisher(topics.CONTROLLER_STATUS)
        self.sub_state = None

    # --- to implement -----------------------------------------------------------------------

    def control(self, t: float, q: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, dict]:
        """Desired body torque (N m) and status values for state (q, w) at time t."""
        raise NotImplementedError

    # --- plumbing ---------------------------------------------------------------------------

    def connect(self) -> None:
        """Wait for the command publisher to be matched, then subscribe to the state."""
        recorder = 1 if self.params['startup.expect_recorder'] else 0
        self.wait_for_publishers({self.pub_cmd: 1 + recorder, self.pub_status: recorder},
                                 self.params['startup.timeout'])
        self.sub_state = self.subscription(topics.STATE, self._on_state)

    def run(self, executor) -> None:
        self.connect()
        executor.spin()

    def _on_state(self, msg) -> None:
        parsed = self.rejects.accept(topics.STATE, lambda: cv.state_from_msg(msg))
        if parsed is None:
            return
        t_ns, q, w = parsed
        torque, status = self.control(t_ns / cv.NS_PER_S, q, w)
        applied = self.publish_torque(t_ns, torque)
        if self.pub_status.get_subscription_count():  # after the command: off the critical path
            status.update({'u_x': applied[0], 'u_y': applied[1], 'u_z': applied[2],
                           'rejected_messages': self.rejects.total})
            self.pub_status.publish(cv.status_to_msg(t_ns, self.get_name(), status))

    def publish_torque(self, t_ns: int, torque: np.ndarray) -> np.ndarray:
        """Send body torque ``torque`` through the configured actuators; return what it commands.

        Wheels: minimum-norm motor torques over the available wheels, then saturation; the
        returned body torque is what the saturated wheel torques produce.
        """
        if self.actuator == 'wheels':
            tau = saturate(self.allocation @ torque, self.wheel_limit, self.params['saturation'])
            self.pub_cmd.publish(cv.wheel_cmd_to_msg(t_ns, self.wheel_names, effort=tau))
            return -(tau @ self.wheel_axes)
        limit = self.params['torquers.max_torque']
        applied = saturate(torque, np.full(3, limit), self.params['saturation'])
        self.pub_cmd.publish(cv.vector_to_msg(t_ns, applied))
        return applied
