"""Dynamics node: owns the plant and the simulated clock.

Lockstep (default, deterministic): for each step ``k`` it publishes ``state``, ``wheels/state`` (and
``truth/state`` when noise is on) and ``/clock`` stamped ``t_k`` (``/clock`` and the viewer
topics only to live subscribers: the recorder writes its own from the state and the latched
``dynamics/recording`` this node sends before ``t_0``, :mod:`adcs_msgs_py.recorded_topics`),
waits until every awaited command topic has delivered a command stamped ``t_k``, publishes the
applied control torque, and integrates ``[t_k, t_k+1]`` holding the commands (zero-order hold,
fixed-step RK4). A step whose commands do not arrive within ``lockstep.timeout`` wall seconds is a
*missed step*: the declared policy (hold the last command, or zero) applies and the miss is
counted on ``dynamics/status``.
Commands stamped for another step are counted as stale and ignored. ``link_faults.drop`` /
``link_faults.delay`` make a seeded fraction of the steps lose their commands or get them late
(:mod:`adcs_sim.truth.link_faults`): missed steps under the same policy, deterministic.

Thrusters (seed 002): a ``thrusters/cmd`` stamped ``t_k`` gives each thruster's on-time from
``t_k``; the node builds the valve command for ``[t_k, t_k+1]`` from it
(:meth:`adcs_sim.truth.thrusters.Thrusters.command`: clipped to the period, minimum on-time rule) and
integrates with :func:`adcs_sim.truth.thrusters.step_pulsed` (RK4 split at the pulse edges; exactly
:meth:`Plant.step` when no edge falls inside the period). After each step it publishes
``thrusters/state`` stamped ``t_k``: thrust at ``t_k``, the on-time applied, and the cumulated
impulse at ``t_k+1``. On a missed step the policy holds the last on-times or fires none.

Realtime mode paces the same loop against the wall clock (``real_time_factor``) with no waiting:
each step uses the latest commands received.

Faults: the node subscribes to the latched ``faults`` topic (the fault injector publishes its
whole schedule at start, each array stamped with its due time; :mod:`adcs_core.faults`). With
``startup.expect_faults`` it waits before t = 0 until it holds the complete schedule; at each
step ``t_k`` it applies the latest fault state stamped ``<= t_k`` to the wheels
(:meth:`~adcs_sim.truth.plant.ReactionWheels.apply_fault`) *before* publishing the step's state and
integrating ``[t_k, t_k+1]``, so a fault stamped ``t_k`` shows in ``wheels/state`` at ``t_k``
and acts over exactly that interval. A fault state received after its step is applied at the
next step and counted as ``late_faults`` on ``dynamics/status``.

Sensors (``sensors.*``, :mod:`adcs_sim.truth.sensor_schema`): each step, after ``state`` and
``truth/state`` (always published when a sensor is fitted), the node measures the true state with its
:class:`~adcs_sim.truth.sensor_suite.SensorSuite` and publishes every fitted sensor's reading on its
``sensors/*`` topic stamped ``t_k`` (:mod:`adcs_msgs_py.conversions_determination`), valid or not;
sensor faults of the schedule are applied at their step like the wheel faults. Before t = 0 it waits
for ``startup.sensor_subscribers`` matched subscribers on each sensor topic (-1: the recorder's).
With ``environment.enabled`` the node samples the environment (:mod:`adcs_core.environment`: orbit,
Sun, eclipse, IGRF or dipole field) at each ``t_k`` and gives the sensors their inputs
(:func:`adcs_sim.truth.sensor_suite.sensor_environment`); without it the star tracker has no exclusion
and the sun sensor and magnetometer are refused by the schema.

The node exits with status 0 when ``duration`` is reached, after the last messages are
acknowledged by their subscribers.
"""
from __future__ import annotations

import time

import numpy as np
from std_msgs.msg import String

