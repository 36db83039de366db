"""Scenario parameter validation without ROS: adcs_msgs_py.params + the node schemas.

Every refusal must be a ParameterError whose message names the offending key (the design rule:
"stop the node at start with a message that names the key").
"""
from __future__ import annotations

import copy
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose, assert_array_equal

from adcs_controllers.families import PD_SCHEMA
from adcs_msgs_py.params import ParameterError
from adcs_msgs_py.params_file import load_params_file
from adcs_sim.bag.schema import RECORDER_SCHEMA
from adcs_sim.truth.plant import ReactionWheels
from adcs_sim.truth.schema import DYNAMICS_SCHEMA, build_plant, initial_state

SCENARIO = Path(__file__).resolve().parents[1] / 'config' / 'microsat_pd_slew.yaml'
SCHEMAS = {'dynamics': DYNAMICS_SCHEMA, 'pd_controller': PD_SCHEMA, 'recorder': RECORDER_SCHEMA}


@pytest.fixture(scope='module')
def sections() -> dict:
    return load_params_file(str(SCENARIO))


def refused(schema, given: dict, key: str) -> ParameterError:
    """Validation of ``given`` fails with a ParameterError about ``key`` (named in the message)."""
    with pytest.raises(ParameterError) as info:
        schema.validate(given)
    err = info.value
    assert err.key == key, str(err)
    assert key in str(err)
    assert err.section == schema.node and f'{schema.node}.ros__parameters.{key}' in str(err)
    return err


def with_(section: dict, **changes) -> dict:
    """Copy of a flat section with dotted keys changed (``__`` in a keyword means ``.``)."""
    out = copy.deepcopy(section)
    for k, v in changes.items():
        out[k.replace('__', '.')] = v
    return out


def without(section: dict, key: str) -> dict:
    out = copy.deepcopy(section)
    del out[key]
    return out


# --- the shipped scenario -------------------------------------------------------------------------

def test_scenario_file_validates(sections):
    """Every section of config/microsat_pd_slew.yaml validates against its node's schema."""
    assert set(sections) == set(SCHEMAS)
    values = {name: SCHEMAS[name].validate(given) for name, given in sections.items()}
    dyn = values['dynamics']
    assert dyn['duration'] == 600.0 and dyn['control_period'] == 1.0
    assert dyn['wheels.names'] == ['rw_x', 'rw_y', 'rw_z']
    assert dyn['initial.attitude'] == [0.3062, 0.1768, 0.1768, 0.9186]
    assert dyn['integrator.max_step'] == 1.0
    assert values['pd_controller']['kp'] == 0.002 and values['pd_controller']['kd'] == 0.05
    assert values['pd_controller']['target.attitude'] == [0.0, 0.0, 0.0, 1.0]   # default
    assert values['recorder']['chunk_size'] == 65536


def test_build_plant_from_scenario(sections):
    """build_plant on the validated PD scenario: total inertia diag(12, 14, 10), three wheels on the
    body axes with spin inertia 0.01 (so the structure inertia is diag(11.99, 13.99, 9.99))."""
    v = DYNAMICS_SCHEMA.validate(sections['dynamics'])
    plant = build_plant(v)
    assert_array_equal(plant.inertia, np.diag([12.0, 14.0, 10.0]))
    assert_allclose(plant.inertia_struct, np.diag([11.99, 13.99, 9.99]), rtol=1e-15)
    wheels = plant.actuator('wheels')
    assert isinstance(wheels, ReactionWheels)
    assert wheels.names == ['rw_x', 'rw_y', 'rw_z']
    assert_array_equal(wheels.axes, np.eye(3))
    assert_array_equal(wheels.max_torque, 0.01)
    assert_array_equal(wheels.max_speed, 628.3)
    assert plant.disturbance is None and not plant.gravity_gradient
    x0 = initial_state(plant, v)
    assert x0.shape == (plant.n_states,) == (13,)
    assert_allclose(np.linalg.norm(x0[:4]), 1.0, rtol=1e-15)


def test_integer_accepted_for_double(sections):
    """kp: 1 is taken as 1.0 (a float, not an int)."""
    v = PD_SCHEMA.validate(with_(sections['pd_controller'], kp=1))
    assert v['kp'] == 1.0 and type(v['kp']) is float
    v = DYNAMICS_SCHEMA.validate(with_(sections['dynamics'], inertia=[12, 14, 10]))
    assert all(type(x) is float for x in v['inertia'])


