"""The estimator families: for each estimator node, its parameter schema and its estimator, declared
once (flight software: pure numpy, leading batch axis, no rclpy, never the truth model).

A family (:class:`EstimatorFamily`) is what an estimator node executable is, as
:mod:`adcs_controllers.families` is for the controllers: the node (:mod:`adcs_controllers.nodes`)
builds ``family.build(section)`` from its validated section and the batch engine
(:mod:`adcs_sim.app.batch.engine`) builds the very same object, so a graph run and its batch run execute
the same code. An estimator has one method, ``step(measurements) -> (Estimate, status)``
(:mod:`adcs_msgs_py.measurements`), called once per lockstep step with every fitted sensor's
reading of that step; it propagates from the previous step with the previous gyro sample, then
updates with the valid measurements of this one. A sensor without a valid measurement (an outage,
not due, eclipse) is simply not used: the estimate is propagated only.

* ``mekf_estimator`` (:class:`MekfEstimator`): the multiplicative EKF with gyro-bias states
  (:mod:`adcs_controllers.estimators.mekf`) on the gyro and any of star tracker, sun sensor and
  magnetometer; updates sequentially in that order, each with an optional NIS gate.
* ``quest_estimator`` (:class:`SingleFrameEstimator`): QUEST / Davenport's q-method / TRIAD
  (:mod:`adcs_controllers.estimators.single_frame`) on the sun and magnetometer vectors with the
  QUEST measurement model's covariance, the rate from the gyro; when fewer than two vectors are valid
  the last attitude is propagated with the gyro (its covariance grows with the angle random walk).

Vector sensors need the inertial reference directions (the Sun, the field) at the step: a
``references(t_ns) -> {'sun': (..., 3), 'magnetometer': (..., 3)}`` callable given to
``build``, or the section's own: ``references.model: environment`` samples the onboard environment
models of its ``environment.*`` block (:func:`environment_references`), ``constant`` (the default) uses
its ``references.*`` vectors.

Measurement noise always comes from the section (the σ the filter assumes), never from a message's
covariance: the message covariances are exact to rounding only (see
:mod:`adcs_msgs_py.conversions_determination`), and a graph run must equal its batch run bit for bit.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from adcs_controllers.estimators import mekf, single_frame
from adcs_core.attitude import cross, dot, quat_conjugate, quat_multiply, quat_norm, rotate_to_body
from adcs_core.environment.environment import build_environment
from adcs_msgs_py.blocks import check_environment, check_unit_quaternion, environment_params, startup_params
from adcs_msgs_py.measurements import SENSORS, Estimate, Measurements
from adcs_msgs_py.params import Param, ParameterError, Schema, positive, vectorised
from adcs_msgs_py.sections import Section, as_section, flat, section
from adcs_msgs_py.sensor_interfaces import BY_NAME, SENSOR_INTERFACES

NS_PER_S = 1_000_000_000
# The vector sensors of the declarations (adcs_msgs_py.sensor_interfaces: a direction or a field of the
# inertial reference ``references.<reference>``), updated in this order, each with its own ``<name>.sigma``.
VECTOR_SENSORS = tuple(s.name for s in SENSOR_INTERFACES if s.measures in ('direction', 'field'))
REFERENCES = tuple(dict.fromkeys(BY_NAME[name].reference for name in VECTOR_SENSORS))
SINGLE_FRAME_VECTORS = ('sun', 'magnetometer')   # the two vectors of the single-frame solution
MIN_DQ4 = 1e-6   # a star tracker quaternion this close to 180 degrees from the estimate is rejected
MAX_RATE = 100.0  # rad/s per axis: a gyro sample beyond is not a rate (rejected, counted), whatever its type allows
References = Callable[[int], dict]

# What the filter's arithmetic can take (issue #31: sigmas of 1e200 or 1e-300, a huge initial covariance
# or reference field made the filter raise on every step). Upper bounds: beyond them a sigma says
# nothing more (an attitude error lives within half a turn; a direction noise of a radian or a field
# noise of 1 mT, 15 times the strongest geomagnetic field, measures nothing; a gyro noisier than
# 1 rad/s^0.5 is the truth model's own limit, adcs_sim.truth.sensor_schema; a bias beyond MAX_RATE is
# beyond any sample the filter accepts). Lower bounds: from the conditioning of what the filter
# solves (covariance_problem).
MAX_ATTITUDE_SIGMA = np.pi     # rad
MAX_DIRECTION_SIGMA = 1.0      # rad: star tracker, sun sensor
MAX_FIELD_SIGMA = 1e-3         # T
MAX_GYRO_NOISE = 1.0           # rad/s^0.5 (sigma_v), rad/s^1.5 (sigma_u)
# Each update solves the innovation covariance S = H P H^T + R (numpy's LU): the answer loses
# log10(cond S) of a double's ~15.7 significant digits; 1e12 keeps ~4 (the NIS gate and the gain
# need no more), and the filter raised or returned NaN within 30 steps wherever cond S passed ~1e15
# (sun.sigma 1e-12 against a 0.1 rad prior: 1e22; gyro.sigma_v 1e12).
MAX_CONDITION = 1e12
# The strongest geomagnetic field (IGRF, at the surface, ~6.7e-5 T): with references.model
# environment, the smallest magnetometer direction noise is magnetometer.sigma over it.
EARTH_FIELD_MAX = 7e-5


def _known_sensors(values) -> str | None:
    bad = [v for v in values if v not in SENSORS]
    if bad or len(set(values)) != len(values):
        return f'sensors must be distinct names among {list(SENSORS)}, got {values}'
    return None


def up_to(limit: float, unit: str):
    """The check of a sigma (a double or each value of an array): in (0, ``limit``]."""
    @vectorised(lambda a: bool(np.all((a > 0) & (a <= limit))))
    def check(v) -> str | None:
        values = v if isinstance(v, (list, tuple)) else [v]
        return None if all(0 < x <= limit for x in values) else \
            f'must be in (0, {limit:g}] {unit} (beyond it the filter learns nothing more), got {v!r}'
    check.description = f'in (0, {limit:g}] {unit}'   # for docs/parameters.md (adcs_sim.app.scenario.parameters)
    return check


def _sigma3(name: str, doc: str, default, limit: float, unit: str) -> Param:
    return Param(name, 'double_array', default=default, length=3, check=up_to(limit, unit), batch=True, doc=doc)


def _vector_sigma(name: str) -> Param:
    """The ``<name>.sigma`` the filter assumes for a vector sensor: a direction noise (rad) or a field
    noise (T)."""
    s = BY_NAME[name]
    if s.measures == 'field':
        return Param(f'{name}.sigma', 'double', default=1e-7, check=up_to(MAX_FIELD_SIGMA, 'T'), batch=True,
                     doc=f'{s.label} noise per axis (T); direction noise sigma/|B_ref|')
    return Param(f'{name}.sigma', 'double', default=1e-3, check=up_to(MAX_DIRECTION_SIGMA, 'rad'), batch=True,
                 doc=f'{s.label} direction noise, 1 sigma perpendicular to the vector (rad)')


def estimator_params(sensors_default: list[str], sensor_choice: str, vectors=VECTOR_SENSORS) -> list[Param]:
    """The parameters both families have: sensors, gyro model, vector sensors, references, start-up."""
    return [
        Param('sensors', 'string_array', default=sensors_default, check=_known_sensors,
              doc=f'the fitted sensors this estimator uses ({sensor_choice}); their topics are sensors/*'),
        Param('gyro.sigma_v', 'double', default=1e-5, check=up_to(MAX_GYRO_NOISE, 'rad/s^0.5'), batch=True,
              doc='angle random walk the filter assumes (rad/s^0.5)'),
        Param('gyro.propagation', 'string', default='increment', choices=('increment', 'hold', 'average'),
              doc="the rate over [t_k-1, t_k]: 'increment' the sample of t_k (a rate-integrating gyro's "
                  "mean rate over the step that ends at t_k, the simulator's gyro); 'hold' the sample of "
                  "t_k-1 (a sample that is the mean rate over the step after it); 'average' the mean of the "
                  "samples of t_k-1 and t_k (instantaneous samples: the trapezoidal rule)"),
        *(_vector_sigma(name) for name in vectors),
        Param('references.model', 'string', default='constant', choices=('constant', 'environment'),
              doc="the inertial reference vectors of the vector sensors: 'constant' references.sun and "
                  "references.magnetometer; 'environment' the onboard models of environment.* (Almanac Sun, "
                  "IGRF or dipole field along the orbit: adcs_core.environment), sampled at each step"),
        *environment_params(),
        Param('references.sun', 'double_array', default=[1.0, 0.0, 0.0], length=3, batch=True,
              doc='inertial Sun direction, used when no environment model is connected'),
        Param('references.magnetometer', 'double_array', default=[0.0, 0.0, 3e-5], length=3, batch=True,
              doc='inertial magnetic field (T), used when no environment model is connected'),
        Param('initial.attitude', 'double_array', default=[0.0, 0.0, 0.0, 1.0], length=4,
              check=check_unit_quaternion, batch=True, doc='initial attitude estimate [x, y, z, w]'),
        _sigma3('initial.attitude_sigma', 'initial attitude uncertainty per body axis, 1 sigma (rad)',
                [0.1, 0.1, 0.1], MAX_ATTITUDE_SIGMA, 'rad'),
        Param('startup.estimate_subscribers', 'int', default=1,
              doc='matched subscribers of estimate/state (besides the recorder) to wait for before '
                  'subscribing to the sensors: the controllers flying on the estimate'),
        *startup_params(),
    ]


def _mekf_check(v: dict) -> None:
    sensors = v['sensors']
    if 'gyro' not in sensors:
        raise ParameterError('sensors', 'the MEKF propagates with the gyro: list gyro')
    updates = [s.name for s in SENSOR_INTERFACES if s.measures != 'rate']
    if not any(s in sensors for s in updates):
        raise ParameterError('sensors', f'the MEKF needs an attitude sensor besides the gyro ({", ".join(updates)})')
    _references_check(v)


def _references_check(v: dict) -> None:
    if v['references.model'] == 'environment':
        check_environment(v)
        return
    for name in VECTOR_SENSORS:
        key = f'references.{BY_NAME[name].reference}'
        if name in v['sensors'] and not np.all(np.linalg.norm(np.asarray(v[key]), axis=-1) > 0):
            raise ParameterError(key, 'a zero reference vector: the direction is undefined')


MEKF_SCHEMA = Schema('mekf_estimator', [
    *estimator_params(['gyro', 'star_tracker'], 'gyro and ' + ', '.join(s.name for s in SENSOR_INTERFACES
                                                                         if s.measures != 'rate')),
    Param('gyro.sigma_u', 'double', default=1e-8, check=up_to(MAX_GYRO_NOISE, 'rad/s^1.5'), batch=True,
          doc='rate random walk of the bias the filter assumes (rad/s^1.5)'),
    _sigma3('star_tracker.sigma', 'star tracker noise per body axis, 1 sigma (rad)', [1e-4, 1e-4, 1e-4],
            MAX_DIRECTION_SIGMA, 'rad'),
    Param('initial.bias', 'double_array', default=[0.0, 0.0, 0.0], length=3, batch=True,
          doc='initial gyro bias estimate (rad/s)'),
    _sigma3('initial.bias_sigma', 'initial bias uncertainty per axis, 1 sigma (rad/s)', [1e-3, 1e-3, 1e-3],
            MAX_RATE, 'rad/s'),
    Param('gate.nis', 'double', default=float('inf'), check=positive, finite=False,
          doc='an update whose normalised innovation squared exceeds this is rejected and counted '
              '(.inf: no gate; chi-square quantiles: 16.3 for 3 dof at 0.999)'),
], cross_check=_mekf_check, doc='multiplicative extended Kalman filter with gyro-bias states '
                                '(Markley & Crassidis 2014 ch. 6; Lefferts, Markley & Shuster 1982)')


def _single_frame_check(v: dict) -> None:
    sensors = v['sensors']
    if sorted(s for s in sensors if s != 'gyro') != sorted(SINGLE_FRAME_VECTORS) or 'gyro' not in sensors:
        raise ParameterError('sensors', f'the single-frame estimator uses gyro, sun and magnetometer, got {sensors}')
    _references_check(v)


QUEST_SCHEMA = Schema('quest_estimator', [
    *estimator_params(['gyro', 'sun', 'magnetometer'], 'gyro, sun and magnetometer', SINGLE_FRAME_VECTORS),
    Param('method', 'string', default='quest', choices=('quest', 'q_method', 'triad'),
          doc='single-frame solution of the two vectors (TRIAD trusts the sun vector)'),
    Param('gyro.bias', 'double_array', default=[0.0, 0.0, 0.0], length=3, batch=True,
          doc='known gyro bias subtracted from the measured rate (rad/s)'),
], cross_check=_single_frame_check, doc='single-frame attitude (QUEST / q-method / TRIAD on the sun and '
                                        'magnetometer vectors, Markley & Crassidis 2014 ch. 5) with the gyro rate')


def _measurement_variances(p: Section) -> list[tuple[str, float, str]]:
    """(key, variance (rad^2), what) of each measurement the section's filter updates with (the
    star tracker only where the schema has it: the MEKF's)."""
    out = []
    if 'star_tracker' in p.sensors and hasattr(p, 'star_tracker'):
        out.append(('star_tracker.sigma', float(np.min(p.star_tracker.sigma)) ** 2, 'the star tracker'))
    for name in (n for n in VECTOR_SENSORS if n in p.sensors):
        s = BY_NAME[name]
        sigma = float(getattr(p, name).sigma)
        if s.measures == 'direction':
            out.append((f'{name}.sigma', sigma ** 2, f'the {s.label}'))
            continue
        constant = p.references.model == 'constant'   # a field noise in T, a direction noise of sigma / |B|
        ref = f'references.{s.reference}'
        field = float(np.linalg.norm(getattr(p.references, s.reference))) if constant else EARTH_FIELD_MAX
        key = ref if constant and field > MAX_FIELD_SIGMA else f'{name}.sigma'
        out.append((key, (sigma / field) ** 2, f'the {s.label} (direction noise {name}.sigma / {field:.3g} T)'))
    return out


