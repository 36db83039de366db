"""The fitted sensors of a scenario, measured together each step (numpy, no ROS).

:class:`SensorSuite` holds the models of :mod:`adcs_sim.truth.sensor_models` that the scenario fits and
returns one :class:`adcs_msgs_py.measurements.Measurements` per step, stamped ``t_k`` (None for a sensor
not fitted). The dynamics node publishes it (each reading on its ``sensors/*`` topic) and the batch
engine hands it to an estimator: the same code, the same numbers. Sensor faults of the fault schedule
(:data:`adcs_core.faults.SENSOR_FAULT_MODES`) are applied with :meth:`SensorSuite.apply_faults` at the
step they are due, before that step's measurement, as the wheel faults are.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from adcs_core.environment.environment import EnvironmentSample
from adcs_core.faults import FaultState
from adcs_core.orbit import R_EARTH
from adcs_msgs_py.measurements import Measurements
from adcs_sim.truth.sensor_models import GYRO_AXES, CoarseSunSensors, Gyro, Magnetometer, StarTracker, SunSensor


@dataclass(frozen=True)
class SensorEnvironment:
    """The environment's reference quantities at a step, inertial axes, optional leading batch axis
    (the environment models compute them; a field left None is not available)."""

    sun: np.ndarray | None = None                   # (..., 3) unit direction to the Sun
    illumination: np.ndarray | None = None          # (...,) illuminated fraction of the Sun's disc, [0, 1]
    nadir: np.ndarray | None = None                 # (..., 3) unit direction to the Earth's centre
    earth_angular_radius: np.ndarray | None = None  # (...,) rad, asin(R_E / r)
    field: np.ndarray | None = None                 # (..., 3) geomagnetic field, T


NO_ENVIRONMENT = SensorEnvironment()


def sensor_environment(sample: EnvironmentSample) -> SensorEnvironment:
    """The sensors' inputs from the environment at a step (:meth:`adcs_core.environment.environment.
    Environment.sample`): the Sun seen from the Earth's centre (the parallax of a LEO orbit, < 1e-4
    rad, is below every sensor's noise), the illuminated fraction, nadir, the Earth's angular radius
    ``asin(R_E / r)`` and the field."""
    radius = np.linalg.norm(sample.r_eci, axis=-1)
    return SensorEnvironment(sun=sample.sun_eci, illumination=sample.shadow, nadir=sample.nadir_eci,
                             earth_angular_radius=np.arcsin(np.minimum(1.0, R_EARTH / radius)),
                             field=sample.b_eci)


class SensorSuite:
    """The fitted sensors (each None when not fitted) on the control step grid ``period_ns``."""

    def __init__(self, period_ns: int, gyro: Gyro | None = None, star_tracker: StarTracker | None = None,
                 sun: SunSensor | CoarseSunSensors | None = None, magnetometer: Magnetometer | None = None) -> None:
        self.period_ns = int(period_ns)
        self.gyro, self.star_tracker, self.sun, self.magnetometer = gyro, star_tracker, sun, magnetometer
        self.faults: dict[str, FaultState] = {}

    def fitted(self) -> tuple[str, ...]:
        return tuple(name for name in ('gyro', 'star_tracker', 'sun', 'magnetometer')
                     if getattr(self, name) is not None)

    def measure(self, k: int, t: float, q, w, env: SensorEnvironment | None = None) -> Measurements:
        """Every fitted sensor's reading at step ``k`` (time ``t = k period``, s) of the true attitude
        ``q`` and rate ``w`` ((4,), (3,) or with the batch axis). Call once per step, in order."""
        env = env or NO_ENVIRONMENT
        readings = {}
        if self.gyro is not None:
            readings['gyro'] = self.gyro.measure(w)
        if self.star_tracker is not None:
            readings['star_tracker'] = self.star_tracker.measure(k, q, env.sun, env.nadir,
                                                                 env.earth_angular_radius)
        if self.sun is not None:
            if env.sun is None or env.illumination is None:
                raise ValueError('the sun sensor needs the environment\'s Sun direction and illumination')
            readings['sun'] = self.sun.measure(q, env.sun, env.illumination)
        if self.magnetometer is not None:
            if env.field is None:
                raise ValueError('the magnetometer needs the environment\'s magnetic field')
            readings['magnetometer'] = self.magnetometer.measure(q, env.field)
        return Measurements(t_ns=int(k) * self.period_ns, **readings)

    def apply_faults(self, snapshot: dict) -> None:
        """Apply the sensor part of a fault snapshot (``{target: FaultState}``, targets of
        :data:`adcs_core.faults.SENSOR_FAULT_MODES`) from this step on; a target whose sensor is not
        fitted is ignored (the scenario checks refuse such a schedule before a run)."""
        for name, fault in snapshot.items():
            self.faults[name] = fault
            failed = fault.mode == 'failed'
            if name.startswith('gyro.'):
                if self.gyro is not None:
                    self.gyro.apply_fault(GYRO_AXES.index(name.split('.', 1)[1]), fault.mode, fault.value)
            elif name in ('star_tracker', 'sun', 'magnetometer') and getattr(self, name) is not None:
                getattr(self, name).failed = failed