def test_unlimited_wheel_limits_with_inf(sections):
    """`.inf` for a wheel's torque or speed limit means unlimited (as the parameter docs say)."""
    text = SCENARIO.read_text().replace('max_speed: [628.3, 628.3, 628.3]', 'max_speed: [.inf, .inf, .inf]')
    assert '.inf' in text
    tree = yaml.safe_load(text)
    given = with_(sections['dynamics'], wheels__max_speed=tree['dynamics']['ros__parameters']['wheels']['max_speed'],
                  wheels__max_torque=[math.inf] * 3)
    plant = build_plant(DYNAMICS_SCHEMA.validate(given))
    assert np.all(np.isinf(plant.actuator('wheels').max_speed))
    assert np.all(np.isinf(plant.actuator('wheels').max_torque))
    assert PD_SCHEMA.validate(with_(sections['pd_controller'], wheels__max_torque=[math.inf] * 3,
                                    torquers__max_torque=math.inf))['wheels.max_torque'] == [math.inf] * 3
    # ... but NaN is never a limit
    refused(DYNAMICS_SCHEMA, with_(sections['dynamics'], wheels__max_speed=[math.nan] * 3), 'wheels.max_speed')
    refused(PD_SCHEMA, with_(sections['pd_controller'], torquers__max_torque=math.nan), 'torquers.max_torque')


# --- files --------------------------------------------------------------------------------------

def test_malformed_yaml_file(tmp_path):
    """A file that is not YAML is refused, naming the file."""
    path = tmp_path / 'broken.yaml'
    path.write_text('dynamics:\n  ros__parameters:\n    inertia: [12.0, 14.0\n    duration: 5.0\n')
    with pytest.raises(ParameterError) as info:
        load_params_file(str(path))
    assert str(path) in str(info.value) and 'YAML' in str(info.value)


def test_missing_file(tmp_path):
    with pytest.raises(ParameterError, match='cannot read'):
        load_params_file(str(tmp_path / 'nope.yaml'))


def test_section_without_ros_parameters(tmp_path):
    """A node section must be {ros__parameters: {...}}: rcl refuses it, and so does the runner,
    quoting rcl (the line and the key it missed)."""
    path = tmp_path / 'flat.yaml'
    path.write_text('dynamics:\n  ros__parameters:\n    duration: 5.0\npd_controller:\n  kp: 0.002\n')
    with pytest.raises(ParameterError) as info:
        load_params_file(str(path))
    assert info.value.key == '<file>'
    assert str(path) in str(info.value) and 'ros__parameters at line 5' in str(info.value)


def test_params_file_is_flattened_and_leading_slash_stripped(tmp_path):
    path = tmp_path / 'ok.yaml'
    path.write_text('/dynamics:\n  ros__parameters:\n    integrator:\n      max_step: 0.5\n    duration: 5.0\n')
    assert load_params_file(str(path)) == {'dynamics': {'integrator.max_step': 0.5, 'duration': 5.0}}


# --- refusals, each naming its key --------------------------------------------------------------

def test_missing_required_duration(sections):
    refused(DYNAMICS_SCHEMA, without(sections['dynamics'], 'duration'), 'duration')


def test_missing_required_gain(sections):
    refused(PD_SCHEMA, without(sections['pd_controller'], 'kp'), 'kp')


@pytest.mark.parametrize('bad', ['fast', True, None, [0.1]], ids=['string', 'bool', 'null', 'list'])
def test_mistyped_double(sections, bad):
    """kp must be a number: a string, a bool (YAML true), null or a list is refused."""
    err = refused(PD_SCHEMA, with_(sections['pd_controller'], kp=bad), 'kp')
    assert 'double' in str(err)


def test_bool_not_accepted_in_double_array(sections):
    refused(DYNAMICS_SCHEMA, with_(sections['dynamics'], inertia=[12.0, True, 10.0]), 'inertia')


@pytest.mark.parametrize('key, value', [
    ('kp', math.nan), ('kp', math.inf), ('kd', -math.inf),
])
def test_non_finite_double(sections, key, value):
    err = refused(PD_SCHEMA, with_(sections['pd_controller'], **{key: value}), key)
    assert 'finite' in str(err)


@pytest.mark.parametrize('key, value', [
    ('inertia', [12.0, math.nan, 10.0]),
    ('initial.rate', [0.0, math.inf, 0.0]),
    ('duration', math.inf),
    ('disturbance.constant', [0.0, 0.0, math.nan]),
])
def test_non_finite_dynamics_values(sections, key, value):
    refused(DYNAMICS_SCHEMA, with_(sections['dynamics'], **{key.replace('.', '__'): value}), key)


