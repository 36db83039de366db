"""Red team of the sensors' parameters and sensor faults: every ``sensors.*`` key refuses bad values
naming the key (explicit cases and a derandomised fuzz), the cross-checks (update period and latency
on the control grid, the vector sensors needing the environment), hostile fault-schedule entries and
``faults`` messages for sensors, sensors off by default (a scenario without the block is unchanged),
and the batch engine applying sensor faults with no wheels and rerunning from t = 0."""
from __future__ import annotations

import math

import numpy as np
import pytest
from diagnostic_msgs.msg import KeyValue
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose, assert_array_equal
from support.scenarios import make_scenario

from adcs_core.attitude import quat_conjugate, quat_multiply, rotation_vector
from adcs_core.faults import FaultState
from adcs_msgs_py import conversions as cv
from adcs_msgs_py.params import ParameterError
from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.scenario.files import validate_scenario
from adcs_sim.truth.fault_schedule import FAULT_SCHEMA, fault_schedule
from adcs_sim.truth.schema import DYNAMICS_SCHEMA
from adcs_sim.truth.sensor_schema import build_sensors

BASE = {'inertia': [12.0, 14.0, 10.0], 'duration': 10.0, 'control_period': 0.5}
SENSOR_KEYS = [p for p in DYNAMICS_SCHEMA.params if p.name.startswith('sensors.')]


def validate(**given):
    return DYNAMICS_SCHEMA.validate({**BASE, **given})


def test_sensors_are_off_by_default():
    v = validate()
    assert build_sensors(v) is None
    assert all(not v[p.name] for p in SENSOR_KEYS if p.name.endswith('.enabled'))


BAD = [
    ('sensors.seed', -1, '>= 0'), ('sensors.seed', 1.5, 'integer'),
    ('sensors.gyro.enabled', 1, 'true or false'),
    ('sensors.gyro.arw', -1e-4, r'\[0, 1.0\]'), ('sensors.gyro.arw', math.nan, 'finite'),
    ('sensors.gyro.rrw', math.inf, 'finite'), ('sensors.gyro.bias', [0.0, 0.0], '3 values'),
    ('sensors.gyro.scale_factor', [0.0, -1.0, 0.0], r'\(-1, 1\]'), ('sensors.gyro.max_rate', 0.0, '> 0'),
    ('sensors.gyro.max_rate', math.nan, 'NaN'), ('sensors.gyro.markov_std', -1.0, 'rad/s'),
    ('sensors.gyro.markov_time', 0.0, '> 0'), ('sensors.gyro.arw', 2.0, r'\[0, 1.0\]'),
    ('sensors.gyro.rrw', 1e300, r'\[0, 1.0\]'), ('sensors.gyro.bias', [0.0, 11.0, 0.0], 'within'),
    ('sensors.gyro.scale_factor', [1e300, 0.0, 0.0], r'\(-1, 1\]'), ('sensors.gyro.markov_std', 1e9, 'rad/s'),
    ('sensors.star_tracker.cross_std', 4.0, 'rad'), ('sensors.star_tracker.period', 1e300, 'beyond any run'),
    ('sensors.star_tracker.latency', 1e12, 'beyond any run'), ('sensors.magnetometer.std', 1.0, 'T'),
    ('sensors.magnetometer.bias', [0.0, 0.0, -0.1], 'within'),
    ('sensors.star_tracker.enabled', 'yes', 'true or false'),
    ('sensors.star_tracker.boresight', [0.0, 0.0, 0.0], 'zero vector'),
    ('sensors.star_tracker.cross_std', -1e-6, 'rad'), ('sensors.star_tracker.about_std', 'big', 'number'),
    ('sensors.star_tracker.period', -1.0, '>= 0'), ('sensors.star_tracker.period', 0.7, 'multiple of control_period'),
    ('sensors.star_tracker.latency', 0.25, 'multiple of control_period'),
    ('sensors.star_tracker.latency', 1e6, 'at most'),
    ('sensors.star_tracker.sun_exclusion_deg', 180.0, r'\[0, 180\)'),
    ('sensors.star_tracker.earth_exclusion_deg', -5.0, r'\[0, 180\)'),
    ('sensors.sun.std', -1.0, 'rad'), ('sensors.sun.type', 'fine', 'one of'),
    ('sensors.sun.normals', [1.0, 0.0, 0.0], 'only for sensors.sun.type'),
    ('sensors.sun.boresight', [1.0, 2.0], '3 values'),
    ('sensors.sun.fov_deg', 0.0, r'\(0, 180\]'), ('sensors.sun.min_illumination', 1.0, r'\[0, 1\)'),
    ('sensors.magnetometer.std', math.inf, 'finite'), ('sensors.magnetometer.bias', [1.0, math.nan, 0.0], 'finite'),
    ('sensors.sun.enabled', True, 'needs environment'), ('sensors.magnetometer.enabled', True, 'needs environment'),
    ('sensors.fine_sun_sensor.enabled', True, 'needs environment'), ('sensors.fine_sun_sensor.std', -1.0, 'rad'),
    ('sensors.fine_sun_sensor.boresight', [1.0, 2.0], '3 values'),
    ('sensors.fine_sun_sensor.fov_deg', 90.0, r'\(0, 90\)'),
    ('sensors.fine_sun_sensor.min_illumination', 1.0, r'\[0, 1\)'),
]


