"""A control period's kernel inputs are packed once (adcs_sim.truth.kernel.KernelPlan): Plant.step
reuses what Plant.control_torque packed for the same state and commands, and only then.

* control_torque then step with the same objects (what the dynamics node and the batch engine do)
  gives the numpy plant's step bit for bit;
* a step with other commands (a new dict, or the same dict with an entry replaced, as the dynamics
  node replaces a command) or another state after control_torque packs its own inputs;
* the packed inputs are used once: a second step of the same objects packs again.
"""
from __future__ import annotations

import numpy as np
from numpy.testing import assert_array_equal
from support.plant_cases import inertia, state, wheel_command, wheels

from adcs_sim.truth.plant import Plant, WheelCommand


def plant_and_inputs():
    plant = Plant(inertia(), [wheels()])
    x = state(plant)
    return plant, x, {'wheels': wheel_command()}


def numpy_step(plant, x, commands):
    return plant.step_numpy(3.0, x, commands, 1.0, 0.25)


def test_step_after_control_torque_reuses_the_packing_and_equals_numpy(monkeypatch):
    plant, x, commands = plant_and_inputs()
    packs = []
    original = type(plant.kernel)._inputs
    monkeypatch.setattr(type(plant.kernel), '_inputs', lambda self, *a: packs.append(1) or original(self, *a))
    assert_array_equal(plant.control_torque(3.0, x, commands), plant.control_torque_numpy(3.0, x, commands))
    assert_array_equal(plant.step(3.0, x, commands, 1.0, 0.25), numpy_step(plant, x, commands))
    assert len(packs) == 1
    plant.step(3.0, x, commands, 1.0, 0.25)  # used once: packed again
    assert len(packs) == 2


def test_other_commands_or_state_after_control_torque_are_packed_afresh():
    plant, x, commands = plant_and_inputs()
    other = WheelCommand(-commands['wheels'].value, commands['wheels'].speed_mode)
    plant.control_torque(3.0, x, commands)
    assert_array_equal(plant.step(3.0, x, {'wheels': other}, 1.0, 0.25), numpy_step(plant, x, {'wheels': other}))
    plant.control_torque(3.0, x, commands)
    commands['wheels'] = other  # the dynamics node replaces a command in its dict
    assert_array_equal(plant.step(3.0, x, commands, 1.0, 0.25), numpy_step(plant, x, commands))
    plant.control_torque(3.0, x, commands)
    y = x.copy()
    y[4] += 0.01
    assert_array_equal(plant.step(3.0, y, commands, 1.0, 0.25), numpy_step(plant, y, commands))
    assert not np.array_equal(numpy_step(plant, y, commands), numpy_step(plant, x, commands))