def covariance_problem(p: dict | Section, period: float) -> tuple[str, str] | None:
    """Whether a validated estimator section's filter can do its arithmetic at the start of a run with
    control period ``period`` (s), else ``(key, why)`` (None: it can).

    Every measurement variance must be a normal double (S >= R stays invertible whatever P does).
    The MEKF's innovation covariance of a vector sensor holds the measurement variance alone along
    the measured direction and the attitude variance across it, and the star tracker's spans them
    too: cond S ~ (P + R) / R, with P the largest attitude variance of the first two updates (the
    prior, and one period of propagation: sigma_v^2 dt + sigma_u^2 dt^3 / 3 + the bias prior's
    sigma_b^2 dt^2). The single-frame solution weighs the two vectors by 1 / R: cond ~ R_max / R_min.
    Either must stay within MAX_CONDITION."""
    p = as_section(p)
    with np.errstate(all='ignore'):
        measured = _measurement_variances(p)
        for key, r, what in measured:
            if not np.finfo(float).tiny <= r < np.inf:
                return key, (f'{what}: variance {r:.3g} rad^2 is not a normal double: the filter '
                             'could not invert its innovation covariance')
        dt = float(period)
        sources = {'initial.attitude_sigma': float(np.max(p.initial.attitude_sigma)) ** 2,
                   'gyro.sigma_v': float(p.gyro.sigma_v) ** 2 * dt}
        if hasattr(p.gyro, 'sigma_u'):   # the MEKF's schema: bias states
            sources['gyro.sigma_u'] = float(p.gyro.sigma_u) ** 2 * dt ** 3 / 3.0
            sources['initial.bias_sigma'] = float(np.max(p.initial.bias_sigma)) ** 2 * dt ** 2
            attitude = sum(sources.values())
            for key, r, what in measured:
                cond = (attitude + r) / r
                if not cond <= MAX_CONDITION:
                    largest = max(sources, key=sources.get)
                    return key, (f'{what}: variance {r:.3g} rad^2 against an attitude variance of '
                                 f'{attitude:.3g} rad^2 at the start (mostly from {largest}): the innovation '
                                 f'covariance would have a condition number of {cond:.3g}, more than the '
                                 f'{MAX_CONDITION:g} the filter\'s solves can take')
        elif len(measured) > 1:   # single frame: the two vectors weighed by 1 / R
            (k_small, r_small, w_small), (_, r_large, w_large) = sorted(measured, key=lambda m: m[1])
            if not r_large / r_small <= MAX_CONDITION:
                return k_small, (f'{w_small}: variance {r_small:.3g} rad^2 against {r_large:.3g} of '
                                 f'{w_large}: weights {r_large / r_small:.3g} apart, more than the '
                                 f'{MAX_CONDITION:g} the single-frame solution can take')
    return None