from adcs_core.orbit import CircularOrbit
from adcs_msgs_py import cdr, topics
from adcs_msgs_py import conversions as cv
from adcs_msgs_py import conversions_determination as cd
from adcs_msgs_py.guard import IntrusionDetected
from adcs_msgs_py.names import (
    MARKERS,
    MARKERS_STATIC,
    RECORDED_VISUAL_TOPICS,
    RECORDING_CONFIG,
)
from adcs_msgs_py.node import AdcsNode, RunStopped, main_for
from adcs_msgs_py.recorded_topics import config_text
from adcs_msgs_py.sensor_interfaces import SENSOR_TOPICS
from adcs_msgs_py.visual import VisualMessages
from adcs_sim.truth.link_faults import DELAY, FATE_NAMES, OK, LinkFaults
from adcs_sim.truth.plant import WheelCommand
from adcs_sim.truth.schema import DYNAMICS_SCHEMA, command_topics
from adcs_sim.truth.step import TruthStep

# The plant's command key of each command topic (thrusters/cmd is held as on-times: self.on_time).
COMMAND_KEYS = {topics.WHEELS_CMD: 'wheels', topics.TORQUE_CMD: 'torquers'}
# Each sensor's topic and message conversion (adcs_msgs_py.measurements.SENSORS names).
SENSOR_OUTPUTS = {name: (SENSOR_TOPICS[name], codec.to_msg) for name, codec in cd.SENSOR_CODECS.items()}


