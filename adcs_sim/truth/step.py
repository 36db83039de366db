"""The truth step: one control period of the simulated spacecraft, pure (no ROS), batch-first.

:class:`TruthStep` owns what the dynamics node and the batch engine both drive (docs/architecture.md, "One step,
two drivers"): the plant (:func:`adcs_sim.truth.schema.build_plant`), the state measurement model
(``noise.*``), the sensor suite (``sensors.*``) on the truth environment (``environment.*``), the
plant's one orbit (:func:`adcs_sim.truth.schema.plant_orbit`) and the fault snapshots
(:class:`adcs_core.faults.FaultTracker`). For step ``k`` at ``t_k``, both drivers call, in this order:

1. :meth:`apply_due_faults` (``t_k``): the latest snapshot stamped ``<= t_k``, to the wheels and the
   sensors (the rule is :meth:`FaultTracker.due`; the node feeds the tracker from the ``faults``
   topic, the batch engine from the ``fault_injector`` section's schedule, :meth:`add_schedule`);
2. :meth:`measure_state` (the noisy state the controllers read) and :meth:`read_sensors` (every
   fitted sensor's reading of ``t_k``), or both at once, :meth:`measure`;
3. :meth:`integrate` over ``[t_k, t_k+1]`` holding the commands: the thrusters' valve command
   (:meth:`~adcs_sim.truth.thrusters.Thrusters.command`), :meth:`Plant.control_torque`, then
   :meth:`Plant.step` or :func:`~adcs_sim.truth.thrusters.step_pulsed`;
4. :meth:`failure`: why the state after the step is not finite (None if it is).

One run is a batch of one: the node builds it from its section (scalar seeds), the batch engine
from the stacked sections of ``n_runs`` runs (one noise and sensor seed per run).
"""
from __future__ import annotations

import numpy as np

from adcs_core.faults import FaultTracker
from adcs_msgs_py.measurements import Measurements
from adcs_msgs_py.sensor_interfaces import split_snapshot
from adcs_sim.truth.divergence import nonfinite_cause
from adcs_sim.truth.plant import ReactionWheels
from adcs_sim.truth.schema import build_plant, build_truth_environment, initial_state, step_timing
from adcs_sim.truth.sensor_schema import build_sensors
from adcs_sim.truth.sensor_suite import sensor_environment
from adcs_sim.truth.sensors import MeasurementModel
from adcs_sim.truth.thrusters import Thrusters, step_pulsed

NS_PER_S = 1_000_000_000


