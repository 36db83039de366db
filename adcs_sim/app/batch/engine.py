"""Batch engine: N runs of one scenario advanced together, no ROS in the loop (numpy only).

The graph is the faithful one-run-at-a-time path; campaigns (:mod:`adcs_sim.app.campaign.plan`) need
thousands of runs. This engine drives the graph's own step objects with a leading batch axis (the
truth step, :class:`adcs_sim.truth.step.TruthStep`, the dynamics node's; the flight-software steps,
:class:`adcs_controllers.step.FlightStep` and :class:`~adcs_controllers.step.EstimationStep`, the
controller and estimator nodes'), so it runs the *same* code:

* the plant (:class:`adcs_sim.truth.plant.Plant`, built by :func:`adcs_sim.truth.schema.build_plant` from
  the ``dynamics`` section) with the same fixed-step RK4 and zero-order hold over each control
  period, on the same time grid (:func:`adcs_sim.truth.schema.step_timing`);
* the same measurement model (:class:`adcs_sim.truth.sensors.MeasurementModel`) and the same sensor
  suite (:func:`adcs_sim.truth.sensor_schema.build_sensors`): :meth:`BatchSimulation._measure` gives
  step ``k``'s :class:`~adcs_msgs_py.measurements.Measurements` (what the dynamics node publishes on
  ``sensors/*``), recorded into :attr:`BatchResult.sensors` when ``record_sensors`` is set;
* the controller section's law object (:data:`adcs_sim.app.scenario.registry.NODES` ``[section].law``, the
  one its node builds) and the same actuation (:class:`adcs_controllers.laws.allocation.Actuation`:
  minimum-norm allocation and saturation, or wheel speed commands for a law whose ``output`` is
  the wheel momentum; or the registry's own ``actuation`` of the section, e.g. seed 002's
  thrusters + pitch wheel, :class:`adcs_controllers.laws.backstepping.ThrusterActuation`, with
  the plant stepped by :func:`adcs_sim.truth.thrusters.step_pulsed` as the dynamics node does).

Each step mirrors the lockstep graph: the state at ``t_k`` is measured (with an estimator section:
the sensors' readings of ``t_k``, from the ``sensors`` callable the engine is given, go through the
estimator family's step, :mod:`adcs_controllers.estimators.families`, the node's very object, and a
controller with ``feedback: estimate`` flies on the estimate; the estimates are in
``BatchResult.estimate``), the law computes a torque,
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
from typing import Callable

import numpy as np

from adcs_controllers.step import MOMENTUM, EstimationStep, FlightStep
from adcs_core.faults import FAULT_ERROR_MODES
from adcs_msgs_py.measurements import Estimate, Measurements, received_readings
from adcs_msgs_py.params import ParameterError
from adcs_sim.app.batch import fused
from adcs_sim.app.analysis.metrics import RunData, run_metrics
from adcs_sim.app.analysis.estimation import estimation_metrics, series_from_batch
from adcs_sim.app.scenario.registry import NODES
from adcs_sim.truth.fault_schedule import fault_schedule
from adcs_sim.truth.sensors import MeasurementModel
from adcs_sim.truth.step import TruthStep

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
    wheel_max_speed: np.ndarray = field(default_factory=lambda: np.zeros(0))  # (n,) or (N, n) rad/s
    q_ref: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 0.0, 1.0]))  # (4,) or (N, 4)
    faults: list = field(default_factory=list)  # (t, level, actuator, mode) as RunData.faults
    thruster_names: list = field(default_factory=list)
    thruster_on_time: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0)))  # (N, K, n) s
    thruster_impulse: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0)))  # (N, K + 1, n) N s
    pointing: tuple | None = None  # (σ̂, τ̂) of a pointing law (seed 003), as RunData.pointing
    # With record_sensors: {sensor: {'value': (N, K + 1, 3 or 4), 'cov': (N, K + 1, 3, 3), 'valid':
    # (N, K + 1)}}, each step's reading (NaN / False where a run has no state); the gyro's also 'bias'
    # (N, K + 1, 3), the true bias in each reading (Gyro.true_bias)
    sensors: dict = field(default_factory=dict)
    # with an estimator section: {'q' (N, K, 4), 'w', 'bias' (N, K, 3), 'cov' (N, K, 6, 6), 'rate_cov'
    # (N, K, 3, 3), 'bias_true' (N, K, 3) when the sensors give it, 'status': {key: (N, K)}} at t[:K]
    estimate: dict | None = None

    @property
    def n_runs(self) -> int:
        return self.q.shape[0]

    def run_data(self, i: int) -> RunData:
        """Run ``i`` as the analysis library's :class:`~adcs_sim.app.analysis.metrics.RunData` (what a bag of
        the same run would give), so batch metrics are computed by the very same functions."""
        k = int(self.n_steps[i])
        q_ref = self.q_ref[i] if self.q_ref.ndim == 2 else self.q_ref
        run = RunData(t=self.t[:k + 1], q=self.q[i, :k + 1], w=self.w[i, :k + 1],
                      t_u=self.t[:k], u=self.u[i, :k], q_ref=q_ref, missed_steps=0,
                      faults=[f for f in self.faults if f[0] <= self.t[k]], pointing=self.pointing)
        if self.wheel_names:
            run.t_wheels, run.wheel_names = self.t[:k + 1], list(self.wheel_names)
            run.wheel_speed = self.wheel_speed[i, :k + 1]
            run.wheel_max_speed = self.wheel_limits()[i]
        return run

    def wheel_limits(self) -> np.ndarray:
        """The wheels' speed limits (N, n) (``inf``: unlimited or not given)."""
        n = len(self.wheel_names)
        limits = self.wheel_max_speed if np.size(self.wheel_max_speed) else np.full(n, math.inf)
        return np.broadcast_to(limits, (self.n_runs, n))

    def metrics(self, i: int, tol_deg: float = 0.5) -> dict:
        """:func:`adcs_sim.app.analysis.metrics.run_metrics` of run ``i`` and, with an estimator section,
        :func:`adcs_sim.app.analysis.estimation.estimation_metrics` (a Monte Carlo row gets both)."""
        out = run_metrics(self.run_data(i), tol_deg)
        if self.estimate is not None:
            out.update(estimation_metrics(series_from_batch(self, i)))
        return out


