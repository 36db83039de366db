"""The fine (two-axis) sun sensor, the sensor added by its declarations alone (issue #32 item 3): the
model (noise on its two measured angles, field of view, eclipse, mounting, faults), its schema, the
tables every layer derives from the declarations, its message round trip, and a run alone equal to the
run in a batch. Its graph run and its MEKF's consistency: tests/test_fine_sun_sensor_graph.py,
tests/test_fine_sun_sensor_nees.py."""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from adcs_controllers.estimators.families import MEKF, QUEST, VECTOR_SENSORS
from adcs_core.attitude import quat_multiply, rotate_to_inertial
from adcs_core.faults import FaultState
from adcs_msgs_py import conversions_determination as cd
from adcs_msgs_py import names, topics
from adcs_msgs_py.measurements import SENSORS, Measurements
from adcs_msgs_py.params import ParameterError
from adcs_msgs_py.sensor_interfaces import NIS_DOF, SENSOR_FAULT_MODES
from adcs_sim.app.batch.engine import as_received
from adcs_sim.app.analysis.estimation import NIS_DOF as ANALYSIS_NIS_DOF
from adcs_sim.truth.fault_schedule import FAULT_SCHEMA, fault_schedule
from adcs_sim.truth.schema import DYNAMICS_SCHEMA
from adcs_sim.truth.sensor_models import FineSunSensor, rotation_quaternion, sensor_frame
from adcs_sim.truth.sensor_schema import NEEDS_ENVIRONMENT, build_sensors, fault_targets
from adcs_sim.truth.sensor_suite import SensorEnvironment

SIGMA = 1e-3
BORESIGHT = [1.0, 0.3, -0.2]
IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])
BASE = {'inertia': [12.0, 14.0, 10.0], 'duration': 10.0, 'control_period': 0.5, 'environment.enabled': True}


def _sun_at(alpha: float, beta: float, boresight=BORESIGHT) -> np.ndarray:
    """The inertial (= body, at the identity) unit Sun direction whose angles in the sensor frame are
    ``alpha, beta`` (rad): unit(tan a, tan b, 1) in the sensor frame."""
    s = np.array([math.tan(alpha), math.tan(beta), 1.0])
    return sensor_frame(boresight) @ (s / np.linalg.norm(s))


def test_noise_is_on_the_two_angles_with_its_sigma():
    """10 000 runs of one step at a Sun 25 deg and -10 deg off the boresight in the sensor's two axes:
    the angles read back from the readings (the sensor's own atan2) differ from the true ones by
    N(0, σ²) each, uncorrelated: sample standard deviations within 3 % of σ (the 99.7 % band of a
    sample of 10 000 is ±2.1 %), correlation below 0.03, means within 4 standard errors of zero."""
    runs = 10_000
    sensor = FineSunSensor(np.arange(runs), SIGMA, BORESIGHT, math.radians(60.0))
    sun = _sun_at(math.radians(25.0), math.radians(-10.0))
    r = sensor.measure(IDENTITY, sun, 1.0)
    assert r.valid.all() and r.value.shape == (runs, 3)
    alpha, beta = sensor.angles(r.value)
    da, db = alpha - math.radians(25.0), beta - math.radians(-10.0)
    assert abs(da.std() / SIGMA - 1) < 0.03 and abs(db.std() / SIGMA - 1) < 0.03, (da.std(), db.std())
    assert abs(np.corrcoef(da, db)[0, 1]) < 0.03
    assert abs(da.mean()) < 4 * SIGMA / math.sqrt(runs) and abs(db.mean()) < 4 * SIGMA / math.sqrt(runs)
    assert_allclose(np.linalg.norm(r.value, axis=-1), 1.0, rtol=0, atol=4e-16)


def test_first_order_covariance_of_the_vector_is_sigma_squared_across_it_on_the_boresight():
    """The unit vector's error covariance against its first-order form σ² J Jᵀ, J the derivatives of
    unit(tan α, tan β, 1) by the angles (central differences, an independent reference): on the
    boresight J Jᵀ = I − s sᵀ (the QUEST measurement model the MEKF assumes); off it (30 deg, 20 deg)
    the two sensitivities |∂s/∂α|, |∂s/∂β| lie within [cos θ, 1] of σ, θ the angle off the boresight."""
    def jacobian(a, b, h=1e-6):
        return np.column_stack([(_sun_at(a + h, b) - _sun_at(a - h, b)) / (2 * h),
                                (_sun_at(a, b + h) - _sun_at(a, b - h)) / (2 * h)])
    runs = 20_000
    for a, b in ((0.0, 0.0), (math.radians(30.0), math.radians(20.0))):
        s = _sun_at(a, b)
        J = jacobian(a, b)
        r = FineSunSensor(np.arange(runs), SIGMA, BORESIGHT, math.radians(60.0)).measure(IDENTITY, s, 1.0)
        err = r.value - s
        assert_allclose(np.cov(err.T), SIGMA ** 2 * J @ J.T, rtol=0, atol=0.05 * SIGMA ** 2)
        if a == 0.0:
            assert_allclose(J @ J.T, np.eye(3) - np.outer(s, s), atol=1e-9)
        else:
            theta = math.acos(s @ sensor_frame(BORESIGHT)[:, 2])
            lengths = np.linalg.norm(J, axis=0)
            assert np.all((lengths >= math.cos(theta) - 1e-9) & (lengths <= 1 + 1e-9)), lengths