class TruthStep:
    """The truth model of a validated ``dynamics`` section (see module doc). ``n_runs``: None for one
    run (the node's, scalar values), else the batch size of a stacked section."""

    def __init__(self, d: dict, n_runs: int | None = None, warm: bool = True) -> None:
        self.section, self.n_runs = d, n_runs
        self.plant = build_plant(d, warm=warm)
        self.period_ns, self.n_steps = step_timing(d)
        self.period = self.period_ns / NS_PER_S
        self.max_step = d['integrator.max_step']
        self.wheels: ReactionWheels | None = next(
            (a for a in self.plant.actuators if isinstance(a, ReactionWheels)), None)
        self.thrusters: Thrusters | None = next(
            (a for a in self.plant.actuators if isinstance(a, Thrusters)), None)
        noise = (d['noise.attitude_std'], d['noise.rate_std'], d['noise.gyro_bias'])
        if n_runs is None:
            self.measurement = MeasurementModel(d['noise.seed'], *noise)
            self._sensor_seeds = None
        else:
            seeds = np.broadcast_to(np.asarray(d['noise.seed']), (n_runs,))
            # a generator per run only if it draws: seeding one costs ~20 us (20 ms for 1000 runs)
            self.measurement = MeasurementModel(seeds[:1], *noise)
            if self.measurement.active:
                self.measurement = MeasurementModel(seeds, *noise)
            self._sensor_seeds = np.broadcast_to(np.asarray(d['sensors.seed']), (n_runs,))
        self.sensors = self._build_sensors()
        self.environment = build_truth_environment(d) if self.sensors is not None else None
        self.faults = FaultTracker()

    def _build_sensors(self):
        return build_sensors(self.section) if self._sensor_seeds is None else \
            build_sensors(self.section, self._sensor_seeds)

    def restart(self) -> None:
        """Back to t = 0: fresh sensor noise streams and no fault applied (a batch runs from here)."""
        self.sensors = self._build_sensors()
        self.faults.rewind()

    def initial_state(self) -> np.ndarray:
        """The state at t = 0 (``(n_runs, n)`` for a batch)."""
        x = initial_state(self.plant, self.section)
        if self.n_runs is None:
            return x
        return np.broadcast_to(x, (self.n_runs, self.plant.n_states)).copy()

    # --- faults -------------------------------------------------------------------------------

    def add_schedule(self, schedule: list) -> None:
        """Hold a whole fault schedule (:func:`adcs_sim.truth.fault_schedule.fault_schedule`), as the
        node holds it once the ``faults`` topic has delivered it."""
        self.faults.hold(schedule)

    def apply_due_faults(self, t_ns: int) -> tuple[dict, dict] | None:
        """Apply the fault snapshot due at ``t_ns`` (the latest stamped ``<= t_ns``, if not yet in
        force) to the sensors and the wheels; returns its (actuator, sensor) parts, or None."""
        snapshot = self.faults.due(t_ns)
        if snapshot is None:
            return None
        wheels, sensors = split_snapshot(snapshot)
        if sensors and self.sensors is not None:
            self.sensors.apply_faults(sensors)
        if self.wheels is not None and wheels:
            self.wheels.apply_faults(wheels)
        return wheels, sensors

    # --- measure ------------------------------------------------------------------------------

    def measure_state(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The measured attitude and rate of state ``x`` (``noise.*``; the true ones without noise)."""
        return self.measurement.measure(x[..., :4], x[..., 4:7])

    def read_sensors(self, k: int, t: float, x: np.ndarray) -> Measurements | None:
        """Every fitted sensor's reading of state ``x`` at step ``k`` (``t`` s), on the truth
        environment at ``t``; None without sensors."""
        if self.sensors is None:
            return None
        env = sensor_environment(self.environment.sample(t)) if self.environment is not None else None
        return self.sensors.measure(k, t, x[..., :4], x[..., 4:7], env)

    def measure(self, k: int, t: float, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, Measurements | None]:
        """:meth:`measure_state` and :meth:`read_sensors` of step ``k``."""
        q_m, w_m = self.measure_state(x)
        return q_m, w_m, self.read_sensors(k, t, x)

    # --- integrate ----------------------------------------------------------------------------

    def integrate(self, t: float, x: np.ndarray, commands: dict, on_time=None) -> tuple[np.ndarray, np.ndarray]:
        """``(state at t + period, control torque at t)``: the plant over ``[t, t + period]`` holding
        ``commands`` (zero-order hold, RK4); with thrusters, ``commands['thrusters']`` is set to the
        valve command of the on-times ``on_time`` (s from ``t``; None: none fired) and the step is
        split at the pulse edges."""
        plant = self.plant
        if self.thrusters is not None:
            if on_time is None:
                on_time = 0.0
            shape = (self.thrusters.count,) if self.n_runs is None else (self.n_runs, self.thrusters.count)
            commands['thrusters'] = self.thrusters.command(t, np.broadcast_to(on_time, shape), self.period)
        torque = plant.control_torque(t, x, commands)
        if self.thrusters is not None:
            return step_pulsed(plant, t, x, commands, self.period, self.max_step), torque
        return plant.step(t, x, commands, self.period, self.max_step), torque

    def failure(self, t: float, x_new: np.ndarray, torque: np.ndarray) -> str | None:
        """Why the state after the step from ``t`` (one run's) is not finite, or None."""
        cause = nonfinite_cause(self.plant, x_new, torque)
        if cause is None:
            return None
        return (f'the plant state is no longer finite at t = {t + self.period:g} s (non-finite '
                f'{cause} after the step from t = {t:g} s)')