# --- shared machinery ------------------------------------------------------------------------------

def environment_references(p: Section) -> References:
    """The onboard reference models of the section's ``environment.*``: the Sun direction and the field
    (T) in inertial axes at ``t_ns`` (:class:`adcs_core.environment.environment.Environment`; flight
    software's own copy of the models, which may differ from the truth model's by its parameters)."""
    env = build_environment(flat(p.environment, 'environment.'))

    def references(t_ns: int) -> dict:
        sample = env.sample(t_ns / NS_PER_S)
        return {'sun': sample.sun_eci, 'magnetometer': sample.b_eci}   # by reference key (REFERENCES)
    return references


def default_references(p: Section) -> References:
    """The references a section asks for (``references.model``)."""
    return environment_references(p) if p.references.model == 'environment' else constant_references(p)


def constant_references(p: Section) -> References:
    """The section's constant ``references.*`` vectors as a references callable."""
    refs = {key: np.asarray(getattr(p.references, key), dtype=float) for key in REFERENCES}
    return lambda t_ns: refs  # noqa: ARG005


def _valid(reading, shape) -> np.ndarray:
    return np.broadcast_to(np.asarray(reading.valid, dtype=bool), shape).copy()


def _finite_rows(value, valid: np.ndarray) -> np.ndarray:
    """``valid`` and the reading's value finite and non-zero (a bad reading is a rejection, not a crash)."""
    v = np.asarray(value, dtype=float)
    with np.errstate(invalid='ignore', over='ignore'):
        n2 = (v * v).sum(axis=-1)
        return valid & np.isfinite(v).all(axis=-1) & (n2 > 0) & np.isfinite(n2)