class BatchSimulation:
    """A batch of runs of one scenario: validated sections with batched values (see module doc).

    ``sections``: ``{section: params}`` as :meth:`Schema.stack` returns them (a ``dynamics``
    section, at most one controller section; ``recorder`` and other sections are ignored).
    ``n_runs``: the batch size (values without a batch axis are shared by every run).
    """

    @classmethod
    def from_runs(cls, runs: list[dict[str, dict]], sensors: 'SensorSource | None' = None,
                  references=None) -> 'BatchSimulation':
        """A batch of N runs, each given as its validated sections (``{section: params}``, as
        :func:`adcs_sim.app.graph.runner.validate_scenario` returns them); the ``recorder`` section is left
        out. Raises ParameterError for a parameter that differs but cannot (:meth:`Schema.stack`)."""
        sections = {name: NODES[name].schema.stack([r[name] for r in runs]) for name in runs[0]
                    if NODES[name].role != 'recorder'}
        return cls(sections, len(runs), sensors, references)

    def __init__(self, sections: dict[str, dict], n_runs: int, sensors: 'SensorSource | None' = None,
                 references=None) -> None:
        if n_runs < 1:
            raise ValueError(f'a batch needs at least one run, got {n_runs}')
        if 'dynamics' not in sections:
            raise ParameterError('dynamics', 'the batch needs a dynamics section')
        self.n_runs = n_runs
        self.dynamics = d = sections['dynamics']
        controllers = [s for s in sections if s in NODES and NODES[s].role == 'controller']
        unsupported = [s for s in sections if s in NODES and NODES[s].role not in
                       ('dynamics', 'controller', 'recorder', 'faults', 'estimator')]
        if unsupported:
            raise ParameterError(unsupported[0], f'section {unsupported[0]!r} is not supported by '
                                 'the batch engine (it simulates the dynamics, controller, estimator '
                                 'and fault_injector sections)')
        faults = [s for s in sections if s in NODES and NODES[s].role == 'faults']
        self.fault_schedule = fault_schedule(sections[faults[0]]) if faults else []
        if len(controllers) > 1:
            raise ParameterError(controllers[1], f'more than one controller section ({controllers})')
        self.controller = controllers[0] if controllers else None
        # the truth step (adcs_sim/truth/step.py): the dynamics node's very objects, with a batch axis
        self.truth = TruthStep(d, n_runs)
        self.truth.add_schedule(self.fault_schedule)
        self.plant = self.truth.plant
        self.period_ns, self.max_step = self.truth.period_ns, self.truth.max_step
        self.n_steps = np.broadcast_to(np.asarray(self.truth.n_steps, dtype=np.int64), (n_runs,)).copy()
        self.record_sensors = False   # set True to get every step's readings in BatchResult.sensors
        self._measured: tuple[int, Measurements] | None = None
        self.law = self.actuation = self.flight = None
        if self.controller is not None:
            # the flight step (adcs_controllers/step.py): the controller node's very objects
            self.flight = FlightStep.build(self.controller, NODES[self.controller].family, sections[self.controller])
            self.flight.faults.hold(self.fault_schedule)
            self.law, self.actuation = self.flight.law, self.flight.actuation
            missing = [a for a in self.actuation.plant_actuators if a not in self.plant.slices]
            if missing:
                raise ParameterError('actuator', f'the controller commands {", ".join(missing)} '
                                     'but the dynamics section has none', self.controller)
        self._build_estimator(sections, sensors, references)
        # The regulation target the metrics measure errors from (as analysis.target_attitude):
        # the law's own (normalised) target, identity in free flight.
        self.q_ref = self.law.q_ref if self.law is not None else np.array([0.0, 0.0, 0.0, 1.0])
        self.wheels, self.thrusters = self.truth.wheels, self.truth.thrusters
        # A law that needs the wheels' momentum (seed 003) or an allocation that needs the wheel speed
        # (seed 002) gets them as its node does: the true speeds of the controller's wheels of the same
        # step (by name; wheels/state carries no noise).
        sigma, tau = getattr(self.law, 'sigma', None), getattr(self.law, 'tau', None)
        self.pointing = None if sigma is None or tau is None else (np.asarray(sigma), np.asarray(tau))
        self.speed_index = None
        if self.flight is not None and self.flight.needs_wheel_speed:
            names = list(self.wheels.names) if self.wheels else []
            missing = [n for n in self.actuation.wheel_names if n not in names]
            if missing:
                raise ParameterError('wheels.names', f'wheel(s) {missing} of the controller are not '
                                     f'in the dynamics section ({names})', self.controller)
            self.speed_index = np.array([names.index(n) for n in self.actuation.wheel_names])

    @property
    def measurement(self) -> MeasurementModel:
        """The truth step's state measurement model (``noise.*``, one seed per run)."""
        return self.truth.measurement

    @property
    def sensors(self):
        """The truth step's sensor suite (``sensors.*``, one seed per run; rebuilt by :meth:`run`), or None."""
        return self.truth.sensors

    def _build_estimator(self, sections: dict, sensors, references) -> None:
        """The estimator section's family object (what its node builds) and the sensors feeding it."""
        names = [s for s in sections if s in NODES and NODES[s].role == 'estimator']
        self.estimator, self.sensor_source = None, sensors
        self.feedback = sections[self.controller].get('feedback', 'state') if self.controller else 'state'
        if len(names) > 1:
            raise ParameterError(names[1], f'more than one estimator section ({names})')
        if names:
            if sensors is None and self.sensors is None:
                raise ParameterError(names[0], 'an estimator needs sensors: fit them in the dynamics section '
                                     '(sensors.*.enabled)')
            # the estimation step (adcs_controllers/step.py): the estimator node's very object
            self.estimation = EstimationStep(names[0], NODES[names[0]].family.build(sections[names[0]], references))
            self.estimator, self.estimator_name = self.estimation.estimator, names[0]
        elif self.feedback == 'estimate':
            raise ParameterError('feedback', "'estimate' needs an estimator section", self.controller)

    def _estimate(self, k: int, x: np.ndarray, hist: dict) -> Estimate:
        """Step ``k``'s estimate from the sensors' readings of ``t_k``, as the node receives them; recorded."""
        if self.sensor_source is not None:   # readings given by the caller
            raw = self.sensor_source(k, k * self.period_ns, x[:, :4], x[:, 4:7])
            bias_true = getattr(self.sensor_source, 'true_bias', None)
        else:                                # the dynamics section's sensor suite, as the node publishes it
            raw = self._measure(k, (k * self.period_ns) / NS_PER_S, x)
            bias_true = self.sensors.gyro.true_bias if self.sensors.gyro is not None else None
        # the node's step, the message round trip made by it: FlightSoftwareError (naming the runs of a
        # non-finite estimate) where the node stops
        est, status = self.estimation.step(raw, batch=True)
        rec = hist.setdefault('estimate', {'status': {}})
        values = {'q': est.q, 'w': est.w, 'bias': est.bias, 'cov': est.cov, 'rate_cov': est.rate_cov}
        if bias_true is not None:
            values['bias_true'] = np.broadcast_to(bias_true, est.bias.shape)
        for key, v in [*values.items(), *((('status', key), v) for key, v in status.items())]:
            store = rec['status'] if isinstance(key, tuple) else rec
            name = key[1] if isinstance(key, tuple) else key
            v = np.broadcast_to(np.asarray(v, dtype=float), (self.n_runs,) + np.shape(v)[1:])
            if name not in store:
                store[name] = np.full((self.n_runs, self.K) + v.shape[1:], math.nan)
            store[name][self.active, k] = v[self.active]
        return est

    def _commands(self, values, speed_mode: bool = False) -> tuple[dict, object]:
        """(the plant's commands of the controller's command ``values``, the thrusters' on-times or None)."""
        commands = self.plant.zero_commands()
        if values is None:
            return commands, None
        for name, parts in self.actuation.plant_commands(values, speed_mode).items():
            commands[name] = self.plant.actuator(name).command_from(*parts)
        return commands, self.actuation.thruster_on_time(values) if self.thrusters is not None else None

    def _history(self, x: np.ndarray, K: int, fill: bool = True) -> dict[str, np.ndarray]:
        """The recorded series (NaN where a run has no sample), with the initial state's; ``fill``
        False: the later samples left unset (the fused loop writes every one, NaN after a run's end)."""
        N, plant = self.n_runs, self.plant
        n_wheels = self.wheels.count if self.wheels else 0
        n_thr = self.thrusters.count if self.thrusters else 0
        new = (lambda shape: np.full(shape, math.nan)) if fill else np.empty
        hist = {'q': new((N, K + 1, 4)), 'w': new((N, K + 1, 3)), 'u': new((N, K, 3)),
                'speed': new((N, K + 1, n_wheels)), 'on': np.full((N, K, n_thr), math.nan),
                'impulse': np.full((N, K + 1, n_thr), math.nan)}
        hist['q'][:, 0], hist['w'][:, 0] = x[:, :4], x[:, 4:7]
        if n_thr:
            hist['impulse'][:, 0] = x[:, plant.slices['thrusters']]
        if n_wheels:
            hist['speed'][:, 0] = x[:, plant.slices['wheels']][:, :n_wheels]
        return hist

    def _measure(self, k: int, t: float, x: np.ndarray) -> Measurements | None:
        """Step ``k``'s sensor readings of the state ``x`` (N, n) at ``t_k`` (None: no sensor fitted),
        as the dynamics node measures them; computed once per step (a second call returns them)."""
        if self.sensors is None:
            return None
        if self._measured is None or self._measured[0] != k:
            self._measured = (k, self.truth.read_sensors(k, t, x))
        return self._measured[1]

    def _sense(self, hist: dict, k: int, x: np.ndarray, has_state: np.ndarray) -> None:
        """Measure step ``k`` (every step, whether recorded or not) and record the runs ``has_state``."""
        m = self._measure(k, (k * self.period_ns) / NS_PER_S, x)
        if m is None or not self.record_sensors:
            return
        K = hist['q'].shape[1]
        for name in m.fitted():
            r = getattr(m, name)
            rec = hist['sensors'].setdefault(name, {
                'value': np.full((self.n_runs, K) + r.value.shape[1:], math.nan),
                'cov': np.full((self.n_runs, K, 3, 3), math.nan), 'valid': np.zeros((self.n_runs, K), bool)})
            for key in ('value', 'cov', 'valid'):
                rec[key][has_state, k] = getattr(r, key)[has_state]
        if 'gyro' in hist['sensors']:   # the bias in each reading, for an estimator's bias error
            rec = hist['sensors']['gyro'].setdefault('bias', np.full((self.n_runs, K, 3), math.nan))
            rec[has_state, k] = self.sensors.gyro.true_bias[has_state]

    def _control(self, k: int, t: float, x: np.ndarray, observe, est: Estimate | None = None) -> tuple:
        """Step ``k``'s commands as the controller node computes them (:meth:`FlightStep.step`, its due
        faults first): (values, momentum mode)."""
        if self.flight is None:
            return None, False
        if self.feedback == 'estimate':   # the controller's state:=estimate/state
            q_m, w_m = est.q, est.w
        else:
            q_m, w_m = self.truth.measure_state(x)
        speed = None if self.speed_index is None else x[:, self.plant.slices['wheels']][:, self.speed_index]
        # FlightSoftwareError where the controller node stops (the law raises); the node counts a
        # refused state (ValueError) instead, which a batch cannot skip for one run: it fails too
        out = self.flight.step(k * self.period_ns, q_m, w_m, speed, batch=True)
        if observe is not None:
            observe(k, t, out.status)
        return out.values, out.output == MOMENTUM

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
        x = self.truth.initial_state()
        loop = fused.plan(self, x, progress, observe)
        hist = self._history(x, K, fill=loop is None)
        hist['sensors'] = {}
        if loop is not None:
            return self._run_fused(loop, x, hist, K)
        self.truth.restart()   # each run from t = 0: fresh sensor streams, no fault in force
        if self.flight is not None:
            self.flight.faults.rewind()
        self._measured = None
        failure: list = [None] * N
        active = self.n_steps > 0
        done_steps = np.zeros(N, dtype=np.int64)
        self.K = K
        with np.errstate(all='ignore'):  # a diverging run's overflow is recorded, not warned
            for k in range(K):
                if not active.any():
                    break
                t = (k * self.period_ns) / NS_PER_S
                if self.fault_schedule:   # the controller's: in FlightStep.step
                    self.truth.apply_due_faults(k * self.period_ns)
                self._sense(hist, k, x, done_steps == k)
                self.active = active
                est = self._estimate(k, x, hist) if self.estimator is not None else None
                values, momentum = self._control(k, t, x, observe, est)
                commands, on_time = self._commands(values, momentum)
                x_new, u = self.truth.integrate(t, x, commands, on_time)
                if self.thrusters is not None:
                    hist['on'][active, k] = commands['thrusters'].on_time[active]
                finite = np.isfinite(x_new).all(axis=-1) & np.isfinite(u).all(axis=-1)
                for i in np.flatnonzero(active & ~finite):
                    failure[i] = self._failure(k, x_new[i], u[i])
                x = x_new if active.all() else np.where(active[:, None], x_new, x)
                self._record(hist, k, x, u, active)
                done_steps += active
                active = active & finite & (done_steps < self.n_steps)
                if progress is not None:
                    progress(k + 1)
            if self.sensors is not None:   # the last state's readings, as the dynamics node publishes them
                k_end = int(done_steps.max())
                self.truth.apply_due_faults(k_end * self.period_ns)
                self._sense(hist, k_end, x, done_steps == k_end)
        return self._result(hist, K, done_steps, failure)

    def _failure(self, k: int, x_new: np.ndarray, u: np.ndarray) -> str:
        """Why a run stopped at control step ``k``: its state after the step or its torque is not finite."""
        return self.truth.failure((k * self.period_ns) / NS_PER_S, x_new, u)

    def _run_fused(self, loop: 'fused.FusedLoop', x: np.ndarray, hist: dict, K: int) -> BatchResult:
        """:meth:`run` on the fused compiled loop (:mod:`adcs_sim.app.batch.fused`): the same rows."""
        self.K = K
        done_steps, failed, x_end = loop.run(self, x, hist)
        failure: list = [None] * self.n_runs
        for i in np.flatnonzero(failed):
            failure[i] = self._failure(int(done_steps[i]) - 1, x_end[i], hist['u'][i, done_steps[i] - 1])
        return self._result(hist, K, done_steps, failure)

    def _result(self, hist: dict, K: int, done_steps: np.ndarray, failure: list) -> BatchResult:
        t_grid = np.arange(K + 1, dtype=np.int64) * self.period_ns / NS_PER_S
        return BatchResult(t=t_grid, q=hist['q'], w=hist['w'], u=hist['u'], n_steps=done_steps,
                           failure=failure, wheel_names=list(self.wheels.names) if self.wheels else [],
                           wheel_speed=hist['speed'], q_ref=np.asarray(self.q_ref, dtype=float),
                           wheel_max_speed=self.wheels.max_speed if self.wheels else np.zeros(0),
                           faults=[(t_ns / NS_PER_S, 2 if mode in FAULT_ERROR_MODES else 0, name, mode)
                                   for t_ns, snap in self.fault_schedule
                                   for name, (mode, _, _) in snap.items()],
                           thruster_names=list(self.thrusters.names) if self.thrusters else [],
                           thruster_on_time=hist['on'], thruster_impulse=hist['impulse'],
                           pointing=self.pointing, sensors=hist.get('sensors', {}),
                           estimate=hist.get('estimate'))


