"""Seed 000 on the graph: dynamics + fault injector + a reconfiguring two-wheel controller in lockstep.

The node-pair tests of issue 6: the controller runs the three-wheel PD until the fault topic says
rw_z failed, switches to the two-wheel law at that very step, the failed wheel produces no torque
afterwards, and the attitude converges; the recorded run is the batch engine's run of the same
scenario. Also: a two-wheel law from the start, and the parameter checks of the seed 000 nodes.
"""
from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_array_equal
from support.ros_graph import run_fault_graph
from support.scenarios import make_scenario

from adcs_msgs_py.params import ParameterError

Q_OFF = [0.2236068, 0.2236068, 0.2236068, 0.9219544]  # seed 000 VI.A q(0), normalised (readings R1)
T_FAULT = 20.0


def reconfiguring_scenario(tmp_path, base: str, controller: str, n: int, fault_time: float = T_FAULT,
                           extra: dict | None = None):
    """``base`` (a config/uosat12_*.yaml) at rest at the off-pointing attitude, the PD holding it,
    rw_z failing at ``fault_time``, ``n`` steps, recorded to ``tmp_path/bag``."""
    expect = {'startup.expect_recorder': True, 'startup.expect_faults': True}
    over = {
        'dynamics': {'duration': float(n), 'initial.attitude': Q_OFF, **expect},
        controller: dict(expect, **(extra or {})),
        'fault_injector': {'schedule.time': [fault_time], 'startup.expect_recorder': True},
        'recorder': {'output': str(tmp_path / 'bag')},
    }
    return make_scenario(tmp_path, over, base=base)


def test_zero_momentum_reconfiguration_in_lockstep(ros_domain, tmp_path):
    """Three-wheel PD until t = 20 s, rw_z fails, the zero-momentum law (wheel SPEED commands to
    rw_x, rw_y only) from that step on; 1600 s later the attitude is inside the paper's fine band
    (q4 within 1 ± 0.01) on all axes, and the bag is the batch engine's run."""
    from adcs_controllers.nodes.zero_momentum_controller import ZeroMomentumController
    from adcs_sim.app.analysis.metrics import RunData
    from adcs_sim.app.batch.engine import BatchSimulation
    from adcs_sim.app.scenario.files import validate_scenario
    from adcs_sim.bag.reader import read_messages

    n = 1620
    scenario = reconfiguring_scenario(tmp_path, 'uosat12_zero_momentum.yaml', 'zero_momentum_controller', n)
    dyn, ctrl = run_fault_graph(scenario, ZeroMomentumController, n)
    assert dyn.missed_steps == 0 and dyn.faults.late == 0 and ctrl.faults.late == 0
    assert dyn.rejects.total == 0 and ctrl.rejects.total == 0
    assert ctrl.law.phase == 'two_wheel' and ctrl.law.two_wheel.unactuated_axis == 'z'

    bag = tmp_path / 'bag'
    run = RunData.from_bag(bag)
    status = {t: values for t, _, values in run.controller_status}
    # the switch happens at the fault's step
    assert status[T_FAULT - 1]['phase'] == 'three_wheel' and status[T_FAULT - 1]['mode'] == 'pd'
    assert status[T_FAULT]['phase'] == 'two_wheel' and status[T_FAULT]['mode'] == 'zero_momentum'
    assert status[T_FAULT]['available_wheels'] == 'rw_x,rw_y'
    # torque commands to all three wheels before, speed commands to rw_x and rw_y from the fault on
    cmds = {t / 1e9: msg for _, t, msg in read_messages(bag, {'/wheels/cmd'})}
    assert list(cmds[T_FAULT - 1].name) == ['rw_x', 'rw_y', 'rw_z'] and len(cmds[T_FAULT - 1].effort) == 3
    assert all(list(m.name) == ['rw_x', 'rw_y'] and len(m.velocity) == 2 and not len(m.effort)
               for t, m in cmds.items() if t >= T_FAULT)
    # the failed wheel: no torque from the fault's step on (its motor and the body's z axis)
    z = run.wheel_names.index('rw_z')
    assert np.all(run.wheel_torque[run.t_wheels >= T_FAULT, z] == 0.0)
    assert np.all(run.u[run.t_u >= T_FAULT, 2] == 0.0)
    # inside the paper's fine band (q4 within 1 ± 0.01, all three axes), the unactuated q3 still
    # shrinking (it is the slow one: |q3| 0.224 at the fault), within the torque limit. Shrinking is
    # asserted as an ordering (was < 0.6 x its value at the fault, a margin with no reason; ours 0.50 x)
    qe = run.q * np.sign(run.q[:, 3:4])
    assert 1.0 - qe[-1, 3] < 0.01
    k = int(np.flatnonzero(run.t == T_FAULT)[0])
    assert abs(qe[-1, 2]) < abs(qe[k, 2])
    assert np.abs(run.u).max() <= 0.02 + 1e-12
    # the batch engine (same plant, law, allocation, fault schedule) gives the same run
    batch = BatchSimulation.from_runs([validate_scenario(scenario)]).run().run_data(0)
    assert_array_equal(batch.q, run.q)
    assert_array_equal(batch.u, run.u)