def test_no_reading_out_of_the_field_of_view_in_the_umbra_or_failed():
    """Valid only with the Sun within the half-cone (35 deg: 34.9 in, 35.1 out), an illuminated
    fraction above min_illumination, and not failed (from the fault's step to its recovery); otherwise
    the zero vector, as its message carries it. Noise-free, a valid reading is the Sun to rounding."""
    sensor = FineSunSensor(3, 0.0, [0.0, 0.0, 1.0], math.radians(35.0), min_illumination=0.2)
    tilt = lambda deg: np.array([math.sin(math.radians(deg)), 0.0, math.cos(math.radians(deg))])  # noqa: E731
    inside = sensor.measure(IDENTITY, tilt(34.9), 1.0)
    assert inside.valid and and_allclose(inside.value, tilt(34.9))
    for sun, lit in ((tilt(35.1), 1.0), (tilt(0.0), 0.2), (tilt(0.0), 0.0), (-tilt(0.0), 1.0)):
        r = sensor.measure(IDENTITY, sun, lit)
        assert not r.valid and np.all(r.value == 0.0)
    sensor.follow_fault('fine_sun_sensor', FaultState('failed'))
    assert not sensor.measure(IDENTITY, tilt(0.0), 1.0).valid
    sensor.follow_fault('fine_sun_sensor', FaultState('recovered'))
    assert sensor.measure(IDENTITY, tilt(0.0), 1.0).valid


def and_allclose(a, b) -> bool:
    return bool(np.allclose(a, b, rtol=0, atol=1e-15))


def test_mounting_follows_the_attitude():
    """A boresight along body +y and a spacecraft turned 90 deg about z (body y = inertial -x): the
    Sun along inertial -x is on the boresight, read as body +y; an inertial +y Sun is out of view."""
    q = rotation_quaternion(np.array([0.0, 0.0, math.pi / 2]))
    sensor = FineSunSensor(0, 0.0, [0.0, 1.0, 0.0], math.radians(10.0))
    r = sensor.measure(q, rotate_to_inertial(q, np.array([0.0, 1.0, 0.0])), 1.0)
    assert r.valid and and_allclose(r.value, [0.0, 1.0, 0.0])
    assert not sensor.measure(q, np.array([0.0, 1.0, 0.0]), 1.0).valid


def test_a_run_alone_reads_what_it_reads_in_a_batch():
    """Seeds (4, 9, 2) as a batch and seed 9 alone, 20 steps of a turning attitude, bit for bit."""
    batch = FineSunSensor([4, 9, 2], SIGMA, BORESIGHT, math.radians(60.0))
    alone = FineSunSensor(9, SIGMA, BORESIGHT, math.radians(60.0))
    sun = _sun_at(0.2, -0.1)
    for k in range(20):
        q = rotation_quaternion(np.array([0.0, 0.02 * k, 0.01 * k]))
        qs = np.stack([quat_multiply(q, rotation_quaternion(np.array([0.01 * i, 0.0, 0.0]))) for i in range(3)])
        qs[1] = q
        b, a = batch.measure(qs, sun, 1.0), alone.measure(q, sun, 1.0)
        assert_array_equal(b.value[1], a.value)
        assert b.valid[1] == a.valid