def _placeholder(value, ok: np.ndarray, fill: np.ndarray) -> np.ndarray:
    """The reading's value where ``ok``, ``fill`` elsewhere (so the array maths never sees NaN)."""
    v = np.asarray(value, dtype=float)
    v = np.where(np.isfinite(v), v, 0.0)
    return np.where(ok[..., None], v, fill)


class _Base:
    """Time keeping, the gyro sample of the previous step and the per-sensor counters."""

    def __init__(self, p: Section, references: References | None) -> None:
        p = as_section(p)
        self.sensors = tuple(p.sensors)
        self.references = references or default_references(p)
        self.sigma_v = np.asarray(p.gyro.sigma_v, dtype=float)
        self.propagation = p.gyro.propagation
        self.sigma_dir = {name: np.asarray(getattr(p, name).sigma, dtype=float) for name in VECTOR_SENSORS
                          if hasattr(getattr(p, name, None), 'sigma')}
        self.t_ns: int | None = None
        self.rate = None          # the last valid gyro sample (what propagates the next interval)
        self.dt = 0.0             # the interval just propagated (s)
        self.counts: dict[str, Any] = {}

    def _count(self, key: str, where) -> None:
        self.counts[key] = self.counts.get(key, 0) + np.asarray(where, dtype=np.int64)

    def _interval(self, m: Measurements) -> float | None:
        """Seconds since the previous step (None at the first); refuses a stamp that does not advance."""
        if self.t_ns is not None and not m.t_ns > self.t_ns:
            raise ValueError(f'estimator: step stamped {m.t_ns} ns does not follow {self.t_ns} ns')
        dt = None if self.t_ns is None else (m.t_ns - self.t_ns) / NS_PER_S
        self.t_ns = m.t_ns
        return dt

    def _gyro(self, m: Measurements, shape) -> tuple[np.ndarray, np.ndarray]:
        """(this step's gyro rate, the rate over the interval that ends here: with
        ``gyro.propagation`` ``increment`` this sample, ``hold`` the last valid one, ``average`` their
        mean; the last valid one wherever this one is not valid)."""
        if m.gyro is None:
            raise ValueError('estimator: no gyro reading (the gyro is not fitted)')
        valid = _valid(m.gyro, shape)
        value = np.asarray(m.gyro.value, dtype=float)
        with np.errstate(invalid='ignore', over='ignore'):
            ok = valid & np.isfinite(value).all(axis=-1) & (np.abs(value) <= MAX_RATE).all(axis=-1)
        self._count('missing_gyro', ~valid)
        self._count('rejected_gyro', valid & ~ok)
        last = np.zeros(shape + (3,)) if self.rate is None else self.rate
        rate = _placeholder(m.gyro.value, ok, last)
        if self.propagation == 'hold':
            interval = last
        else:
            fresh = rate if self.propagation == 'increment' else 0.5 * (last + rate)
            interval = np.where(ok[..., None], fresh, last)
        self.rate = rate
        return rate, interval

    def _vector(self, m: Measurements, name: str, shape, t_ns: int):
        """(measured unit vectors, reference unit vectors, direction σ, where usable) of one vector sensor."""
        reading = getattr(m, name)
        if name not in self.sensors or reading is None:
            return None
        ref = np.broadcast_to(np.asarray(self.references(t_ns)[BY_NAME[name].reference], dtype=float),
                              shape + (3,))
        ref_norm = np.sqrt(dot(ref, ref))
        valid = _valid(reading, shape)
        ok = _finite_rows(reading.value, valid) & (ref_norm > 0)
        r = np.where(ok[..., None], ref, [1.0, 0.0, 0.0]) / np.where(ok, ref_norm, 1.0)[..., None]
        b = _placeholder(reading.value, ok, r)
        b = b / np.sqrt(dot(b, b))[..., None]
        sigma = np.broadcast_to(self.sigma_dir[name], shape)
        if BY_NAME[name].measures == 'field':   # noise in T -> direction noise in rad
            sigma = sigma / np.where(ok, ref_norm, 1.0)
        self._count(f'missing_{name}', ~valid)
        self._count(f'rejected_{name}', valid & ~ok)
        return b, r, sigma, ok

    def _status(self, bias, nis: dict, innovation: dict, used: dict) -> dict:
        status = {'bias_x': bias[..., 0], 'bias_y': bias[..., 1], 'bias_z': bias[..., 2]}
        for name in self.sensors:
            if name == 'gyro':
                continue
            status[f'nis_{name}'] = nis.get(name, np.nan)
            status[f'innovation_{name}'] = innovation.get(name, np.nan)
            status[f'used_{name}'] = used.get(name, False)
        status.update({k: v for k, v in sorted(self.counts.items())})
        return status


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle (rad) between unit vectors, robust at 0 and π."""
    return np.arctan2(np.sqrt(dot(cross(a, b), cross(a, b))), dot(a, b))


# --- the MEKF ----------------------------------------------------------------------------------------

class MekfEstimator(_Base):
    """The MEKF as an estimator family (see the module doc). State ``q`` (..., 4), ``beta`` (..., 3),
    ``P`` (..., 6, 6); batch shape from the first step's readings."""

    def __init__(self, p: Section, references: References | None = None) -> None:
        p = as_section(p)
        super().__init__(p, references)
        self.sigma_u = np.asarray(p.gyro.sigma_u, dtype=float)
        s_st = np.asarray(p.star_tracker.sigma, dtype=float)
        self.R_st = s_st[..., :, None] ** 2 * np.eye(3)
        self.gate = float(p.gate.nis)
        q0 = np.asarray(p.initial.attitude, dtype=float)
        self.q = q0 / quat_norm(q0)[..., None]
        self.beta = np.asarray(p.initial.bias, dtype=float)
        var = np.concatenate(np.broadcast_arrays(np.asarray(p.initial.attitude_sigma, dtype=float),
                                                 np.asarray(p.initial.bias_sigma, dtype=float)), axis=-1) ** 2
        self.P = var[..., :, None] * np.eye(6)

    def _start(self, shape) -> None:
        self.q = np.broadcast_to(self.q, shape + (4,)).copy()
        self.beta = np.broadcast_to(self.beta, shape + (3,)).copy()
        self.P = np.broadcast_to(self.P, shape + (6, 6)).copy()

    def _gated(self, new, nis, ok, name: str):
        """Apply an update where ``ok`` and its NIS passes the gate; count the gated ones."""
        passed = ok & ~(nis > self.gate)
        self._count(f'rejected_{name}', ok & ~passed)
        q, beta, P = new
        self.q = np.where(passed[..., None], q, self.q)
        self.beta = np.where(passed[..., None], beta, self.beta)
        self.P = np.where(passed[..., None, None], P, self.P)
        return np.where(ok, nis, np.nan), passed

    def _star_tracker(self, m: Measurements, shape, nis, innovation, used) -> None:
        reading = m.star_tracker
        if 'star_tracker' not in self.sensors or reading is None:
            return
        valid = _valid(reading, shape)
        ok = _finite_rows(reading.value, valid)
        q_meas = _placeholder(reading.value, ok, self.q)
        q_meas = q_meas / quat_norm(q_meas)[..., None]
        dq = quat_multiply(quat_conjugate(self.q), q_meas)
        ok &= np.abs(dq[..., 3]) > MIN_DQ4          # 180 degrees away: no small-rotation innovation
        self._count('missing_star_tracker', ~valid)
        self._count('rejected_star_tracker', valid & ~ok)
        q_meas = np.where(ok[..., None], q_meas, self.q)
        y = 2.0 * dq[..., :3] / np.where(ok, dq[..., 3], 1.0)[..., None]   # the filter's innovation
        innovation['star_tracker'] = np.where(ok, np.sqrt(dot(y, y)), np.nan)
        q, beta, P, s = mekf.update_quaternion(self.q, self.beta, self.P, q_meas, self.R_st, ok)
        nis['star_tracker'], used['star_tracker'] = self._gated((q, beta, P), s, ok, 'star_tracker')

    def _vectors(self, m: Measurements, shape, nis, innovation, used) -> None:
        for name in VECTOR_SENSORS:
            got = self._vector(m, name, shape, m.t_ns)
            if got is None:
                continue
            b, r, sigma, ok = got
            innovation[name] = np.where(ok, _angle(b, rotate_to_body(self.q, r)), np.nan)
            q, beta, P, s = mekf.update_vectors(self.q, self.beta, self.P, b[..., None, :], r[..., None, :],
                                                sigma[..., None], ok)
            nis[name], used[name] = self._gated((q, beta, P), s, ok, name)

    def step(self, m: Measurements) -> tuple[Estimate, dict]:
        """Propagate from the previous step with its gyro sample, update with this step's valid
        measurements; return the estimate at ``m.t_ns`` and the status values."""
        shape = np.shape(m.gyro.valid) if m.gyro is not None else ()
        dt = self._interval(m)
        rate, interval = self._gyro(m, shape)
        if dt is None:
            self._start(shape)
        else:
            self.q, self.beta, self.P = mekf.propagate(self.q, self.beta, self.P, interval, dt,
                                                       self.sigma_v, self.sigma_u)
            self.dt = dt
        nis, innovation, used = {}, {}, {}
        self._star_tracker(m, shape, nis, innovation, used)
        self._vectors(m, shape, nis, innovation, used)
        return self._estimate(m.t_ns, rate), self._status(self.beta, nis, innovation, used)

    def _estimate(self, t_ns: int, rate: np.ndarray) -> Estimate:
        """``ω̂ = ω_meas − β̂``; its covariance ``P_ββ + σ_v²/Δt I`` (the bias error and the gyro's white
        noise over the interval just propagated; the bias block only at the first step)."""
        white = self.sigma_v ** 2 / self.dt if self.dt > 0 else 0.0 * self.sigma_v
        rate_cov = self.P[..., 3:, 3:] + np.asarray(white)[..., None, None] * np.eye(3)
        return Estimate(t_ns, self.q.copy(), rate - self.beta, self.beta.copy(), self.P.copy(), rate_cov)


