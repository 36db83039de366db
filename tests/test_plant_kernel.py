"""The compiled plant kernel (adcs_sim.truth.kernel) equals the numpy plant bit for bit. No ROS.

``Plant.step`` and ``Plant.control_torque`` run on the kernel; ``Plant.step_numpy`` and
``Plant.control_torque_numpy`` are the numpy reference. Every actuator
model and every branch of it (speed loop, limits, friction, each fault mode, thrusters with pulse
edges, disturbance, gravity gradient), single runs and batches (on one thread and on all
threads), dispersed parameters, and runs that diverge to inf/NaN.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_array_equal
from support.plant_cases import AXES, inertia, state, wheel_command, wheels

from adcs_core.orbit import CircularOrbit
from adcs_sim.truth import kernel
from adcs_sim.truth.plant import Disturbance, Plant, ReactionWheels, Torquers, WheelCommand
from adcs_sim.truth.thrusters import Thrusters, step_pulsed


def same(plant: Plant, x, commands, period=1.0, max_step=0.25, t=3.0):
    assert plant.kernel is not None
    with np.errstate(all='ignore'):
        fast = plant.step(t, x, commands, period, max_step)
        ref = plant.step_numpy(t, x, commands, period, max_step)
        tau, tau_ref = plant.control_torque(t, x, commands), plant.control_torque_numpy(t, x, commands)
    assert fast.shape == ref.shape and tau.shape == tau_ref.shape
    assert_array_equal(fast, ref)
    assert_array_equal(tau, tau_ref)
    return fast


@pytest.mark.parametrize('batch', [(), (1,), (3,), (12,), (2, 5)])
def test_wheels_friction_speed_loop_and_limits(batch):
    plant = Plant(inertia(batch), [wheels(batch, viscous=[1e-5] * 4, coulomb=[2e-4, 0, 1e-4, 0],
                                          speed_gain=[0.5, 1.0, 2.0, 0.1])])
    x = state(plant, batch)
    same(plant, x, {'wheels': wheel_command(batch)})
    same(plant, x, {'wheels': wheel_command(batch, (False,) * 4)}, period=0.7, max_step=0.1)


@pytest.mark.parametrize('mode,value', [('failed', 0.0), ('degraded', 0.005), ('bias', 0.003),
                                        ('stuck', 0.0), ('recovered', 0.0)])
def test_every_wheel_fault(mode, value):
    plant = Plant(inertia(), [wheels(coulomb=[1e-4] * 4)])
    w = plant.actuator('wheels')
    w.apply_fault(1, 'stuck')
    w.apply_fault(2, mode, value)
    x = state(plant)
    for _ in range(3):
        x = same(plant, x, {'wheels': wheel_command()})
    w.available[:] = [True, False, True, False]  # changed in place, as tests and nodes may
    same(plant, x, {'wheels': wheel_command()})


def test_torquers_disturbance_and_gravity_gradient():
    orbit = CircularOrbit(700e3, inclination=math.radians(98.0), raan=0.3, arg_latitude0=1.0)
    dist = Disturbance([1e-5, 0, -2e-5], [3e-5, 1e-5, 0], [0.001, 0.01, 0.1], [0, 1, 2])
    plant = Plant(inertia((6,)), [Torquers(max_torque=[0.01, 0.02, 0.005])], dist, orbit, True)
    x = state(plant, (6,))
    cmd = np.random.default_rng(7).uniform(-0.03, 0.03, (6, 3))
    same(plant, x, {'torquers': cmd}, period=2.0, max_step=0.3, t=1234.5)


def test_thrusters_with_pulse_edges_and_a_wheel():
    pos = [[0.3, 0.3, 0.5], [-0.3, 0.3, 0.5], [-0.3, -0.3, 0.5], [0.3, -0.3, 0.5]]
    dirs = [[0, 1, 0], [-1, 0, 0], [0, -1, 0], [1, 0, 0]]
    thr = Thrusters([f't{i}' for i in range(4)], pos, dirs, [0.01, 0.01, 0.02, 0.01], min_on_time=0.02)
    rw = ReactionWheels(['rw_y'], [[0, 1, 0]], [0.01], [0.01], [600.0])
    plant = Plant(inertia(), [thr, rw])
    x = state(plant)
    commands = {'thrusters': thr.command(10.0, [0.0, 0.33, 1.0, 0.71], 1.0),
                'wheels': WheelCommand(np.array([0.004]), np.array([False]))}
    with np.errstate(all='ignore'):
        fast = step_pulsed(plant, 10.0, x, commands, 1.0, 0.1)
        plant.kernel, kept = None, plant.kernel
        ref = step_pulsed(plant, 10.0, x, commands, 1.0, 0.1)
        plant.kernel = kept
    assert_array_equal(fast, ref)
    same(plant, x, commands, t=10.0)


def test_diverging_runs_give_the_same_inf_and_nan():
    plant = Plant(inertia((9,)), [wheels((9,), max_torque=np.full(4, np.inf), max_speed=np.full(4, np.inf))])
    x = state(plant, (9,), scale=1e150)
    x[0, 4] = np.nan
    out = same(plant, x, {'wheels': WheelCommand(np.full((9, 4), 1e300), np.zeros(4, dtype=bool))})
    assert not np.isfinite(out).all()


def test_a_run_is_the_same_in_any_batch(monkeypatch):
    """The threaded kernel (a batch of 16) gives each run the bits of that run alone."""
    monkeypatch.setattr(kernel, 'PARALLEL_MIN_RUNS', 2)
    monkeypatch.setattr(kernel, 'PARALLEL_MIN_WORK', 2)
    plant = Plant(inertia((16,)), [wheels((16,))])
    x, cmd = state(plant, (16,)), wheel_command((16,))
    together = plant.step(0.0, x, {'wheels': cmd}, 1.0, 0.25)
    assert_array_equal(together, plant.step_numpy(0.0, x, {'wheels': cmd}, 1.0, 0.25))
    for i in (0, 7, 15):
        alone = Plant(inertia((16,))[i], [wheels((16,))]).actuator('wheels')
        one = Plant(inertia((16,))[i], [ReactionWheels(alone.names, AXES, wheels((16,)).spin_inertia[i],
                                                        wheels((16,)).max_torque[i], alone.max_speed)])
        assert_array_equal(one.step(0.0, x[i], {'wheels': WheelCommand(cmd.value[i], cmd.speed_mode)}, 1.0, 0.25),
                           together[i])


def test_an_unknown_actuator_keeps_the_numpy_path():
    class Magnetorquer(Torquers):
        kernel_kind = None

    plant = Plant(inertia(), [Magnetorquer(name='mtq')])
    assert plant.kernel is None
    x = state(plant)
    out = plant.step(0.0, x, {'mtq': np.array([0.01, 0.0, 0.0])}, 1.0, 0.5)
    assert_array_equal(out, plant.step_numpy(0.0, x, {'mtq': np.array([0.01, 0.0, 0.0])}, 1.0, 0.5))


def test_compiled_without_fastmath_and_with_numpy_errors():
    """What the bit-for-bit argument rests on (module doc of adcs_sim.truth.kernel)."""
    for fn in (kernel.rk4_runs, kernel.torque_runs):
        options = fn.targetoptions
        assert not options.get('fastmath', False)
        assert options['error_model'] == 'numpy'