# Float64 values a run records per control step (BatchSimulation._history: q, w, u; per wheel its
# speed, per thruster its on-time and impulse) and, with an estimator, per step its estimate (q, w,
# bias, the 6x6 and 3x3 covariances, the true bias) and its status (the bias, and per sensor its NIS,
# innovation, use and missing / rejected counts).
STATE_VALUES = 4 + 3 + 3
ESTIMATE_VALUES = 4 + 3 + 3 + 36 + 9 + 3 + 3
STATUS_VALUES_PER_SENSOR = 5


def run_bytes(sections: dict, steps: int) -> int:
    """Memory one run of a batch of ``sections`` (validated, as :class:`BatchSimulation` takes them)
    records over ``steps`` control steps: what each run of a campaign's chunk holds until its row
    is made (without ``record_sensors``)."""
    d = sections['dynamics']
    values = STATE_VALUES + len(d['wheels.names']) + 2 * len(d['thrusters.names'])
    values += sum(ESTIMATE_VALUES + STATUS_VALUES_PER_SENSOR * len(p['sensors'])
                  for name, p in sections.items() if name in NODES and NODES[name].role == 'estimator')
    return 8 * values * (steps + 1)


SensorSource = Callable[[int, int, np.ndarray, np.ndarray], Measurements]
"""``sensors(k, t_ns, q, w) -> Measurements`` of step ``k`` (true state (N, 4), (N, 3)), batch axis N;
an optional attribute ``true_bias`` (N, 3) is the gyro's true bias at that step (6-dof NEES)."""


# The readings as an estimator node receives them (the rule is the interface's, one place for both drivers).
as_received = received_readings