def test_two_wheel_law_from_the_start(ros_domain, tmp_path):
    """The plain case: three_wheel.enabled false, the GSMN law runs from t = 0 on rw_x, rw_y with
    rw_z failed at t = 0: the phase is two_wheel throughout, z gets no torque, V decreases (asserted as an
    ordering; was below half of V(0), a margin with no reason)."""
    from adcs_controllers.nodes.snlc_gsmn_controller import SnlcGsmnController
    from adcs_sim.app.analysis.metrics import RunData

    n = 200
    scenario = reconfiguring_scenario(tmp_path, 'uosat12_gsmn.yaml', 'snlc_gsmn_controller', n,
                                      fault_time=0.0, extra={'three_wheel.enabled': False})
    dyn, ctrl = run_fault_graph(scenario, SnlcGsmnController, n)
    assert dyn.missed_steps == 0
    run = RunData.from_bag(tmp_path / 'bag')
    phases = {values['phase'] for _, _, values in run.controller_status}
    assert phases == {'two_wheel'}
    modes = {values['mode'] for _, _, values in run.controller_status}
    assert modes <= {'low_gain', 'high_gain', 'zero_torque'} and 'low_gain' in modes
    assert np.all(run.u[:, 2] == 0.0)
    V = np.array([float(values['V']) for _, _, values in run.controller_status])
    assert V[-1] < V[0]


# --- parameters --------------------------------------------------------------------------------

@pytest.mark.parametrize('base, section, overrides, key, text', [
    ('uosat12_gsmn.yaml', 'snlc_gsmn_controller', {'three_wheel.kp': 0.0}, 'three_wheel.kp', 'must be > 0'),
    ('uosat12_gsmn.yaml', 'snlc_gsmn_controller', {'unactuated_axis': 'w'}, 'unactuated_axis', 'w'),
    ('uosat12_gsmn.yaml', 'snlc_gsmn_controller', {'epsilon': -0.02}, 'epsilon', '> 0'),
    ('uosat12_gsmn.yaml', 'snlc_gsmn_controller', {'three_wheel.target.attitude': [0.2, 0.2, 0.2, 0.8246]},
     'three_wheel.target.attitude', 'unit norm'),
    ('uosat12_snlc.yaml', 'snlc_controller', {'K': float('nan')}, 'K', 'finite'),
    ('uosat12_zero_momentum.yaml', 'zero_momentum_controller', {'wheels.spin_inertia': [0.01, 0.01]},
     'wheels.spin_inertia', 'one value per wheel'),
    ('uosat12_zero_momentum.yaml', 'zero_momentum_controller', {'wheels.bias_speed': [1.0]},
     'wheels.bias_speed', 'one value per wheel'),
    ('uosat12_zero_momentum.yaml', 'zero_momentum_controller', {'actuator': 'torquers'},
     'actuator', 'wheel speeds'),
])
def test_bad_seed000_parameters_are_named(tmp_path, base, section, overrides, key, text):
    from adcs_sim.app.scenario.files import validate_scenario
    with pytest.raises(ParameterError, match=text) as err:
        validate_scenario(make_scenario(tmp_path, {section: overrides}, base=base))
    assert f'{section}.ros__parameters.{key}' in str(err.value)


def test_reconfiguration_follows_the_wheels():
    """The pure switch: three wheels -> PD; X, Y left -> two-wheel law about z; Y, Z left -> about x
    (UK-DMC's axes); one wheel left -> 'unsupported' (PD over what is left); all back -> PD."""
    from adcs_controllers.laws.reconfiguration import TwoWheelReconfiguration
    from adcs_controllers.laws.underactuated import SnlcLaw
    p = {'inertia': [40.45, 42.09, 42.36], 'k': 0.02, 'g': 0.08, 'K': 10.0, 'a1': 0.025, 'a2': 0.025,
         'target.attitude': [0, 0, 0, 1.0], 'target.rate': [0, 0, 0.0], 'three_wheel.enabled': True,
         'three_wheel.kp': 0.0032, 'three_wheel.kd': 0.08, 'three_wheel.target.attitude': Q_OFF}
    law = TwoWheelReconfiguration.factory(SnlcLaw)(p)
    axes = np.eye(3)
    assert law.phase == 'three_wheel'
    q = np.array([0.1, -0.2, 0.3, np.sqrt(1 - 0.14)])
    w = np.array([0.01, -0.02, 0.005])
    assert law.on_wheels(axes, [True, True, False]).startswith('phase three_wheel -> two_wheel')
    u, st = law.control(0.0, q, w)
    assert st['phase'] == 'two_wheel' and u[2] == 0.0
    assert 'unactuated axis is now x' in law.on_wheels(axes, [False, True, True])
    u_x, _ = law.control(0.0, q, w)
    assert u_x[0] == 0.0 and law.phase == 'two_wheel'
    # about x, the law is the z law in the rotated axes (y, z, x)
    ref, _ = SnlcLaw(dict(p, inertia=[42.09, 42.36, 40.45])).control(0.0, q[[1, 2, 0, 3]], w[[1, 2, 0]])
    assert_array_equal(u_x[[1, 2, 0]], ref)
    assert 'unsupported' in law.on_wheels(axes, [False, True, False])
    assert law.control(0.0, q, w)[1]['mode'] == 'pd'
    assert law.on_wheels(axes, [True, True, True]).startswith('phase unsupported -> three_wheel')
