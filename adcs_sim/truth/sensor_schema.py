"""The truth half of each sensor, declared once (:class:`SensorModel` in :data:`SENSOR_MODELS`): its
``sensors.<name>.*`` block of the ``dynamics`` section, the model it builds, what it needs of the
environment; and the :class:`SensorSuite` built from them (no ROS). Its interface half (topic, message,
faults, NIS) is :mod:`adcs_msgs_py.sensor_interfaces`.

Every sensor is off by default (``sensors.<name>.enabled``), so a scenario without the block runs and
records exactly as before. Units are SI and radians, except the geometry angles whose names end in
``_deg``. The star tracker's update period and latency are whole multiples of ``control_period`` (its
latency is exact: :class:`adcs_sim.truth.sensor_models.StarTracker`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from adcs_msgs_py.params import Param, ParameterError, non_negative, positive
from adcs_msgs_py.sections import Section, as_section
from adcs_msgs_py.sensor_interfaces import BY_NAME, SENSORS
from adcs_sim.truth.sensor_models import CoarseSunSensors, FineSunSensor, Gyro, Magnetometer, StarTracker, SunSensor
from adcs_sim.truth.sensor_suite import SensorSuite

MAX_LATENCY_STEPS = 100_000   # the star tracker keeps one attitude per step of latency


MAX_RATE_NOISE = 1.0     # rad/sqrt(s), rad/s^1.5: a gyro noisier than this measures nothing
MAX_ANGLE_STD = 1.0      # rad: star tracker and sun sensor noise
MAX_RATE_BIAS = 10.0     # rad/s: gyro bias and bias instability
MAX_FIELD = 1e-3         # T: magnetometer noise and bias (the geomagnetic field is ~5e-5 T)


def _rate_noise(v) -> str | None:
    return None if 0.0 <= v <= MAX_RATE_NOISE else f'must be in [0, {MAX_RATE_NOISE}], got {v!r}'


def _angle_std(v) -> str | None:
    return None if 0.0 <= v <= MAX_ANGLE_STD else f'must be in [0, {MAX_ANGLE_STD}] rad, got {v!r}'


def _rate_bias(v) -> str | None:
    return None if 0.0 <= v <= MAX_RATE_BIAS else f'must be in [0, {MAX_RATE_BIAS}] rad/s, got {v!r}'


def _rate_biases(values) -> str | None:
    return None if all(abs(v) <= MAX_RATE_BIAS for v in values) else \
        f'every value must be within +-{MAX_RATE_BIAS} rad/s, got {values}'


def _field_std(v) -> str | None:
    return None if 0.0 <= v <= MAX_FIELD else f'must be in [0, {MAX_FIELD}] T, got {v!r}'


def _field_biases(values) -> str | None:
    return None if all(abs(v) <= MAX_FIELD for v in values) else \
        f'every value must be within +-{MAX_FIELD} T, got {values}'


def _nonzero_vector(values) -> str | None:
    return None if math.sqrt(sum(v * v for v in values)) > 1e-9 else f'must not be the zero vector, got {values}'


def _scale_factor(values) -> str | None:
    return None if all(-1.0 < v <= 1.0 for v in values) else \
        f'every scale-factor error must be in (-1, 1], got {values}'


def _angle_below_180(v) -> str | None:
    return None if 0.0 <= v < 180.0 else f'must be in [0, 180) deg, got {v}'


def _half_angle(v) -> str | None:
    return None if 0.0 < v <= 180.0 else f'must be in (0, 180] deg, got {v}'


def _fraction_below_1(v) -> str | None:
    return None if 0.0 <= v < 1.0 else f'must be in [0, 1), got {v}'


def _enabled(name: str, what: str) -> Param:
    return Param(f'sensors.{name}.enabled', 'bool', default=False, doc=f'fit the {what} (publishes {what} '
                 'readings every step; off: not fitted)')


def _seed_param() -> list[Param]:
    return [Param('sensors.seed', 'int', default=0, check=non_negative, batch=True,
                  doc='seed of the sensor noise (each sensor its own stream of it; >= 0)')]


def _gyro_params() -> list[Param]:
    zeros = [0.0, 0.0, 0.0]
    return [
        _enabled('gyro', 'gyro'),
        Param('sensors.gyro.arw', 'double', default=0.0, check=_rate_noise,
              doc='angle random walk sigma_v (rad/sqrt(s))'),
        Param('sensors.gyro.rrw', 'double', default=0.0, check=_rate_noise,
              doc='rate random walk sigma_u of the bias (rad/s^1.5)'),
        Param('sensors.gyro.bias', 'double_array', default=zeros, length=3, check=_rate_biases, batch=True,
              doc='bias at t = 0 (rad/s, body axes); constant when rrw = 0'),
        Param('sensors.gyro.scale_factor', 'double_array', default=zeros, length=3, check=_scale_factor,
              batch=True, doc='scale-factor error per axis (fraction, in (-1, 1]; 1e-4 = 100 ppm)'),
        Param('sensors.gyro.max_rate', 'double', default=math.inf, check=positive, finite=False,
              doc='saturation: each axis reads at most this (rad/s; .inf for none)'),
        Param('sensors.gyro.markov_std', 'double', default=0.0, check=_rate_bias,
              doc='bias instability: stationary sigma of a first-order Gauss-Markov bias (rad/s; 0: none)'),
        Param('sensors.gyro.markov_time', 'double', default=3600.0, check=positive,
              doc='correlation time of the Gauss-Markov bias (s)'),
    ]


def _star_tracker_params() -> list[Param]:
    return [
        _enabled('star_tracker', 'star tracker'),
        Param('sensors.star_tracker.boresight', 'double_array', default=[0.0, 0.0, 1.0], length=3,
              check=_nonzero_vector, doc='boresight in body axes (need not be unit)'),
        Param('sensors.star_tracker.cross_std', 'double', default=0.0, check=_angle_std,
              doc='cross-boresight noise (rad, 1 sigma per axis)'),
        Param('sensors.star_tracker.about_std', 'double', default=0.0, check=_angle_std,
              doc='about-boresight noise (rad, 1 sigma)'),
        Param('sensors.star_tracker.period', 'double', default=0.0, check=non_negative,
              doc='update period (s): a multiple of control_period; 0: every step'),
        Param('sensors.star_tracker.latency', 'double', default=0.0, check=non_negative,
              doc='the reading at t_k is the attitude at t_k - latency (s): a multiple of control_period'),
        Param('sensors.star_tracker.sun_exclusion_deg', 'double', default=0.0, check=_angle_below_180,
              doc='no reading with the Sun within this angle of the boresight (deg; 0: none)'),
        Param('sensors.star_tracker.earth_exclusion_deg', 'double', default=0.0, check=_angle_below_180,
              doc="no reading with the boresight within this angle of the Earth's limb (deg; 0: none)"),
    ]


def _sun_params() -> list[Param]:
    return [
        _enabled('sun', 'sun sensor'),
        Param('sensors.sun.type', 'string', default='vector', choices=('vector', 'coarse'),
              doc='vector: a sun vector sensor (std, boresight, fov_deg); coarse: an assembly of cosine '
                  'detectors (normals, std, fov_deg per detector) and its least-squares sun vector'),
        Param('sensors.sun.normals', 'double_array', default=[],
              doc='coarse: detector normals in body axes, 3 per detector (at least 3 spanning 3-D)'),
        Param('sensors.sun.std', 'double', default=0.0, check=_angle_std,
              doc='vector: angular noise of the sun vector (rad, 1 sigma per axis perpendicular to it); '
                  'coarse: noise of each detector, in units of the full-Sun signal'),
        Param('sensors.sun.boresight', 'double_array', default=[0.0, 0.0, 1.0], length=3,
              check=_nonzero_vector, doc='axis of the field of view, body axes'),
        Param('sensors.sun.fov_deg', 'double', default=90.0, check=_half_angle,
              doc='field-of-view half angle (deg; 180: the whole sky); coarse: of each detector'),
        Param('sensors.sun.min_illumination', 'double', default=0.0, check=_fraction_below_1,
              doc='no reading unless the illuminated fraction of the Sun exceeds this (fraction; 0: none in umbra)'),
    ]


def _magnetometer_params() -> list[Param]:
    return [
        _enabled('magnetometer', 'magnetometer'),
        Param('sensors.magnetometer.std', 'double', default=0.0, check=_field_std,
              doc='noise (T, 1 sigma per axis)'),
        Param('sensors.magnetometer.bias', 'double_array', default=[0.0, 0.0, 0.0], length=3, check=_field_biases,
              batch=True,
              doc='constant bias (T, body axes)'),
    ]


def _fine_sun_params() -> list[Param]:
    return [
        _enabled('fine_sun_sensor', 'fine (two-axis) sun sensor'),
        Param('sensors.fine_sun_sensor.std', 'double', default=0.0, check=_angle_std,
              doc='noise of each of the two measured angles (rad, 1 sigma)'),
        Param('sensors.fine_sun_sensor.boresight', 'double_array', default=[0.0, 0.0, 1.0], length=3,
              check=_nonzero_vector, doc='boresight (mounting) in body axes; alpha is measured towards x_s, body x '
                                         'made perpendicular to it (body y for a boresight along x), beta towards '
                                         'boresight x x_s'),
        Param('sensors.fine_sun_sensor.fov_deg', 'double', default=60.0, check=_half_cone_below_90,
              doc='field-of-view half-cone angle (deg): no reading with the Sun further from the boresight'),
        Param('sensors.fine_sun_sensor.min_illumination', 'double', default=0.0, check=_fraction_below_1,
              doc='no reading unless the illuminated fraction of the Sun exceeds this (fraction; 0: none in umbra)'),
    ]


def _half_cone_below_90(v) -> str | None:
    return None if 0.0 < v < 90.0 else f'must be in (0, 90) deg, got {v}'


_half_cone_below_90.description = 'in (0, 90) deg'   # for docs/parameters.md


def _fine_sun(v: Section, seed, period_ns: int) -> FineSunSensor:
    f = v.sensors.fine_sun_sensor
    return FineSunSensor(seed, f.std, f.boresight, math.radians(f.fov_deg), f.min_illumination)


def _steps(period: float, duration, value: float, key: str) -> int:
    """Duration parameter ``key`` = ``value`` (s) as a whole number of control periods ``period``
    (ParameterError naming it if not)."""
    period_ns = int(round(float(period) * 1e9))
    if float(value) > duration + period and float(value) > 1e9:
        raise ParameterError(key, f'{value} s is beyond any run (duration {duration} s)')
    value_ns = int(round(float(value) * 1e9))
    if value_ns % period_ns:
        raise ParameterError(key, f'must be a whole multiple of control_period ({period} s), '
                             f'got {value}')
    return value_ns // period_ns


def _check_coarse(v: dict) -> None:
    normals = v['sensors.sun.normals']
    if v['sensors.sun.type'] != 'coarse':
        if normals:
            raise ParameterError('sensors.sun.normals', 'only for sensors.sun.type: coarse')
        return
    if len(normals) % 3 or len(normals) < 9:
        raise ParameterError('sensors.sun.normals', f'expected 3 values per detector and at least 3 '
                             f'detectors, got {len(normals)} values')
    n = np.asarray(normals, dtype=float).reshape(-1, 3)
    length = np.linalg.norm(n, axis=-1)
    if np.any(~(length > 1e-9)) or not np.all(np.isfinite(length)):
        raise ParameterError('sensors.sun.normals', 'every detector normal must be a finite non-zero vector')
    u = n / length[:, None]
    if np.linalg.matrix_rank(u, tol=1e-6) < 3:
        raise ParameterError('sensors.sun.normals', 'the detector normals must span 3-D')


def _star_tracker_check(v: dict) -> None:
    period, latency = 'sensors.star_tracker.period', 'sensors.star_tracker.latency'
    _steps(v['control_period'], v['duration'], v[period], period)
    if _steps(v['control_period'], v['duration'], v[latency], latency) > MAX_LATENCY_STEPS:
        raise ParameterError('sensors.star_tracker.latency', f'at most {MAX_LATENCY_STEPS} control periods, '
                             f'got {v["sensors.star_tracker.latency"]} s')


def _gyro(v: Section, seed, period_ns: int) -> Gyro:
    g = v.sensors.gyro
    return Gyro(seed, period_ns / 1e9, g.arw, g.rrw, g.bias, g.scale_factor, g.max_rate, g.markov_std,
                g.markov_time)


def _star_tracker(v: Section, seed, period_ns: int) -> StarTracker:
    st = v.sensors.star_tracker
    steps = lambda value, key: _steps(v.control_period, v.duration, value, key)  # noqa: E731
    return StarTracker(seed, st.boresight, st.cross_std, st.about_std,
                       max(1, steps(st.period, 'sensors.star_tracker.period')),
                       steps(st.latency, 'sensors.star_tracker.latency'),
                       math.radians(st.sun_exclusion_deg), math.radians(st.earth_exclusion_deg))


def _sun(v: Section, seed, period_ns: int) -> SunSensor | CoarseSunSensors:
    sun = v.sensors.sun
    if sun.type == 'coarse':
        return CoarseSunSensors(seed, sun.normals, sun.std, math.radians(sun.fov_deg), sun.min_illumination)
    return SunSensor(seed, sun.std, sun.boresight, math.radians(sun.fov_deg), sun.min_illumination)


def _magnetometer(v: Section, seed, period_ns: int) -> Magnetometer:
    return Magnetometer(seed, v.sensors.magnetometer.std, v.sensors.magnetometer.bias)


def _no_check(v: dict) -> None:
    return None


@dataclass(frozen=True)
class SensorModel:
    """The truth half of one sensor (its interface half: :mod:`adcs_msgs_py.sensor_interfaces`, same
    name): its ``sensors.<name>.*`` parameters, the model it builds from a validated section
    (``build(v, seed, period_ns)``, ``seed`` one per run for a batch), the model classes it may build
    (their ``ENVIRONMENT``: what it needs of the environment) and its cross-check."""

    name: str
    params: Callable[[], list[Param]]
    build: Callable[[Section, Any, int], Any]
    models: tuple[type, ...]
    check: Callable[[dict], None] = _no_check

    @property
    def needs_environment(self) -> bool:
        return any(m.ENVIRONMENT for m in self.models)


SENSOR_MODELS: tuple[SensorModel, ...] = (
    SensorModel('gyro', _gyro_params, _gyro, (Gyro,)),
    SensorModel('star_tracker', _star_tracker_params, _star_tracker, (StarTracker,), _star_tracker_check),
    SensorModel('sun', _sun_params, _sun, (SunSensor, CoarseSunSensors), _check_coarse),
    SensorModel('magnetometer', _magnetometer_params, _magnetometer, (Magnetometer,)),
    SensorModel('fine_sun_sensor', _fine_sun_params, _fine_sun, (FineSunSensor,)),
)
# One truth declaration per interface declaration, in the same order (the Measurements fields).
if tuple(s.name for s in SENSOR_MODELS) != SENSORS:
    raise ImportError(f'SENSOR_MODELS {[s.name for s in SENSOR_MODELS]} are not the interface declarations {SENSORS}')
# The sensors that cannot measure without the environment models (adcs_core.environment: the Sun
# direction, the eclipse, the geomagnetic field): fitted, they need `environment.enabled: true`.
NEEDS_ENVIRONMENT = tuple(s.name for s in SENSOR_MODELS if s.needs_environment)


def sensor_params() -> list[Param]:
    """The ``sensors.*`` parameters of the dynamics section."""
    return _seed_param() + [p for s in SENSOR_MODELS for p in s.params()]


def check_sensors(v: dict) -> None:
    """Cross-check of the ``sensors.*`` block (the dynamics section's cross-check calls it)."""
    for s in SENSOR_MODELS:
        s.check(v)
    if not v['environment.enabled']:
        for name in NEEDS_ENVIRONMENT:
            if v[f'sensors.{name}.enabled']:
                raise ParameterError(f'sensors.{name}.enabled', 'needs environment.enabled: true (the Sun '
                                     'direction, eclipse and geomagnetic field at the orbit: environment.*)')


def build_sensors(v: dict | Section, seed=None) -> SensorSuite | None:
    """The suite of a validated dynamics section (None when no sensor is fitted); ``seed`` one per run
    for a batch (default ``sensors.seed``)."""
    v = as_section(v)
    seed = v.sensors.seed if seed is None else seed
    period_ns = int(round(float(v.control_period) * 1e9))
    parts = {s.name: s.build(v, seed, period_ns) for s in SENSOR_MODELS
             if getattr(v.sensors, s.name).enabled}
    return SensorSuite(period_ns, **parts) if parts else None


def fitted_sensors(v: dict) -> tuple[str, ...]:
    """Names of the sensors a dynamics section fits (``adcs_msgs_py.measurements.SENSORS`` order)."""
    return tuple(s.name for s in SENSOR_MODELS if v[f'sensors.{s.name}.enabled'])


def fault_targets(v: dict) -> set[str]:
    """The sensor fault targets (:data:`adcs_msgs_py.sensor_interfaces.SENSOR_FAULT_MODES`) a dynamics
    section has."""
    return {target for name in fitted_sensors(v) for target in BY_NAME[name].targets}
