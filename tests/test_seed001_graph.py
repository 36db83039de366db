"""Seed 001 on the graph: dynamics with ideal torquers + the M2S / M2R controller nodes in lockstep.

The node-pair test of issue 7: the adaptive M2S compensator (VAG-C at 1 N m, disturbance
estimation, a constant disturbance in the plant: every part of Theorem 2 and section 7 at once)
runs against the dynamics node; the recorded run is the batch engine's run of the same scenario
bit for bit, and the status the node published is what the pure law computes from the states the
node received (the estimator states live in the law object and are integrated between messages).
Also: the parameter checks of both nodes, each naming its key.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_array_equal
from support.ros_graph import run_lockstep_graph
from support.scenarios import make_scenario

from adcs_msgs_py.params import ParameterError


def test_m2s_in_lockstep_is_the_batch_run_and_the_law(ros_domain, tmp_path):
    """150 steps (3 s at 0.02 s) of m2s_disturbance_vagc_1: the torques saturate at 1 N m from the
    first step, q of the VAG law grows, the disturbance estimate moves; bag == batch engine bit for
    bit; the published status (V, Ĵ, d̂, q) == the pure law replayed over the received states."""
    from adcs_controllers.laws.motion_to_spin import M2sLaw
    from adcs_controllers.nodes.m2s_controller import M2sController
    from adcs_core.attitude import quat_normalize
    from adcs_msgs_py import conversions as cv
    from adcs_sim.app.analysis.metrics import RunData
    from adcs_sim.app.batch.engine import BatchSimulation
    from adcs_sim.app.scenario.files import validate_scenario
    from adcs_sim.bag.reader import read_messages

    n = 150
    expect = {'startup.expect_recorder': True}
    scenario = make_scenario(tmp_path, {
        'dynamics': {'duration': n * 0.02, **expect}, 'm2s_controller': expect,
        'recorder': {'output': str(tmp_path / 'bag')}}, base='m2s_disturbance_vagc_1.yaml')
    dyn, ctrl = run_lockstep_graph(scenario, M2sController, {
        '/state': n + 1, '/controller/status': n + 1, '/torque_cmd': n + 1, '/dynamics/status': 2})
    assert dyn.missed_steps == 0 and dyn.rejects.total == 0 and ctrl.rejects.total == 0

    bag = tmp_path / 'bag'
    run = RunData.from_bag(bag)
    assert len(run.t) == n + 1
    assert np.abs(run.u).max() == 1.0  # saturated (cutoff) at the torquers' limit
    sections = validate_scenario(scenario)
    batch = BatchSimulation.from_runs([sections]).run().run_data(0)
    assert_array_equal(batch.q, run.q)
    assert_array_equal(batch.w, run.w)
    assert_array_equal(batch.u, run.u)

    # replay the pure law over the states the controller received: the same status, bit for bit
    law = M2sLaw(sections['m2s_controller'])
    states = [cv.state_from_msg(m) for _, _, m in read_messages(bag, {'/state'})]
    published = [values for _, _, values in run.controller_status]  # texts (repr of the floats), by step
    assert len(published) == len(states) == n + 1
    keys = ['V', 'theta', 'q_vag', 'J_hat_11', 'J_hat_22', 'J_hat_33', 'J_hat_23', 'J_hat_13', 'J_hat_12',
            'd_hat_x', 'd_hat_y', 'd_hat_z', 'u_cmd_x', 'u_cmd_y', 'u_cmd_z']
    for (t_ns, q, w), theirs in zip(states, published):
        _, status = law.control(t_ns / 1e9, quat_normalize(q), w)
        mine = law.published_status(status)
        assert {k: mine[k] for k in keys} == {k: float(theirs[k]) for k in keys}, t_ns
    first, last = published[0], published[-1]
    assert [float(first[f'J_hat_{ij}']) for ij in ('11', '22', '33', '23', '13', '12')] == [1, 1, 1, 0, 0, 0]
    assert float(first['q_vag']) == 1.0 and float(last['q_vag']) > 1.0  # VAG: q grows while saturated (eq. 56)
    assert float(last['d_hat_x']) != 0.0 and first['mode'] == 'saturated'


@pytest.mark.parametrize('base,section,overrides,key,text', [
    ('m2r_umax1.yaml', 'm2r_controller', {'alpha': 0.6}, 'alpha', r'eq\. \(20\).*> u_max = 1'),
    ('m2r_umax1.yaml', 'm2r_controller', {'B': [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0]}, 'B',
     'invertible'),
    ('m2r_umax1.yaml', 'm2r_controller', {'target.rate': [0.0, 0.1, 0.0]}, 'target.rate', 'rest'),
    ('m2r_umax1.yaml', 'm2r_controller', {'A': [1.0, 1.0, 3.0]}, 'A', 'distinct'),
    ('m2r_umax1.yaml', 'm2r_controller', {'proposition': 3}, 'proposition', '1 or 2'),
    ('m2r_umax1.yaml', 'm2r_controller', {'actuator': 'wheels'}, 'actuator', 'torquers'),
    ('m2s_intermediate_cutoff_10.yaml', 'm2s_controller', {'K_omega': 1.5}, 'K_omega', r'\(0, 1\)'),
    ('m2s_intermediate_cutoff_10.yaml', 'm2s_controller', {'saturation': 'cutoff'}, 'saturation',
     'one of'),
    ('m2s_intermediate_cutoff_10.yaml', 'm2s_controller', {'Q': [1.0, 1.0]}, 'Q', '0 or 6 or 36'),
    ('m2s_intermediate_cutoff_10.yaml', 'm2s_controller', {'beta': -1.0}, 'beta', '> 0'),
    ('m2s_intermediate_cutoff_10.yaml', 'm2s_controller', {'max_step': math.nan}, 'max_step', 'finite'),
])
def test_seed001_parameters_are_checked(tmp_path, base, section, overrides, key, text):
    """A non-physical or inconsistent seed 001 section stops at start with the key named; M2R's
    gains are checked against the torque bound of Proposition 1 for the torquers' limit."""
    from adcs_sim.app.scenario.files import validate_scenario
    with pytest.raises(ParameterError, match=text) as err:
        validate_scenario(make_scenario(tmp_path, {section: overrides}, base=base))
    assert f'{section}.ros__parameters.{key}' in str(err.value)


def test_m2s_section_with_empty_defaults_builds_the_paper_law():
    """The params file's empty lists mean the paper's defaults: K1 = D = I, Q = I6, B = I, no
    disturbance estimate; the torquers' scalar limit is the law's per-axis u_max."""
    from support.paths import CONFIG

    from adcs_controllers.families import M2S_SCHEMA
    from adcs_controllers.laws.motion_to_spin import M2sLaw
    from adcs_sim.app.scenario.files import validate_scenario
    section = validate_scenario(CONFIG / 'm2s_intermediate_cutoff_10.yaml')['m2s_controller']
    law = M2sLaw(section)
    assert_array_equal(law.K1, np.eye(3)) and law.B is None and law.C_d is None
    assert_array_equal(law.Q0, np.eye(6))
    assert law.u_max.tolist() == [10.0] and law.saturation == 1 and math.isclose(law.Kp, 1 / 6)
    stacked = M2S_SCHEMA.stack([section, dict(section, **{'torquers.max_torque': 1.0})])
    assert M2sLaw(stacked).u_max.tolist() == [[10.0], [1.0]]  # one limit per run of a batch