@pytest.mark.parametrize('key, value, text', BAD, ids=[f'{k}={v!r}' for k, v, _ in BAD])
def test_bad_sensor_values_are_refused_naming_the_key(key, value, text):
    with pytest.raises(ParameterError, match=text) as err:
        validate(**{key: value})
    assert err.value.key == key and f'dynamics.ros__parameters.{key}' in str(err.value)


@pytest.mark.parametrize('normals, text', [
    ([1.0, 0.0, 0.0, 0.0, 1.0, 0.0], 'at least 3'), ([1.0, 0.0, 0.0, 0.0, 1.0], 'at least 3'),
    ([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0], 'non-zero'),
    ([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0], 'span 3-D')])
def test_coarse_sun_sensor_normals_are_checked(normals, text):
    with pytest.raises(ParameterError, match=text) as err:
        validate(**{'sensors.sun.type': 'coarse', 'sensors.sun.normals': normals})
    assert err.value.key == 'sensors.sun.normals'
    # a valid assembly passes the sensor checks
    assert validate(**{'sensors.sun.type': 'coarse', 'sensors.sun.normals': [1.0, 0, 0, 0, 1, 0, 0, 0, 1]})


def test_every_sensor_key_has_a_bad_case():
    assert {p.name for p in SENSOR_KEYS} <= {k for k, _, _ in BAD}


_values = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**6, 10**6), st.booleans(),
                    st.text(max_size=3), st.lists(st.floats(allow_nan=True), max_size=4))


@settings(derandomize=True, max_examples=150, deadline=None, suppress_health_check=list(HealthCheck))
@given(st.sampled_from(SENSOR_KEYS), _values)
def test_fuzzed_sensor_values_validate_or_name_the_key(param, value):
    """Any value: validated (and a suite built from it measures finite numbers), or refused with a
    ParameterError naming that key; never another exception."""
    try:
        v = validate(**{param.name: value, 'sensors.gyro.enabled': True, 'sensors.star_tracker.enabled': True}
                     if not param.name.endswith('.enabled') else {param.name: value})
    except ParameterError as exc:
        assert exc.key == param.name
        return
    suite = build_sensors(v)
    if suite is not None and 'sun' not in suite.fitted() and 'magnetometer' not in suite.fitted():
        for k in range(3):
            m = suite.measure(k, k * 0.5, np.array([0.0, 0.0, 0.0, 1.0]), np.array([0.01, 0.0, -0.01]))
            for name in m.fitted():
                assert np.isfinite(getattr(m, name).value).all()


# --- sensor faults ------------------------------------------------------------------------------

def schedule(**overrides):
    v = {'schedule.time': [1.0, 2.0], 'schedule.actuator': ['star_tracker', 'gyro.x'],
         'schedule.mode': ['failed', 'bias'], 'schedule.value': [0.0, 0.01]}
    v.update(overrides)
    return v


@pytest.mark.parametrize('overrides, key, text', [
    ({'schedule.mode': ['bias', 'bias']}, 'schedule.mode', 'star_tracker has no mode'),
    ({'schedule.mode': ['failed', 'degraded']}, 'schedule.mode', 'gyro.x has no mode'),
    ({'schedule.actuator': ['star_tracker', 'gyro.w']}, 'schedule.actuator', 'gyro.w'),
    ({'schedule.value': [0.0, 1e3]}, 'schedule.value', 'gyro bias jump'),
    ({'schedule.value': [0.0, math.inf]}, 'schedule.value', 'finite'),
    ({'wheels.names': ['magnetometer']}, 'wheels.names', 'sensor fault targets'),
])
def test_hostile_sensor_fault_entries_are_refused(overrides, key, text):
    with pytest.raises(ParameterError, match=text) as err:
        FAULT_SCHEMA.validate(schedule(**overrides))
    assert err.value.key == key


def test_sensor_fault_snapshots_carry_only_the_named_targets():
    snaps = fault_schedule(FAULT_SCHEMA.validate(schedule(**{'wheels.names': ['rw']})))
    assert list(snaps[0][1]) == ['rw', 'star_tracker', 'gyro.x']
    assert snaps[2][1]['gyro.x'] == FaultState('bias', 0.01, 2.0)
    assert list(fault_schedule(FAULT_SCHEMA.validate({'wheels.names': ['rw']}))[0][1]) == ['rw']


