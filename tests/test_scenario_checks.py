"""The sections of a scenario agree with each other, and the run's needs fit, before anything
starts (issue #17): otherwise every step waits out the lockstep timeout and the run exits 0, or
the dynamics node allocates terabytes, or a step never ends."""
from __future__ import annotations

import pytest
from support.paths import CONFIG
from support.scenarios import make_scenario

from adcs_msgs_py.params import ParameterError
from adcs_sim.app.scenario import checks as scenario_checks
from adcs_sim.app.scenario.checks import check_resources
from adcs_sim.app.scenario.files import validate_scenario


def refused(path, section: str, key: str, *words: str) -> str:
    with pytest.raises(ParameterError) as info:
        validate_scenario(path)
    message = str(info.value)
    assert f'{section}.ros__parameters.{key}' in message, message
    for word in words:
        assert word in message, message
    return message


@pytest.mark.parametrize('scenario', sorted(p.name for p in CONFIG.glob('*.yaml')))
def test_every_shipped_scenario_agrees_and_fits(scenario):
    validate_scenario(CONFIG / scenario)


def test_controller_wheel_names_differ_from_the_plants(tmp_path):
    path = make_scenario(tmp_path, {'pd_controller': {'wheels.names': ['a', 'b', 'c']}})
    refused(path, 'pd_controller', 'wheels.names', "['rw_x', 'rw_y', 'rw_z']", 'lockstep timeout')


def test_controller_has_fewer_wheels_than_the_plant(tmp_path):
    path = make_scenario(tmp_path, {'pd_controller': {
        'wheels.names': ['rw_x', 'rw_y'], 'wheels.axes': [1.0, 0.0, 0.0, 0.0, 1.0, 0.0],
        'wheels.max_torque': [0.01, 0.01]}})
    refused(path, 'pd_controller', 'wheels.names', 'rw_z')


def test_fault_injector_wheels_differ_from_the_plants(tmp_path):
    path = make_scenario(tmp_path, {'fault_injector': {
        'wheels.names': ['rw_x', 'rw_y', 'rw_q'], 'schedule.time': [10.0], 'schedule.actuator': ['rw_x'],
        'schedule.mode': ['failed']}})
    refused(path, 'fault_injector', 'wheels.names', 'rw_q')


def test_fault_on_a_wheel_the_plant_does_not_have(tmp_path):
    path = make_scenario(tmp_path, {'fault_injector': {
        'wheels.names': ['rw_x', 'rw_y', 'rw_z', 'rw_w'], 'schedule.time': [10.0], 'schedule.actuator': ['rw_w'],
        'schedule.mode': ['failed']}})
    refused(path, 'fault_injector', 'schedule.actuator', 'rw_w')


def test_actuator_kinds_disagree(tmp_path):
    """A torquer controller for a plant without torquers: the plant waits for wheels/cmd forever."""
    path = make_scenario(tmp_path, {'pd_controller': {'actuator': 'torquers'}})
    refused(path, 'pd_controller', 'actuator', "['torque_cmd']", "['wheels/cmd']")


def test_plant_waits_for_a_command_the_controller_never_sends(tmp_path):
    path = make_scenario(tmp_path, {'dynamics': {'torquers.enabled': True}})
    refused(path, 'pd_controller', 'actuator', 'torque_cmd')


def test_thruster_names_differ(tmp_path):
    path = make_scenario(tmp_path, {'backstepping_controller': {'thrusters.names': ['t1', 't2', 't3', 't4']}},
                         base='eseo_backstepping.yaml')
    refused(path, 'backstepping_controller', 'thrusters.names', 'thr_1')


def test_a_duration_whose_memory_cannot_be_met_is_refused(tmp_path):
    path = make_scenario(tmp_path, {'dynamics': {'duration': 1.0e15}})
    refused(path, 'dynamics', 'duration', 'GiB', '1000000000000000 control steps')


def test_the_memory_need_is_what_the_machine_has(monkeypatch):
    dyn = {'duration': 1000.0, 'control_period': 1.0, 'integrator.max_step': 1.0}
    check_resources(dyn, memory=2 * 1000 * scenario_checks.DYNAMICS_BYTES_PER_STEP)
    with pytest.raises(ParameterError, match='duration'):
        check_resources(dyn, memory=2 * 999 * scenario_checks.DYNAMICS_BYTES_PER_STEP)


def test_an_integrator_step_count_per_period_that_cannot_run_is_refused(tmp_path):
    path = make_scenario(tmp_path, {'dynamics': {'integrator.max_step': 1.0e-9}})
    refused(path, 'dynamics', 'integrator.max_step', '1000000000 RK4 sub-steps')