def test_every_layer_reads_it_from_its_declarations():
    """Declared twice (interface, truth) and nowhere else, it has: a Measurements field, a topic with a
    Vector3Stamped spec and a QoS reason, the dynamics node as its only publisher, a fault target
    'failed', a 2-dof NIS in the analysis, a vector update with its own sigma in the MEKF (not in the
    single-frame estimator), its sensors.fine_sun_sensor.* block, and needs the environment."""
    assert 'fine_sun_sensor' in SENSORS and Measurements(0).fine_sun_sensor is None
    topic = names.SENSOR_TOPICS['fine_sun_sensor']
    assert topic == 'sensors/fine_sun' and topics.TOPICS[topic].msg_type.__name__ == 'Vector3Stamped'
    assert topic in topics.QOS_RATIONALE and names.PUBLISHER_ROLES[topic] == ('dynamics',)
    assert SENSOR_FAULT_MODES['fine_sun_sensor'] == ('failed',)
    assert NIS_DOF['fine_sun_sensor'] == ANALYSIS_NIS_DOF['fine_sun_sensor'] == 2
    assert 'fine_sun_sensor' in VECTOR_SENSORS and 'fine_sun_sensor' in NEEDS_ENVIRONMENT
    assert 'fine_sun_sensor.sigma' in {p.name for p in MEKF.schema.params}
    assert 'fine_sun_sensor.sigma' not in {p.name for p in QUEST.schema.params}
    v = DYNAMICS_SCHEMA.validate({**BASE, 'sensors.fine_sun_sensor.enabled': True})
    assert fault_targets(v) == {'fine_sun_sensor'}
    assert isinstance(build_sensors(v).fine_sun_sensor, FineSunSensor)


@pytest.mark.parametrize('key, value, text', [
    ('sensors.fine_sun_sensor.fov_deg', 90.0, r'\(0, 90\)'), ('sensors.fine_sun_sensor.fov_deg', 0.0, r'\(0, 90\)'),
    ('sensors.fine_sun_sensor.std', -1e-3, 'rad'), ('sensors.fine_sun_sensor.boresight', [0.0, 0.0, 0.0], 'zero'),
    ('sensors.fine_sun_sensor.min_illumination', 1.0, r'\[0, 1\)'),
])
def test_bad_values_are_refused_naming_the_key(key, value, text):
    with pytest.raises(ParameterError, match=text) as err:
        DYNAMICS_SCHEMA.validate({**BASE, 'sensors.fine_sun_sensor.enabled': True, key: value})
    assert err.value.key == key


def test_it_needs_the_environment_and_its_faults_are_failed_only():
    with pytest.raises(ParameterError, match='needs environment') as err:
        DYNAMICS_SCHEMA.validate({**BASE, 'environment.enabled': False, 'sensors.fine_sun_sensor.enabled': True})
    assert err.value.key == 'sensors.fine_sun_sensor.enabled'
    good = {'schedule.time': [1.0], 'schedule.actuator': ['fine_sun_sensor'], 'schedule.mode': ['failed']}
    assert fault_schedule(FAULT_SCHEMA.validate(good))[-1][1]['fine_sun_sensor'].mode == 'failed'
    with pytest.raises(ParameterError, match='fine_sun_sensor'):
        fault_schedule(FAULT_SCHEMA.validate({**good, 'schedule.mode': ['bias'], 'schedule.value': [0.1]}))


def test_its_message_round_trip_is_what_the_batch_engine_hands_the_estimator():
    """Each reading (valid, or not: the zero vector) through its declared codec (Vector3Stamped) reads
    back bit for bit, and equals the batch engine's as_received of it."""
    sensor = FineSunSensor(list(range(30)), SIGMA, BORESIGHT, math.radians(40.0), min_illumination=0.5)
    suns = np.array([_sun_at(a, b) for a, b in np.random.default_rng(3).uniform(-0.8, 0.8, (30, 2))])
    r = sensor.measure(np.tile(IDENTITY, (30, 1)), suns, np.linspace(0.0, 1.0, 30))
    assert r.valid.any() and not r.valid.all()
    codec = cd.SENSOR_CODECS['fine_sun_sensor']
    received = as_received(Measurements(5, fine_sun_sensor=r)).fine_sun_sensor
    for i in range(30):
        one = type(r)(r.value[i], r.cov[i], r.valid[i])
        t_ns, back = codec.from_msg(codec.to_msg(5, one), 'sensors/fine_sun')
        assert t_ns == 5 and back.valid == r.valid[i]
        assert_array_equal(back.value, received.value[i])
        if r.valid[i]:
            assert_array_equal(back.value, r.value[i])


def test_the_suite_reads_it_from_the_environment():
    """Through the suite (the dynamics node's and the batch engine's), it reads the environment's Sun
    and illumination; without them it refuses naming what it misses."""
    v = DYNAMICS_SCHEMA.validate({**BASE, 'sensors.fine_sun_sensor.enabled': True,
                                  'sensors.fine_sun_sensor.std': SIGMA})
    suite = build_sensors(v)
    env = SensorEnvironment(sun=np.array([0.0, 0.0, 1.0]), illumination=np.array(1.0))
    m = suite.measure(0, 0.0, IDENTITY, np.zeros(3), env)
    assert m.fitted() == ('fine_sun_sensor',) and m.fine_sun_sensor.valid
    with pytest.raises(ValueError, match='Sun direction and illumination'):
        build_sensors(v).measure(0, 0.0, IDENTITY, np.zeros(3))