class DynamicsNode(AdcsNode):
    schema = DYNAMICS_SCHEMA

    def __init__(self, context) -> None:
        super().__init__(context)
        p = self.params
        # the truth step (adcs_sim/truth/step.py): the objects the batch engine drives too
        self.truth = truth = TruthStep(p, warm=False)   # the plant is warmed in run(), once the endpoints exist
        self.plant, self.measurement, self.sensors = truth.plant, truth.measurement, truth.sensors
        self.wheels, self.thrusters = truth.wheels, truth.thrusters
        self.x = truth.initial_state()
        self.commands = self.plant.zero_commands()
        self.period_ns, self.n_steps, self.period = truth.period_ns, truth.n_steps, truth.period
        self.lockstep = p['mode'] == 'lockstep'
        self.awaited = command_topics(p) if self.lockstep else []
        self.wheel_index = {name: i for i, name in enumerate(self.wheels.names)} if self.wheels else {}
        self.thruster_index = ({name: i for i, name in enumerate(self.thrusters.names)}
                               if self.thrusters else {})
        self.on_time = np.zeros(len(self.thruster_index))  # held thruster on-times (s)

        self.missed_steps = 0
        self.stale_commands = 0
        self.step_ns = 0
        self.received: set[str] = set()
        self.link = LinkFaults(p['link_faults.seed'], p['link_faults.drop'], p['link_faults.delay'],
                               self.n_steps)
        self._late = 0   # commands of the previous step that the link delayed past its deadline

        self.pub_recording = self.publisher(RECORDING_CONFIG)   # before /clock: recorded_topics.py
        self.pub_clock = self.publisher(topics.CLOCK)
        self.pub_state = self.publisher(topics.STATE)
        truth = self.measurement.active or self.sensors is not None
        self.pub_truth = self.publisher(topics.TRUTH_STATE) if truth else None
        self.pub_sensors = {name: self.publisher(SENSOR_OUTPUTS[name][0])
                            for name in (self.sensors.fitted() if self.sensors else ())}
        self.pub_wheels = self.publisher(topics.WHEELS_STATE) if self.wheels else None
        self.pub_applied = self.publisher(topics.APPLIED_TORQUE)
        self.pub_thrusters = self.publisher(topics.THRUSTERS_STATE) if self.thrusters else None
        self.pub_status = self.publisher(topics.DYNAMICS_STATUS)
        self._step_publishers = [p for p in (self.pub_clock, self.pub_state, self.pub_truth,
                                             self.pub_wheels) if p is not None]
        self._step_publishers += list(self.pub_sensors.values())
        self._codecs()
        self.visual, self.pub_visual = self._visual_setup(p)
        self._visual_speed = None   # wheel speeds at the start of the step being integrated

        self.subs = {}
        if self.wheels:
            self.subs[topics.WHEELS_CMD] = self.subscription(topics.WHEELS_CMD, self._on_wheel_cmd, raw=True)
        if 'torquers' in self.plant.slices:
            self.subs[topics.TORQUE_CMD] = self.subscription(topics.TORQUE_CMD, self._on_torque_cmd, raw=True)
        if self.thrusters:
            self.subs[topics.THRUSTERS_CMD] = self.subscription(topics.THRUSTERS_CMD, self._on_thruster_cmd,
                                                                raw=True)
        self.faults = self.truth.faults   # fed from the wire; the truth step applies what is due
        self.sub_faults = self.subscription(topics.FAULTS, self._on_faults)

    def _codecs(self) -> None:
        """The hot messages go out as CDR bytes (:mod:`adcs_msgs_py.cdr`: templates made once, the
        numbers written in) and the commands come in as bytes, read by the same codecs."""
        self._state_cdr = cdr.StateCodec(topics.STATE)
        self._clock_cdr = cdr.ClockCodec()
        self._wheels_cdr = cdr.JointStateCodec(topics.WHEELS_STATE)
        self._thrusters_cdr = cdr.JointStateCodec(topics.THRUSTERS_STATE)
        self._cmd_cdr = {t: cdr.command_codec(t) for t in (topics.WHEELS_CMD, topics.THRUSTERS_CMD, topics.TORQUE_CMD)}
        self._applied_cdr = cdr.VectorCodec(topics.APPLIED_TORQUE)

    def _visual_setup(self, p) -> tuple[VisualMessages | None, dict]:
        """The viewer messages (adcs_msgs_py/visual.py) and their publishers, if enabled."""
        if not p['visualization.enabled']:
            return None, {}
        w, th, orbit = self.wheels, self.thrusters, self.plant.orbit
        orbit = orbit if isinstance(orbit, CircularOrbit) else None   # an SGP4 orbit has no fixed frame rate
        visual = VisualMessages(p['visualization.target_attitude'], p['visualization.axis_length'],
                                *((w.axes, w.spin_inertia, w.max_speed) if w else (None, None, None)),
                                *((th.positions, th.directions) if th else (None, None)), orbit=orbit)
        return visual, {t: self.publisher(t) for t in visual.topics}

    def recording_config(self) -> str:
        """What the recorder writes itself (``dynamics/recording``, adcs_msgs_py/recorded_topics.py):
        /clock from the state's stamps, the viewer topics from the true attitude's topic."""
        attitude = topics.TRUTH_STATE if self.pub_truth is not None else topics.STATE
        return config_text(topics.STATE, self.visual, attitude,
                           [t for t in RECORDED_VISUAL_TOPICS if t in self.pub_visual])

    # --- faults -----------------------------------------------------------------------------

    def _on_faults(self, msg) -> None:
        parsed = self.rejects.accept(topics.FAULTS, lambda: cv.faults_from_msg(msg, self.wheel_index))
        if parsed is not None:
            self.faults.add(*parsed)

    def apply_due_faults(self) -> None:
        """Apply the fault state due at the current step (if it changed): :meth:`TruthStep.apply_due_faults`."""
        applied = self.truth.apply_due_faults(self.step_ns)
        if applied is None:
            return
        wheels, sensors = applied
        t = self.step_ns / cv.NS_PER_S
        if sensors and self.sensors is not None:
            faulty = {n: f.mode for n, f in sensors.items() if f.mode not in ('nominal', 'recovered')}
            self.get_logger().info(f't = {t:g} s: sensor faults {faulty or "none"}')
        if self.wheels is None or not wheels:
            return
        faulty = {n: m for n, m in zip(self.wheels.names, self.wheels.modes) if m != 'nominal'}
        self.get_logger().info(f't = {t:g} s: wheel faults {faulty or "none"}')

    def wait_for_faults(self, executor) -> None:
        """Spin until the complete fault schedule is here (``startup.expect_faults``)."""
        self.spin_until(executor, f'the fault schedule on {self.sub_faults.topic_name}',
                        lambda: self.faults.complete, self.params['startup.timeout'])

    # --- commands ---------------------------------------------------------------------------

    def _accept_stamp(self, topic: str, t_ns: int) -> bool:
        if self.lockstep and t_ns != self.step_ns:
            self.stale_commands += 1
            return False
        self.received.add(topic)
        return True

    def _on_wheel_cmd(self, data: bytes) -> None:
        codec = self._cmd_cdr[topics.WHEELS_CMD]
        parsed = self.rejects.accept(topics.WHEELS_CMD,
                                     lambda: cv.wheel_cmd_from_msg(codec.message(data), self.wheel_index))
        if parsed is None:
            return
        t_ns, index, values, mode = parsed
        if not self._accept_stamp(topics.WHEELS_CMD, t_ns):
            return
        old = self.commands['wheels']
        value, speed_mode = old.value.copy(), old.speed_mode.copy()
        value[index] = values
        speed_mode[index] = mode == 'speed'
        self.commands['wheels'] = WheelCommand(value, speed_mode)

    def _on_torque_cmd(self, data: bytes) -> None:
        parsed = self.rejects.accept(topics.TORQUE_CMD, lambda: self._cmd_cdr[topics.TORQUE_CMD].decode(data))
        if parsed is None:
            return
        t_ns, torque = parsed
        if self._accept_stamp(topics.TORQUE_CMD, t_ns):
            self.commands['torquers'] = torque

    def _on_thruster_cmd(self, data: bytes) -> None:
        codec = self._cmd_cdr[topics.THRUSTERS_CMD]
        parsed = self.rejects.accept(topics.THRUSTERS_CMD,
                                     lambda: cv.thruster_cmd_from_msg(codec.message(data), self.thruster_index))
        if parsed is None:
            return
        t_ns, index, on_time = parsed
        if not self._accept_stamp(topics.THRUSTERS_CMD, t_ns):
            return
        value = np.zeros(self.thrusters.count)  # thrusters the command does not name stay off
        value[index] = on_time
        self.on_time = value

    def _integrate(self, t: float) -> np.ndarray:
        """Advance the plant over ``[t, t + period]`` holding the commands; returns the applied
        control torque at ``t`` (:meth:`TruthStep.integrate`; with thrusters it sets the valve command)."""
        if self.visual is not None and self.wheels is not None:
            self._visual_speed = self.x[self.plant.slices['wheels']][:self.wheels.count].copy()
        self.x, torque = self.truth.integrate(t, self.x, self.commands, self.on_time)
        return torque

    def publish_thrusters(self, t: float, t_ns: int) -> None:
        """``thrusters/state`` of the step just integrated (stamp ``t_ns`` = its start)."""
        if self.pub_thrusters is None or not self.pub_thrusters.get_subscription_count():
            return
        cmd = self.commands['thrusters']
        self.pub_thrusters.publish(self._thrusters_cdr.encode(   # thruster_state_to_msg's bytes
            t_ns, self.thrusters.names, self.x[self.plant.slices['thrusters']], cmd.on_time,
            self.thrusters.forces(t, cmd)))

    # --- publishing -----------------------------------------------------------------------

    def publish_visual_state(self, t_ns: int, q) -> None:
        """frames/* and error/* of the true attitude at ``t_ns``, to what is subscribed."""
        live = {t: pub for t, pub in self.pub_visual.items() if pub.get_subscription_count()}
        for topic, data in self.visual.attitude_cdr(t_ns, q, live):
            live[topic].publish(data)

    def publish_markers(self, t_ns: int) -> None:
        """markers of the step just integrated (stamp ``t_ns`` = its start): the wheel momentum at
        its start, the thrusters that fired in it."""
        pub = self.pub_visual.get(MARKERS)
        if pub is None or not pub.get_subscription_count():
            return
        on_time = self.commands['thrusters'].on_time if self.thrusters is not None else ()
        pub.publish(self.visual.marker_array_cdr(t_ns, self._visual_speed, on_time))   # marker_array's bytes

    def publish_state(self) -> None:
        t_ns = self.step_ns
        x = self.x
        q, w = x[:4], x[4:7]
        # The state first: the controllers start computing while the rest goes out.
        q_m, w_m = self.truth.measure_state(x)
        self.pub_state.publish(self._state_cdr.encode(t_ns, q_m, w_m))   # state_to_msg's bytes
        # Then what other controllers and estimators answer from (a wheel-momentum law pairs the
        # state with wheels/state), then what is only recorded or observed: not even built when
        # nobody subscribes.
        if self.wheels is not None and self.pub_wheels.get_subscription_count():
            xa = x[self.plant.slices['wheels']]
            n = self.wheels.count
            speed = xa[:n]
            torque = self.wheels.motor_torque(speed, self.commands['wheels'])
            self.pub_wheels.publish(self._wheels_cdr.encode(t_ns, self.wheels.names, xa[n:], speed, torque))
        self.publish_sensors(t_ns, x)
        if self.pub_clock.get_subscription_count():
            self.pub_clock.publish(self._clock_cdr.encode(t_ns))
        if self.pub_truth is not None and self.pub_truth.get_subscription_count():
            self.pub_truth.publish(self._state_cdr.encode(t_ns, q, w))
        if self.visual is not None:
            self.publish_visual_state(t_ns, q)

    def publish_sensors(self, t_ns: int, x: np.ndarray) -> None:
        """Every fitted sensor's reading of the true state at ``t_ns`` (:meth:`TruthStep.read_sensors`:
        measured every step, whoever listens: the noise streams advance by step, not by subscriber)."""
        if self.sensors is None:
            return
        m = self.truth.read_sensors(t_ns // self.period_ns, t_ns / cv.NS_PER_S, x)
        for name, pub in self.pub_sensors.items():
            pub.publish(SENSOR_OUTPUTS[name][1](t_ns, getattr(m, name)))

    def publish_status(self, final: bool = False) -> None:
        values = {'step': self.step_ns // self.period_ns if self.period_ns else 0,
                  'missed_steps': self.missed_steps, 'stale_commands': self.stale_commands,
                  'rejected_messages': self.rejects.total, 'final': str(final).lower(),
                  'awaited_commands': ','.join(self.awaited) or 'none', 'mode': self.params['mode'],
                  'late_faults': self.faults.late}
        if self.link.active:
            values.update({'link_lost_steps': self.link.dropped, 'link_late_steps': self.link.delayed})
        level = 'WARN' if self.missed_steps else 'OK'
        self.pub_status.publish(cdr.status_bytes(self.step_ns, 'dynamics', values, level))

    # --- main loop ------------------------------------------------------------------------

    def wait_for_graph(self, executor) -> None:
        p = self.params
        timeout = p['startup.timeout']
        recorder = 1 if p['startup.expect_recorder'] else 0
        for topic in self.awaited:
            sub = self.subs[topic]
            self.wait_for(f'a controller publishing {sub.topic_name}',
                          lambda s=sub: s.get_publisher_count() >= 1, timeout, endpoints=[sub])
        state_subs = p['startup.state_subscribers']
        if state_subs < 0:
            state_subs = (1 if self.awaited else 0) + recorder
        required = {self.pub_state: state_subs}
        # /clock and the per-step viewer topics: the recorder writes its own (adcs_msgs_py/recorded_topics.py)
        visual = [pub for t, pub in self.pub_visual.items() if t not in RECORDED_VISUAL_TOPICS]
        for pub in (self.pub_recording, self.pub_truth, self.pub_wheels, self.pub_applied, self.pub_status,
                    self.pub_thrusters, *visual):
            if pub is not None:
                required[pub] = max(required.get(pub, 0), recorder)
        sensor_subs = p['startup.sensor_subscribers']
        for pub in self.pub_sensors.values():
            required[pub] = recorder if sensor_subs < 0 else sensor_subs
        if topics.THRUSTERS_CMD in self.awaited and self.pub_wheels is not None:
            # A thruster + wheel controller (seed 002) allocates with the wheel speed: it answers
            # a step only with that step's wheels/state, so that must reach it from t = 0.
            required[self.pub_wheels] = max(required.get(self.pub_wheels, 0), 1 + recorder)
        self.wait_for_publishers(required, timeout)
        self.wait_recorder_matched([pub for pub, n in required.items() if n >= recorder > 0], executor)

    def run(self, executor) -> None:
        self.plant.warm()   # loads the compiled kernel while discovery matches the endpoints
        self.wait_for_graph(executor)
        if self.params['startup.expect_faults']:
            self.wait_for_faults(executor)
        self.get_logger().info(
            f'{self.params["mode"]} run: {self.n_steps} steps of {self.period:g} s, '
            f'waiting for {self.awaited or "no commands"}')
        self.publish_status()
        # latched, once before t = 0: what the recorder writes itself, the static markers; it has
        # them before the state of t = 0
        self.pub_recording.publish(String(data=self.recording_config()))
        latched = [self.pub_recording]
        if MARKERS_STATIC in self.pub_visual:
            self.pub_visual[MARKERS_STATIC].publish(self.visual.static_markers(0))
            latched.append(self.pub_visual[MARKERS_STATIC])
        if self.params['startup.expect_recorder']:
            self.wait_acked(latched, self.params['startup.timeout'])
        timeout = self.params['lockstep.timeout']
        pace = self.period / self.params['real_time_factor']
        wall0 = time.monotonic()
        self.step_ns = 0
        self.apply_due_faults()
        self.publish_state()
        for k in range(self.n_steps):
            if self.lockstep:
                held = self._link_before(k)
                self._wait_commands(executor, timeout)
                self._link_after(k, held)
            else:
                self._spin_until(executor, wall0 + k * pace)
            self.apply_due_faults()  # one that arrived while waiting (late unless stamped t_k)
            t = self.step_ns / cv.NS_PER_S
            torque = self._integrate(t)
            self._stop_if_not_finite(t, torque)
            self.step_ns = (k + 1) * self.period_ns
            self.received.clear()
            self.apply_due_faults()
            # Next state out first (the controllers' critical path), then the record of this step.
            self.publish_state()
            if self.pub_applied.get_subscription_count():
                self.pub_applied.publish(self._applied_cdr.encode(k * self.period_ns, torque))   # vector_to_msg's bytes
            self.publish_thrusters(t, k * self.period_ns)
            if self.visual is not None:
                self.publish_markers(k * self.period_ns)
        loop_s = time.monotonic() - wall0   # the stepping loop alone (benchmarks/showcase_graph.py)
        self.publish_status(final=True)
        self._drain_acks()
        self.get_logger().info(f'done at t = {self.step_ns / cv.NS_PER_S:g} s; '
                               f'missed steps: {self.missed_steps}; stepping loop {loop_s:.3f} s')

    def _stop_if_not_finite(self, t: float, torque) -> None:
        """A state that is no longer finite ends the run (status published first): every later
        step would only wait out the controllers' refusal of it."""
        failure = self.truth.failure(t, self.x, torque)
        if failure is not None:
            self.publish_status(final=True)
            self._drain_acks()
            raise RunStopped(f'{failure}; run stopped')

    def _wait_commands(self, executor, timeout: float) -> None:
        awaited = self.awaited
        if awaited:
            deadline = time.monotonic() + timeout
            while not self.received.issuperset(awaited):
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    self._missed()
                    break
                executor.spin_once(timeout_sec=remaining)
        # The controllers answering is not enough when a recorder listens (pace_recorder); in
        # free flight nothing else paces the loop, so wait for the acknowledgements every step.
        recorded = self._step_publishers + [self.pub_applied, self.pub_thrusters, *self.pub_visual.values()]
        if awaited:   # blocking: a spin here could apply a command of this step that missed its deadline
            self.pace_recorder(self.step_ns // self.period_ns, recorded, timeout)
        else:   # free flight: no command to take, so spin for a recorder in this process (wait_acked)
            self.wait_acked(recorded, timeout, executor)
            executor.spin_once(timeout_sec=0.0)

    def _missed(self) -> None:
        self.missed_steps += 1
        missing = sorted(set(self.awaited) - self.received)
        self.get_logger().warning(
            f'step t = {self.step_ns / cv.NS_PER_S:g} s: no command on {missing} within '
            f'{self.params["lockstep.timeout"]:g} s; policy {self.params["lockstep.timeout_policy"]} '
            f'({self.missed_steps} missed)', throttle_duration_sec=5.0)
        if self.params['lockstep.timeout_policy'] == 'zero':
            self._zero_commands(missing)
        self.publish_status()

    def _zero_commands(self, command_topics) -> None:
        """The ``zero`` timeout policy: no command on ``command_topics`` for this step."""
        zero = self.plant.zero_commands()
        for topic in command_topics:
            if topic == topics.THRUSTERS_CMD:   # held as on-times; the valve command is built from them
                self.on_time = np.zeros_like(self.on_time)
            else:
                key = COMMAND_KEYS[topic]
                self.commands[key] = zero[key]

    # --- simulated link faults (adcs_sim.truth.link_faults) ----------------------------------------

    def _link_before(self, k: int) -> tuple[dict, np.ndarray] | None:
        """Before waiting for step k's commands: count last step's late ones as stale (they
        arrive now, stamped for that step) and keep the commands in effect (and the thrusters'
        on-times) if step k's are to be lost or late."""
        if self._late:
            self.stale_commands += self._late
            self._late = 0
        if self.awaited and self.link.fate(k) != OK:
            return dict(self.commands), self.on_time.copy()
        return None

    def _link_after(self, k: int, held: tuple[dict, np.ndarray] | None) -> None:
        """Step k's commands came, but the simulated link loses them or delivers them after the
        deadline: the step runs without them, a missed step under the timeout policy (a step
        already missed by timeout is left as it is)."""
        if held is None or not self.received.issuperset(self.awaited):
            return
        fate = self.link.fate(k)
        self.commands, self.on_time = dict(held[0]), held[1]
        self.link.count(fate)
        if fate == DELAY:
            self._late = len(self.awaited)
        self.missed_steps += 1
        self.get_logger().warning(
            f'step t = {self.step_ns / cv.NS_PER_S:g} s: command on {sorted(self.awaited)} '
            f'{FATE_NAMES[fate]} on the simulated link; policy '
            f'{self.params["lockstep.timeout_policy"]} ({self.missed_steps} missed)',
            throttle_duration_sec=5.0)
        if self.params['lockstep.timeout_policy'] == 'zero':
            self._zero_commands(self.awaited)
        self.publish_status()

    def _spin_until(self, executor, wall_deadline: float) -> None:
        executor.spin_once(timeout_sec=0.0)
        while (remaining := wall_deadline - time.monotonic()) > 0:
            executor.spin_once(timeout_sec=remaining)

    def on_intrusion(self, intruders) -> None:
        """Stop on an intruder (AdcsNode), but only once every reader has acknowledged what this node
        already published: the recorder then holds every step up to the stop (the last step's
        applied torque goes out after the next state; a writer destroyed at once could take it
        along: seen on a fresh clone, tests/test_intruders.py)."""
        try:
            super().on_intrusion(intruders)
        except IntrusionDetected:
            if hasattr(self, '_step_publishers'):   # an intruder matched after the endpoints exist
                self._drain_acks()
            raise

    def _drain_acks(self) -> None:
        self.wait_acked(self._step_publishers + [self.pub_applied, self.pub_status, self.pub_thrusters,
                                                 *self.pub_visual.values()], 5.0)


def main(args=None) -> None:
    raise SystemExit(main_for(DynamicsNode, args))


if __name__ == '__main__':
    main()
