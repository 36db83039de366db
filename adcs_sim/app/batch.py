"""Batch engine: N runs of one scenario advanced together, no ROS in the loop (numpy only).

The graph is the faithful one-run-at-a-time path; campaigns (:mod:`adcs_sim.app.campaign`) need
thousands of runs. This engine runs the *same* code as the graph with a leading batch axis:

* the plant (:class:`adcs_sim.truth.plant.Plant`, built by :func:`adcs_sim.truth.schema.build_plant` from
  the ``dynamics`` section) with the same fixed-step RK4 and zero-order hold over each control
  period, on the same time grid (:func:`adcs_sim.truth.schema.step_timing`);
* the same measurement model (:class:`adcs_sim.truth.sensors.MeasurementModel`);
* the controller section's law object (:data:`adcs_sim.app.registry.NODES` ``[section].law``, the
  one its node builds) and the same actuation (:class:`adcs_controllers.laws.allocation.Actuation`:
  minimum-norm allocation and saturation, or wheel speed commands for a law whose ``output`` is
  the wheel momentum; or the registry's own ``actuation`` of the section, e.g. seed 002's
  thrusters + pitch wheel, :class:`adcs_controllers.laws.backstepping.ThrusterActuation`, with
  the plant stepped by :func:`adcs_sim.truth.thrusters.step_pulsed` as the dynamics node does).

Each step mirrors the lockstep graph: the state at ``t_k`` is measured, the law computes a torque,
the actuation turns it into commands, the applied body torque is recorded (``actuators/torque``)
and the plant integrates ``[t_k, t_k+1]`` holding the commands. A ``fault_injector`` section's
schedule is applied as the graph applies it (the latest snapshot stamped ``<= t_k``, at step
``t_k``, to the plant, the allocation and the law; the same for every run). The runs of a batch
may differ in any parameter declared ``batch=True`` in its schema (inertia, initial state, gains, limits,
duration, noise seed...); :meth:`adcs_msgs_py.params.Schema.stack` checks that.

Runs that end early (a shorter ``duration``) or diverge (a non-finite state) are *masked*: they
keep being carried through the array operations but their state is frozen and nothing more is
recorded for them; the loop ends when no run is active. Every matrix product goes through
:func:`adcs_core.attitude.matvec`, so a run's numbers are the same bit for bit whichever runs share
its batch.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from adcs_core.attitude import quat_normalize
from adcs_core.faults import FAULT_ERROR_MODES
from adcs_msgs_py.params import ParameterError
from adcs_sim.app.analysis import RunData, run_metrics
from adcs_sim.app.registry import NODES
from adcs_sim.truth.divergence import nonfinite_cause
from adcs_sim.truth.fault_schedule import fault_schedule
from adcs_sim.truth.plant import ReactionWheels, WheelCommand
from adcs_sim.truth.schema import build_plant, initial_state, step_timing
from adcs_sim.truth.sensors import MeasurementModel
from adcs_sim.truth.thrusters import Thrusters, step_pulsed

NS_PER_S = 1_000_000_000


@dataclass
class BatchResult:
    """Time series of N runs on a common time grid; NaN where a run has no sample."""

    t: np.ndarray                 # (K + 1,) state times, s
    q: np.ndarray                 # (N, K + 1, 4) true attitude
    w: np.ndarray                 # (N, K + 1, 3) true body rate
    u: np.ndarray                 # (N, K, 3) applied body torque, held over [t_k, t_k+1]
    n_steps: np.ndarray           # (N,) control steps simulated per run
    failure: list = field(default_factory=list)  # per run: None, or why it stopped early
    wheel_names: list = field(default_factory=list)
    wheel_speed: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0)))  # (N, K + 1, n)
    q_ref: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 0.0, 1.0]))  # (4,) or (N, 4)
    faults: list = field(default_factory=list)  # (t, level, actuator, mode) as RunData.faults
    thruster_names: list = field(default_factory=list)
    thruster_on_time: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0)))  # (N, K, n) s
    thruster_impulse: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0)))  # (N, K + 1, n) N s
    pointing: tuple | None = None  # (σ̂, τ̂) of a pointing law (seed 003), as RunData.pointing

    @property
    def n_runs(self) -> int:
        return self.q.shape[0]

    def run_data(self, i: int) -> RunData:
        """Run ``i`` as the analysis library's :class:`~adcs_sim.app.analysis.RunData` (what a bag of
        the same run would give), so batch metrics are computed by the very same functions."""
        k = int(self.n_steps[i])
        q_ref = self.q_ref[i] if self.q_ref.ndim == 2 else self.q_ref
        run = RunData(t=self.t[:k + 1], q=self.q[i, :k + 1], w=self.w[i, :k + 1],
                      t_u=self.t[:k], u=self.u[i, :k], q_ref=q_ref, missed_steps=0,
                      faults=[f for f in self.faults if f[0] <= self.t[k]], pointing=self.pointing)
        if self.wheel_names:
            run.t_wheels, run.wheel_names = self.t[:k + 1], list(self.wheel_names)
            run.wheel_speed = self.wheel_speed[i, :k + 1]
        return run

    def metrics(self, i: int, tol_deg: float = 0.5) -> dict:
        """:func:`adcs_sim.app.analysis.run_metrics` of run ``i``."""
        return run_metrics(self.run_data(i), tol_deg)


class BatchSimulation:
    """A batch of runs of one scenario: validated sections with batched values (see module doc).

    ``sections``: ``{section: params}`` as :meth:`Schema.stack` returns them (a ``dynamics``
    section, at most one controller section; ``recorder`` and other sections are ignored).
    ``n_runs``: the batch size (values without a batch axis are shared by every run).
    """

    @classmethod
    def from_runs(cls, runs: list[dict[str, dict]]) -> 'BatchSimulation':
        """A batch of N runs, each given as its validated sections (``{section: params}``, as
        :func:`adcs_sim.app.runner.validate_scenario` returns them); the ``recorder`` section is left
        out. Raises ParameterError for a parameter that differs but cannot (:meth:`Schema.stack`)."""
        sections = {name: NODES[name].schema.stack([r[name] for r in runs]) for name in runs[0]
                    if NODES[name].role != 'recorder'}
        return cls(sections, len(runs))

    def __init__(self, sections: dict[str, dict], n_runs: int) -> None:
        if n_runs < 1:
            raise ValueError(f'a batch needs at least one run, got {n_runs}')
        if 'dynamics' not in sections:
            raise ParameterError('dynamics', 'the batch needs a dynamics section')
        self.n_runs = n_runs
        self.dynamics = d = sections['dynamics']
        controllers = [s for s in sections if s in NODES and NODES[s].role == 'controller']
        unsupported = [s for s in sections if s in NODES and NODES[s].role not in
                       ('dynamics', 'controller', 'recorder', 'faults')]
        if unsupported:
            raise ParameterError(unsupported[0], f'section {unsupported[0]!r} is not supported by '
                                 'the batch engine (it simulates the dynamics, controller and '
                                 'fault_injector sections)')
        faults = [s for s in sections if s in NODES and NODES[s].role == 'faults']
        self.fault_schedule = fault_schedule(sections[faults[0]]) if faults else []
        if len(controllers) > 1:
            raise ParameterError(controllers[1], f'more than one controller section ({controllers})')
        self.controller = controllers[0] if controllers else None
        self.plant = build_plant(d)
        self.period_ns, steps = step_timing(d)
        self.n_steps = np.broadcast_to(np.asarray(steps, dtype=np.int64), (n_runs,)).copy()
        self.max_step = d['integrator.max_step']
        seeds = np.broadcast_to(np.asarray(d['noise.seed']), (n_runs,))
        self.measurement = MeasurementModel(seeds, d['noise.attitude_std'], d['noise.rate_std'],
                                            d['noise.gyro_bias'])
        self.law = self.actuation = None
        if self.controller is not None:
            p = sections[self.controller]
            self.law, self.actuation = NODES[self.controller].family.build(p)
            if self.actuation.kind == 'wheels':
                self.law.on_wheels(self.actuation.axes, self.actuation.available)
            if self.actuation.kind not in self.plant.slices:
                raise ParameterError('actuator', f'the controller commands {self.actuation.kind} '
                                     'but the dynamics section has none', self.controller)
        # The regulation target the metrics measure errors from (as analysis.target_attitude):
        # the law's own (normalised) target, identity in free flight.
        self.q_ref = self.law.q_ref if self.law is not None else np.array([0.0, 0.0, 0.0, 1.0])
        self.wheels = next((a for a in self.plant.actuators if isinstance(a, ReactionWheels)), None)
        self.thrusters = next((a for a in self.plant.actuators if isinstance(a, Thrusters)), None)
        # A law that needs the wheels' momentum (seed 003) gets it as its node does: from the true
        # speeds of the controller's wheels (by name; wheels/state carries no noise), through
        # Actuation.wheel_momentum.
        sigma, tau = getattr(self.law, 'sigma', None), getattr(self.law, 'tau', None)
        self.pointing = None if sigma is None or tau is None else (np.asarray(sigma), np.asarray(tau))
        self.needs_wheel_momentum = bool(getattr(self.law, 'needs_wheel_momentum', False))
        self.momentum_index = None
        if self.needs_wheel_momentum:
            names = list(self.wheels.names) if self.wheels else []
            missing = [n for n in self.actuation.wheel_names if n not in names]
            if missing:
                raise ParameterError('wheels.names', f'wheel(s) {missing} of the controller are not '
                                     f'in the dynamics section ({names})', self.controller)
            self.momentum_index = np.array([names.index(n) for n in self.actuation.wheel_names])

    def _apply_faults(self, t_ns: int, applied: int) -> int:
        """Apply the latest fault snapshot stamped ``<= t_ns`` if newer than snapshot ``applied``
        (the dynamics node's and the controller's rule, :mod:`adcs_core.faults`): to the plant's
        wheels, the allocation and the law. Returns the index of the snapshot in force."""
        due = max((i for i, (ts, _) in enumerate(self.fault_schedule) if ts <= t_ns), default=-1)
        if due <= applied:
            return applied
        snapshot = self.fault_schedule[due][1]
        self.wheels.apply_faults(snapshot)
        if self.actuation is not None and self.actuation.kind == 'wheels' \
                and self.actuation.follow_faults(snapshot):
            self.law.on_wheels(self.actuation.axes, self.actuation.available)
        return due

    def _commands(self, values, speed_mode: bool = False, t: float = 0.0, period: float = 0.0) -> dict:
        commands = {a.name: a.zero_command() for a in self.plant.actuators}
        if self.thrusters is not None:  # the dynamics node's valve command (none fired: off)
            on_time = values[0] if values is not None and self.actuation.kind == 'thrusters' else 0.0
            commands['thrusters'] = self.thrusters.command(
                t, np.broadcast_to(on_time, (self.n_runs, self.thrusters.count)), period)
        if values is None:
            return commands
        if self.actuation.kind == 'thrusters':
            commands['wheels'] = WheelCommand(values[1], np.zeros(values[1].shape, dtype=bool))
        elif self.actuation.kind == 'wheels':
            commands['wheels'] = WheelCommand(values, np.full(values.shape, speed_mode))
        else:
            commands['torquers'] = values
        return commands

    def _history(self, x: np.ndarray, K: int) -> dict[str, np.ndarray]:
        """The recorded series (NaN where a run has no sample), with the initial state's."""
        N, plant = self.n_runs, self.plant
        n_wheels = self.wheels.count if self.wheels else 0
        n_thr = self.thrusters.count if self.thrusters else 0
        hist = {'q': np.full((N, K + 1, 4), math.nan), 'w': np.full((N, K + 1, 3), math.nan),
                'u': np.full((N, K, 3), math.nan), 'speed': np.full((N, K + 1, n_wheels), math.nan),
                'on': np.full((N, K, n_thr), math.nan), 'impulse': np.full((N, K + 1, n_thr), math.nan)}
        hist['q'][:, 0], hist['w'][:, 0] = x[:, :4], x[:, 4:7]
        if n_thr:
            hist['impulse'][:, 0] = x[:, plant.slices['thrusters']]
        if n_wheels:
            hist['speed'][:, 0] = x[:, plant.slices['wheels']][:, :n_wheels]
        return hist

    def _control(self, k: int, t: float, x: np.ndarray, observe) -> tuple:
        """Step ``k``'s commands as the controller node computes them: (values, momentum mode)."""
        if self.law is None:
            return None, False
        N = self.n_runs
        wheel_sl = self.plant.slices.get('wheels')
        q_m, w_m = self.measurement.measure(x[:, :4], x[:, 4:7])
        q_m = quat_normalize(q_m)  # what a controller does to the attitude it receives
        momentum = self.law.output == 'wheel_momentum'
        if self.needs_wheel_momentum:
            speed = x[:, wheel_sl][:, self.momentum_index]
            out, status = self.law.control(t, q_m, w_m, self.actuation.wheel_momentum(speed))
        else:
            out, status = self.law.control(t, q_m, w_m)
        if observe is not None:
            observe(k, t, status)
        if momentum:
            return self.actuation.command_momentum(np.broadcast_to(out, (N, 3))), True
        if self.actuation.kind == 'thrusters':
            speed = x[:, wheel_sl][:, :self.wheels.count]
            on_time, tau_w, _ = self.actuation.command(np.broadcast_to(out, (N, 3)), w_m, speed)
            return (on_time, tau_w), False
        values, _ = self.actuation.command(np.broadcast_to(out, (N, 3)))
        return values, False

    def _record(self, hist: dict, k: int, x: np.ndarray, u: np.ndarray, active: np.ndarray) -> None:
        """Step ``k``'s torque and the state at ``t_k+1`` of the active runs."""
        if active.all():  # the usual case: slices, not a boolean mask (same values, less indexing)
            active = slice(None)
        hist['u'][active, k] = u[active]
        hist['q'][active, k + 1] = x[active, :4]
        hist['w'][active, k + 1] = x[active, 4:7]
        if self.wheels is not None:
            hist['speed'][active, k + 1] = x[active][:, self.plant.slices['wheels']][:, :self.wheels.count]
        if self.thrusters is not None:
            hist['impulse'][active, k + 1] = x[active][:, self.plant.slices['thrusters']]

    def run(self, progress=None, observe=None) -> BatchResult:
        """Simulate every run to its end (or divergence). ``progress(steps_done)`` is called
        after each control step if given; ``observe(k, t, status)`` with the law's status of
        step ``k`` (what the controller node publishes, with the batch axis), if given."""
        N, K = self.n_runs, int(self.n_steps.max())
        plant = self.plant
        period = self.period_ns / NS_PER_S
        x = np.broadcast_to(initial_state(plant, self.dynamics), (N, plant.n_states)).copy()
        hist = self._history(x, K)
        failure: list = [None] * N
        fault_applied = -1
        active = self.n_steps > 0
        done_steps = np.zeros(N, dtype=np.int64)
        with np.errstate(all='ignore'):  # a diverging run's overflow is recorded, not warned
            for k in range(K):
                if not active.any():
                    break
                t = (k * self.period_ns) / NS_PER_S
                if self.fault_schedule:
                    fault_applied = self._apply_faults(k * self.period_ns, fault_applied)
                values, momentum = self._control(k, t, x, observe)
                commands = self._commands(values, momentum, t, period)
                u = plant.control_torque(t, x, commands)
                if self.thrusters is not None:
                    x_new = step_pulsed(plant, t, x, commands, period, self.max_step)
                    hist['on'][active, k] = commands['thrusters'].on_time[active]
                else:
                    x_new = plant.step(t, x, commands, period, self.max_step)
                finite = np.isfinite(x_new).all(axis=-1) & np.isfinite(u).all(axis=-1)
                for i in np.flatnonzero(active & ~finite):
                    failure[i] = (f'the plant state is no longer finite at t = {t + period:g} s (non-finite '
                                  f'{nonfinite_cause(plant, x_new[i], u[i])} after the step from t = {t:g} s)')
                x = x_new if active.all() else np.where(active[:, None], x_new, x)
                self._record(hist, k, x, u, active)
                done_steps += active
                active = active & finite & (done_steps < self.n_steps)
                if progress is not None:
                    progress(k + 1)
        return self._result(hist, K, done_steps, failure)

    def _result(self, hist: dict, K: int, done_steps: np.ndarray, failure: list) -> BatchResult:
        t_grid = np.arange(K + 1, dtype=np.int64) * self.period_ns / NS_PER_S
        return BatchResult(t=t_grid, q=hist['q'], w=hist['w'], u=hist['u'], n_steps=done_steps,
                           failure=failure, wheel_names=list(self.wheels.names) if self.wheels else [],
                           wheel_speed=hist['speed'], q_ref=np.asarray(self.q_ref, dtype=float),
                           faults=[(t_ns / NS_PER_S, 2 if mode in FAULT_ERROR_MODES else 0, name, mode)
                                   for t_ns, snap in self.fault_schedule
                                   for name, (mode, _, _) in snap.items()],
                           thruster_names=list(self.thrusters.names) if self.thrusters else [],
                           thruster_on_time=hist['on'], thruster_impulse=hist['impulse'],
                           pointing=self.pointing)