@pytest.mark.parametrize('schema_name', ['dynamics', 'pd_controller'])
@pytest.mark.parametrize('inertia, why', [
    ([12.0, -14.0, 10.0], 'positive definite'),
    ([12.0, 0.0, 10.0], 'positive definite'),
    ([1.0, 2.0, 3.0, 2.0, 1.0, 0.0, 3.0, 0.0, 1.0], 'positive definite'),   # symmetric, indefinite
    ([1.0, 0.1, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0], 'symmetric'),
    ([1.0, 1.0, 3.0], 'triangle'),
], ids=['negative', 'zero', 'indefinite9', 'asymmetric', 'triangle'])
def test_non_physical_inertia(sections, schema_name, inertia, why):
    """Non-positive-definite, asymmetric, or triangle-inequality-violating inertia: refused."""
    err = refused(SCHEMAS[schema_name], with_(sections[schema_name], inertia=inertia), 'inertia')
    assert why in str(err)


def test_inertia_wrong_length(sections):
    refused(DYNAMICS_SCHEMA, with_(sections['dynamics'], inertia=[12.0, 14.0]), 'inertia')


def test_wheel_spin_inertia_too_large(sections):
    """Total inertia minus wheel spin inertia must stay positive definite."""
    err = refused(DYNAMICS_SCHEMA, with_(sections['dynamics'], wheels__spin_inertia=[0.01, 14.0, 0.01]),
                  'wheels.spin_inertia')
    assert 'positive definite' in str(err)


@pytest.mark.parametrize('schema_name', ['dynamics', 'pd_controller'])
def test_zero_length_wheel_axis(sections, schema_name):
    err = refused(SCHEMAS[schema_name], with_(sections[schema_name],
                                              wheels__axes=[1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]),
                  'wheels.axes')
    assert 'rw_y' in str(err) and 'zero length' in str(err)


@pytest.mark.parametrize('schema_name', ['dynamics', 'pd_controller'])
def test_negative_max_torque(sections, schema_name):
    refused(SCHEMAS[schema_name], with_(sections[schema_name], wheels__max_torque=[0.01, -0.01, 0.01]),
            'wheels.max_torque')


@pytest.mark.parametrize('key, value', [
    ('wheels.axes', [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]),
    ('wheels.max_torque', [0.01, 0.01]),
    ('wheels.spin_inertia', [0.01, 0.01, 0.01, 0.01]),
    ('wheels.max_speed', [628.3]),
    ('wheels.viscous_friction', [0.0, 0.0]),
    ('wheels.initial_speed', [1.0]),
])
def test_wrong_number_of_wheel_values(sections, key, value):
    """Per-wheel arrays must have one value per wheel (3 per wheel for axes); optional ones may be empty."""
    err = refused(DYNAMICS_SCHEMA, with_(sections['dynamics'], **{key.replace('.', '__'): value}), key)
    assert 'per wheel' in str(err)


def test_optional_wheel_arrays_may_be_empty(sections):
    v = DYNAMICS_SCHEMA.validate(with_(sections['dynamics'], wheels__viscous_friction=[]))
    assert_array_equal(build_plant(v).actuator('wheels').viscous, 0.0)


def test_duplicate_wheel_names(sections):
    refused(PD_SCHEMA, with_(sections['pd_controller'], wheels__names=['a', 'a', 'b']), 'wheels.names')


@pytest.mark.parametrize('schema_name, key', [
    ('dynamics', 'inertial'), ('dynamics', 'wheels.spin_inertias'), ('pd_controller', 'kI'),
    ('recorder', 'chunksize'),
])
def test_unknown_parameter(sections, schema_name, key):
    err = refused(SCHEMAS[schema_name], with_(sections[schema_name], **{key.replace('.', '__'): 1.0}), key)
    assert 'unknown' in str(err)


def test_builtin_ros_parameters_are_not_unknown(sections):
    DYNAMICS_SCHEMA.validate(with_(sections['dynamics'], use_sim_time=False))


@pytest.mark.parametrize('q', [[0.0, 0.0, 0.0, 2.0], [0.3, 0.2, 0.2, 0.9], [0.0, 0.0, 0.0, 0.0]])
def test_non_unit_initial_attitude(sections, q):
    """The initial quaternion must be unit within 1e-3 (the seed's 4-digit value is accepted)."""
    err = refused(DYNAMICS_SCHEMA, with_(sections['dynamics'], initial__attitude=q), 'initial.attitude')
    assert 'unit norm' in str(err)


