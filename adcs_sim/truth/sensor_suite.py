"""The fitted sensors of a scenario, measured together each step (numpy, no ROS).

:class:`SensorSuite` holds the models of :mod:`adcs_sim.truth.sensor_models` that the scenario fits and
returns one :class:`adcs_msgs_py.measurements.Measurements` per step, stamped ``t_k`` (None for a sensor
not fitted). The dynamics node publishes it (each reading on its ``sensors/*`` topic) and the batch
engine hands it to an estimator: the same code, the same numbers. Sensor faults of the fault schedule
(:data:`adcs_msgs_py.sensor_interfaces.SENSOR_FAULT_MODES`) are applied with :meth:`SensorSuite.apply_faults` at the
step they are due, before that step's measurement, as the wheel faults are.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from adcs_core.environment.environment import EnvironmentSample
from adcs_core.faults import FaultState
from adcs_core.orbit import R_EARTH
from adcs_msgs_py.measurements import SENSORS, Measurements
from adcs_msgs_py.sensor_interfaces import BY_NAME, FAULT_TARGET_SENSOR


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


# What each SensorEnvironment field is, for the error of a model that needs it and has not got it.
ENVIRONMENT_WORDS = {'sun': 'Sun direction', 'illumination': 'illumination', 'nadir': 'nadir',
                     'earth_angular_radius': "Earth's angular radius", 'field': 'magnetic field'}


class SensorSuite:
    """The fitted sensors on the control step grid ``period_ns``: one attribute per declared sensor
    (:data:`adcs_msgs_py.measurements.SENSORS`; None when not fitted), given in that order or by name.
    Each model reads through its :meth:`~adcs_sim.truth.sensor_models._Model.read` and follows its
    faults through ``follow_fault``: the suite never names a sensor."""

    def __init__(self, period_ns: int, *models, **named) -> None:
        self.period_ns = int(period_ns)
        given = dict(zip(SENSORS, models))
        unknown = sorted(set(named) - set(SENSORS))
        if len(models) > len(SENSORS) or unknown:
            raise TypeError(f'SensorSuite: sensors are {list(SENSORS)}, got {len(models)} models and {unknown}')
        given.update(named)
        for name in SENSORS:
            setattr(self, name, given.get(name))
        self.faults: dict[str, FaultState] = {}

    def fitted(self) -> tuple[str, ...]:
        return tuple(name for name in SENSORS if getattr(self, name) is not None)

    def measure(self, k: int, t: float, q, w, env: SensorEnvironment | None = None) -> Measurements:
        """Every fitted sensor's reading at step ``k`` (time ``t = k period``, s) of the true attitude
        ``q`` and rate ``w`` ((4,), (3,) or with the batch axis). Call once per step, in order."""
        env = env or NO_ENVIRONMENT
        readings = {}
        for name in self.fitted():
            model = getattr(self, name)
            missing = [ENVIRONMENT_WORDS[f] for f in model.ENVIRONMENT if getattr(env, f) is None]
            if missing:
                raise ValueError(f"the {BY_NAME[name].label} needs the environment's {' and '.join(missing)}")
            readings[name] = model.read(k, q, w, env)
        return Measurements(t_ns=int(k) * self.period_ns, **readings)

    def apply_faults(self, snapshot: dict) -> None:
        """Apply the sensor part of a fault snapshot (``{target: FaultState}``, targets of
        :data:`adcs_msgs_py.sensor_interfaces.SENSOR_FAULT_MODES`) from this step on; a target whose
        sensor is not fitted is ignored (the scenario checks refuse such a schedule before a run)."""
        for target, fault in snapshot.items():
            self.faults[target] = fault
            model = getattr(self, FAULT_TARGET_SENSOR[target], None)
            if model is not None:
                model.follow_fault(target, fault)