def test_scenario_refuses_a_fault_on_a_sensor_not_fitted(tmp_path):
    with pytest.raises(ParameterError, match='sensors fitted: none') as err:
        validate_scenario(make_scenario(tmp_path, {'fault_injector': schedule()}))
    assert err.value.key == 'schedule.actuator'
    fitted = {'sensors.gyro.enabled': True, 'sensors.star_tracker.enabled': True}
    assert 'fault_injector' in validate_scenario(make_scenario(tmp_path, {'fault_injector': schedule(),
                                                                          'dynamics': fitted}))


def _status_msg(name, mode, value='0.0'):
    snapshot = {name: FaultState('nominal')}
    msg = cv.faults_to_msg(0, snapshot, 0, 1)
    msg.status[0].values = [KeyValue(key='mode', value=mode), KeyValue(key='value', value=value),
                            KeyValue(key='time', value='0.0'), KeyValue(key='event', value='0'),
                            KeyValue(key='events', value='1')]
    return msg


@pytest.mark.parametrize('name, mode, value, text', [
    ('star_tracker', 'stuck', '0.0', 'unknown mode'), ('gyro.y', 'degraded', '0.0', 'unknown mode'),
    ('gyro.z', 'bias', 'nan', 'not valid'), ('gyro.q', 'bias', '0.0', 'unknown actuator'),
])
def test_hostile_sensor_fault_messages_are_rejected(name, mode, value, text):
    with pytest.raises(cv.InvalidMessage, match=text):
        cv.faults_from_msg(_status_msg(name, mode, value), {'rw_x': 0})


def test_sensor_fault_messages_are_accepted_by_any_node():
    """A controller knows only its wheels: the sensor targets pass through its parse."""
    t, event, events, snap = cv.faults_from_msg(_status_msg('gyro.x', 'bias', '0.02'), {'rw_x': 0})
    assert snap == {'gyro.x': FaultState('bias', 0.02, 0.0)} and (event, events) == (0, 1)


def test_batch_applies_sensor_faults_without_wheels_and_reruns_from_t0(tmp_path):
    """Free flight (no controller), a torquer-less, wheel-less plant: the star tracker fails at 2 s
    and recovers at 3.5 s (between steps: from the next step, 4 s); run() twice gives the same
    readings (the suite is rebuilt for each run)."""
    scenario = make_scenario(tmp_path, {
        'dynamics': {'duration': 6.0, 'wheels': None, 'sensors.star_tracker.enabled': True,
                     'sensors.star_tracker.cross_std': 1e-4, 'sensors.gyro.enabled': True,
                     'sensors.gyro.arw': 1e-4, 'lockstep.commands': ['none']},
        'fault_injector': {'schedule.time': [2.0, 3.5], 'schedule.actuator': ['star_tracker'] * 2,
                           'schedule.mode': ['failed', 'recovered']}}, drop=('pd_controller',))
    sim = BatchSimulation.from_runs([validate_scenario(scenario)])
    sim.record_sensors = True
    first = sim.run()
    assert_array_equal(first.sensors['star_tracker']['valid'][0], [True, True, False, False, True, True, True])
    second = sim.run()
    for name in ('gyro', 'star_tracker'):
        assert_array_equal(first.sensors[name]['value'], second.sensors[name]['value'])


def test_batch_records_the_gyro_true_bias(tmp_path):
    """BatchResult.sensors['gyro']['bias'] is the bias in each reading: a noiseless gyro with a bias
    jump on x at 2 s reads its rate plus that bias exactly (the rate of the step that ended: the
    rotation vector of the attitude increment over the period; the true rate at t = 0)."""
    scenario = make_scenario(tmp_path, {
        'dynamics': {'duration': 4.0, 'sensors.gyro.enabled': True, 'sensors.gyro.bias': [1e-3, 0.0, -2e-3]},
        'fault_injector': {'schedule.time': [2.0], 'schedule.actuator': ['gyro.x'], 'schedule.mode': ['bias'],
                           'schedule.value': [0.05]}})
    sim = BatchSimulation.from_runs([validate_scenario(scenario)])
    sim.record_sensors = True
    result = sim.run()
    bias = result.sensors['gyro']['bias'][0]
    assert_array_equal(bias[:2], [[1e-3, 0.0, -2e-3]] * 2)
    assert_array_equal(bias[2:], [[1e-3 + 0.05, 0.0, -2e-3]] * 3)
    q, period = result.q[0], result.t[1] - result.t[0]
    mean = rotation_vector(quat_multiply(quat_conjugate(q[:-1]), q[1:])) / period
    rate = np.concatenate([result.w[0, :1], mean])
    assert_allclose(result.sensors['gyro']['value'][0], rate + bias, rtol=1e-15, atol=1e-18)