def test_non_unit_target_attitude(sections):
    refused(PD_SCHEMA, with_(sections['pd_controller'], target__attitude=[0.0, 0.0, 0.5, 0.5]), 'target.attitude')


def test_unknown_lockstep_command_topic(sections):
    err = refused(DYNAMICS_SCHEMA, with_(sections['dynamics'], lockstep__commands=['wheels/cmd', 'thrust_cmd']),
                  'lockstep.commands')
    assert 'thrust_cmd' in str(err)


def test_lockstep_waits_for_missing_actuator(sections):
    refused(DYNAMICS_SCHEMA, with_(sections['dynamics'], lockstep__commands=['torque_cmd']), 'lockstep.commands')


def test_max_step_exceeds_control_period(sections):
    err = refused(DYNAMICS_SCHEMA, with_(sections['dynamics'], integrator__max_step=2.0), 'integrator.max_step')
    assert 'control_period' in str(err)
    # equal is fine
    DYNAMICS_SCHEMA.validate(with_(sections['dynamics'], integrator__max_step=1.0))


def test_duration_shorter_than_a_period(sections):
    refused(DYNAMICS_SCHEMA, with_(sections['dynamics'], duration=0.5), 'duration')


@pytest.mark.parametrize('key, value', [('control_period', 0.0), ('duration', -1.0), ('kd', -0.1)])
def test_non_positive_values(sections, key, value):
    schema_name = 'pd_controller' if key == 'kd' else 'dynamics'
    refused(SCHEMAS[schema_name], with_(sections[schema_name], **{key: value}), key)


@pytest.mark.parametrize('key, value', [('mode', 'fast'), ('saturation', 'wrap')])
def test_choices(sections, key, value):
    schema_name = 'dynamics' if key == 'mode' else 'pd_controller'
    err = refused(SCHEMAS[schema_name], with_(sections[schema_name], **{key: value}), key)
    assert 'one of' in str(err)


def test_gravity_gradient_needs_altitude(sections):
    refused(DYNAMICS_SCHEMA, with_(sections['dynamics'], gravity_gradient=True), 'orbit.altitude')


def test_controller_wheels_actuator_needs_wheels(sections):
    given = {k: v for k, v in sections['pd_controller'].items() if not k.startswith('wheels.')}
    refused(PD_SCHEMA, given, 'wheels.names')
    # torquers need no wheels
    PD_SCHEMA.validate(with_(given, actuator='torquers'))


def test_recorder_int_parameter(sections):
    """chunk_size is an int: a float is refused, a positive int accepted."""
    refused(RECORDER_SCHEMA, with_(sections['recorder'], chunk_size=1024.5), 'chunk_size')
    refused(RECORDER_SCHEMA, with_(sections['recorder'], chunk_size=0), 'chunk_size')
    assert RECORDER_SCHEMA.validate(with_(sections['recorder'], chunk_size=1024))['chunk_size'] == 1024


def test_errors_from_a_file_name_section_and_key(tmp_path, sections):
    """End to end: a mistyped value in a written file is reported as <section>.ros__parameters.<key>."""
    tree = yaml.safe_load(SCENARIO.read_text())
    tree['pd_controller']['ros__parameters']['kp'] = 'fast'
    path = tmp_path / 'bad.yaml'
    path.write_text(yaml.safe_dump(tree))
    loaded = load_params_file(str(path))
    with pytest.raises(ParameterError, match=r"'pd_controller\.ros__parameters\.kp'"):
        PD_SCHEMA.validate(loaded['pd_controller'])


def test_an_unknown_key_names_its_close_matches_in_one_line():
    """A misspelt key: the message is one line with at most five close matches and where every
    parameter is described, never the whole list of the section's keys."""
    with pytest.raises(ParameterError) as err:
        DYNAMICS_SCHEMA.validate({'inertai': [1.0, 2.0, 3.0]})
    message = str(err.value)
    assert '\n' not in message
    assert "did you mean 'inertia'?" in message
    assert 'docs/parameters.md' in message
    assert 'wheels.max_torque' not in message and len(message) < 300
    suggested = message.split('did you mean ', 1)[1].split('?', 1)[0]
    assert 1 <= suggested.count("'") // 2 <= 5


def test_an_unknown_key_far_from_any_says_where_the_keys_are():
    with pytest.raises(ParameterError) as err:
        PD_SCHEMA.validate({'inertia': [1.0, 1.0, 1.0], 'kp': 1.0, 'kd': 1.0, 'zzzzqqq': 1})
    message = str(err.value)
    assert 'did you mean' not in message and 'docs/parameters.md' in message and 'target.rate' not in message