# --- single frame ------------------------------------------------------------------------------------

class SingleFrameEstimator(_Base):
    """QUEST / q-method / TRIAD on the sun and magnetometer vectors each step, the rate from the gyro
    minus its known bias (see the module doc). ``cov``: the QUEST covariance in its attitude block,
    zeros elsewhere (no bias state)."""

    def __init__(self, p: Section, references: References | None = None) -> None:
        p = as_section(p)
        super().__init__(p, references)
        self.method = p.method
        self.bias = np.asarray(p.gyro.bias, dtype=float)
        q0 = np.asarray(p.initial.attitude, dtype=float)
        self.q = q0 / quat_norm(q0)[..., None]
        self.P = np.asarray(p.initial.attitude_sigma, dtype=float)[..., :, None] ** 2 * np.eye(3)

    def _solve(self, b: np.ndarray, r: np.ndarray, w: np.ndarray) -> np.ndarray:
        if self.method == 'triad':
            return single_frame.triad(b[..., 0, :], r[..., 0, :], b[..., 1, :], r[..., 1, :])
        solver = single_frame.quest if self.method == 'quest' else single_frame.q_method
        return solver(b, r, w)

    def step(self, m: Measurements) -> tuple[Estimate, dict]:
        shape = np.shape(m.gyro.valid) if m.gyro is not None else ()
        dt = self._interval(m)
        rate, interval = self._gyro(m, shape)
        if dt is None:
            self.q = np.broadcast_to(self.q, shape + (4,)).copy()
            self.P = np.broadcast_to(self.P, shape + (3, 3)).copy()
        else:   # propagate (what an outage keeps): exact rotation, P grows by σ_v² Δt
            P6 = np.zeros(shape + (6, 6))
            P6[..., :3, :3] = self.P
            self.q, _, P6 = mekf.propagate(self.q, np.zeros(shape + (3,)), P6, interval - self.bias, dt,
                                           self.sigma_v, 0.0)
            self.P, self.dt = P6[..., :3, :3], dt
        sun = self._vector(m, 'sun', shape, m.t_ns)
        mag = self._vector(m, 'magnetometer', shape, m.t_ns)
        if sun is None or mag is None:
            raise ValueError('single-frame estimator: the sun sensor and the magnetometer must be fitted')
        b, r = np.stack([sun[0], mag[0]], axis=-2), np.stack([sun[1], mag[1]], axis=-2)
        sigma = np.stack([sun[2], mag[2]], axis=-1)
        spread = np.sqrt(dot(cross(b[..., 0, :], b[..., 1, :]), cross(b[..., 0, :], b[..., 1, :])))
        spread_r = np.sqrt(dot(cross(r[..., 0, :], r[..., 1, :]), cross(r[..., 0, :], r[..., 1, :])))
        floor = np.sqrt(single_frame.OBSERVABILITY_MIN) * 10.0
        ok = sun[3] & mag[3] & (spread > floor) & (spread_r > floor)
        self._count('unobservable', sun[3] & mag[3] & ~ok)
        # runs without a fix solve a well-posed dummy problem (discarded): the arrays stay finite
        dummy_b = np.broadcast_to(np.eye(3)[:2], shape + (2, 3))
        b, r = np.where(ok[..., None, None], b, dummy_b), np.where(ok[..., None, None], r, dummy_b)
        q_fix = self._solve(b, r, sigma ** -2.0)
        P_fix = single_frame.quest_covariance(b, np.where(ok[..., None], sigma, 1.0))
        innovation = {name: np.where(ok, _angle(b[..., i, :], rotate_to_body(self.q, r[..., i, :])), np.nan)
                      for i, name in enumerate(SINGLE_FRAME_VECTORS)}
        self.q = np.where(ok[..., None], q_fix, self.q)
        self.P = np.where(ok[..., None, None], P_fix, self.P)
        cov = np.zeros(shape + (6, 6))
        cov[..., :3, :3] = self.P
        white = self.sigma_v ** 2 / self.dt if self.dt > 0 else 0.0 * self.sigma_v
        rate_cov = np.asarray(white)[..., None, None] * np.broadcast_to(np.eye(3), shape + (3, 3))
        bias = np.broadcast_to(self.bias, shape + (3,))
        est = Estimate(m.t_ns, self.q.copy(), rate - bias, np.zeros(shape + (3,)), cov, rate_cov)
        used = {name: ok for name in SINGLE_FRAME_VECTORS}
        return est, self._status(np.zeros(shape + (3,)), {}, innovation, used)


# --- the families ------------------------------------------------------------------------------------

@dataclass(frozen=True)
class EstimatorFamily:
    """One estimator node: its section's ``schema`` and its estimator class (called with the validated
    section and an optional references callable)."""

    schema: Schema
    estimator: Callable[..., Any]

    @property
    def node(self) -> str:
        return self.schema.node

    @property
    def module(self) -> str:
        return f'adcs_controllers.nodes.{self.schema.node}'

    def section(self, p: dict | Section) -> Section:
        """A validated (or stacked) section as its typed section (:mod:`adcs_msgs_py.sections`)."""
        return section(self.schema, p)

    def build(self, p: dict | Section, references: References | None = None):
        """The estimator of a validated (or stacked) section, read as its typed section: what the node
        and the batch engine run."""
        return self.estimator(self.section(p), references)


MEKF = EstimatorFamily(MEKF_SCHEMA, MekfEstimator)
QUEST = EstimatorFamily(QUEST_SCHEMA, SingleFrameEstimator)
ESTIMATOR_FAMILIES: dict[str, EstimatorFamily] = {f.node: f for f in (MEKF, QUEST)}
