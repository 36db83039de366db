"""Seed 003 (single-axis pointing, two wheels, non-zero momentum) on the ROS graph.

* dynamics + fault injector + pointing controller A or B + recorder in lockstep, in this process,
  a short horizon of config/pointing_controller_{a,b}.yaml: the controller answers every step
  (it pairs ``state`` and ``wheels/state`` by stamp), and the recorded run equals the batch
  engine's run of the same scenario bit for bit;
* the controller's status carries the stage, the angle errors and the pointing error;
* an infeasible pointing request (eq. 14) is refused at start, naming the key and the numbers;
* a wheel state that lacks one of the controller's wheels is rejected and counted, not a crash.
"""
from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_array_equal
from support.ros_graph import run_fault_graph
from support.scenarios import make_scenario

from adcs_msgs_py.params import ParameterError
from adcs_sim.app.analysis.metrics import RunData
from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.scenario.registry import NODES
from adcs_sim.app.scenario.files import validate_scenario

N_STEPS = 60


def _scenario(tmp_path, which: str, extra: dict | None = None):
    section = f'pointing_{which}_controller'
    expect = {'startup.expect_recorder': True, 'startup.expect_faults': True}  # as adcs-run sets them
    return make_scenario(tmp_path, {
        'dynamics': {'duration': float(N_STEPS), **expect},
        section: {**expect, **(extra or {})},
        'fault_injector': {'startup.expect_recorder': True},
        'recorder': {'output': str(tmp_path / 'bag')}}, base=f'pointing_controller_{which}.yaml')


@pytest.mark.parametrize('which', ['a', 'b'])
def test_pointing_controller_graph_equals_batch(ros_domain, tmp_path, which):
    from adcs_controllers.nodes.pointing_a_controller import PointingAController
    from adcs_controllers.nodes.pointing_b_controller import PointingBController
    scenario = _scenario(tmp_path, which)
    node_class = PointingAController if which == 'a' else PointingBController
    dyn, ctrl = run_fault_graph(scenario, node_class, N_STEPS)
    assert dyn.missed_steps == 0 and dyn.stale_commands == 0 and dyn.rejects.total == 0
    assert ctrl.rejects.total == 0
    graph = RunData.from_bag(tmp_path / 'bag')

    batch = BatchSimulation.from_runs([validate_scenario(scenario)]).run().run_data(0)
    assert_array_equal(graph.t, batch.t)
    assert_array_equal(graph.q, batch.q)
    assert_array_equal(graph.w, batch.w)
    assert_array_equal(graph.u, batch.u)
    assert_array_equal(graph.wheel_speed, batch.wheel_speed)
    # the failed (stuck) Z wheel never turns; the body torque about e3 is zero (u3 = 0)
    assert np.all(graph.wheel_speed[:, 2] == 0.0) and np.all(graph.u[:, 2] == 0.0)

    statuses = [values for _, _, values in graph.controller_status]
    assert len(statuses) == N_STEPS + 1
    keys = {'mode', 'stage', 'e_psi', 'e_theta', 'e_phi', 'pointing_error'}
    assert keys <= set(statuses[0])
    assert {s['mode'] for s in statuses} <= ({'A1_momentum', 'A2_lqr'} if which == 'a' else {'B'})
    assert statuses[0]['available_wheels'] == 'rw_x,rw_y'


@pytest.mark.parametrize('which', ['a', 'b'])
def test_infeasible_pointing_is_refused_with_the_numbers(tmp_path, which):
    # tau 60 deg above the plane normal to H, sigma 35 deg above the wheels' plane: 60 > 90 - 35
    lam, alpha = np.radians(35.0), np.radians(60.0)
    scenario = make_scenario(tmp_path, {f'pointing_{which}_controller': {
        'sigma': [float(np.cos(lam)), 0.0, float(np.sin(lam))],
        'tau': [float(np.cos(alpha)), 0.0, float(np.sin(alpha))]}}, base=f'pointing_controller_{which}.yaml')
    with pytest.raises(ParameterError) as info:
        validate_scenario(scenario)
    text = str(info.value)
    assert '.tau' in text and 'eq. (14)' in text and '60 deg' in text and '55 deg' in text


def test_pointing_needs_the_wheels_spin_inertia(tmp_path):
    scenario = make_scenario(tmp_path, {'pointing_b_controller': {'wheels.spin_inertia': [0.0077]}},
                             base='pointing_controller_b.yaml')
    with pytest.raises(ParameterError, match='wheels.spin_inertia'):
        validate_scenario(scenario)


def test_wheel_state_without_the_controllers_wheels_is_rejected(ros_domain, tmp_path):
    """Bad wheel states are counted and dropped; the pending buffers stay small."""
    from support.ros_graph import InProcessGraph

    from adcs_controllers.nodes.pointing_b_controller import PointingBController
    from adcs_msgs_py import conversions as cv
    scenario = _scenario(tmp_path, 'b')
    with InProcessGraph(scenario) as graph:
        ctrl = graph.add(PointingBController)
        bad = cv.wheel_state_to_msg(0, ['rw_x'], [0.0], [1.0], [0.0])
        ctrl._on_wheel_state(bad)
        nan = cv.wheel_state_to_msg(0, ['rw_x', 'rw_y', 'rw_z'], [0.0] * 3, [float('nan'), 0.0, 0.0], [0.0] * 3)
        ctrl._on_wheel_state(nan)
        assert ctrl.rejects.total == 2
        for k in range(20):   # wheel states whose state never comes: the buffer keeps only a few
            ctrl._on_wheel_state(cv.wheel_state_to_msg(k * 10**9, ['rw_x', 'rw_y', 'rw_z'], [0.0] * 3,
                                                       [0.0] * 3, [0.0] * 3))
        assert len(ctrl.pairs.sides[1]) <= ctrl.pairs.keep


def test_registry_builds_the_pointing_laws_from_the_sections():
    secs = validate_scenario(make_scenario.__globals__['CONFIG'] / 'pointing_controller_a.yaml')
    law = NODES['pointing_a_controller'].law(secs['pointing_a_controller'])
    assert law.needs_wheel_momentum and np.allclose(law.H, [0.0, 0.0, 0.85])


def test_initial_momentum_sets_the_body_rate(tmp_path):
    """initial.momentum: H in inertial axes, wheels at their initial speed, the body carries the
    rest (J w0 = R(q0)^T H - sum a_i Js_i Omega0_i): the plant's inertial momentum is H."""
    from adcs_sim.truth.schema import build_plant, initial_state
    secs = validate_scenario(make_scenario(tmp_path, {'dynamics': {'wheels.initial_speed': [10.0, -5.0, 0.0]}},
                                           base='pointing_controller_b.yaml'))
    d = secs['dynamics']
    plant = build_plant(d)
    x0 = initial_state(plant, d)
    np.testing.assert_allclose(plant.inertial_momentum(x0), [0.0, 0.0, 0.85], rtol=0, atol=1e-15)
    np.testing.assert_array_equal(x0[7:10], [10.0, -5.0, 0.0])
    # the scenario as written: wheels at rest, all of H0 in the body
    d0 = validate_scenario(make_scenario(tmp_path, {}, base='pointing_controller_b.yaml'))['dynamics']
    x = initial_state(build_plant(d0), d0)
    assert np.all(x[7:10] == 0.0)
    assert np.linalg.norm(np.diag([10.0, 8.0, 9.0]) @ x[4:7]) == pytest.approx(0.85, rel=1e-14)


@pytest.mark.parametrize('overrides, key', [
    ({'initial.momentum': [0.0, 0.85]}, 'initial.momentum'),
    ({'initial.rate': [0.01, 0.0, 0.0]}, 'initial.rate'),
])
def test_bad_initial_momentum_is_named(tmp_path, overrides, key):
    scenario = make_scenario(tmp_path, {'dynamics': overrides}, base='pointing_controller_b.yaml')
    with pytest.raises(ParameterError, match=key.replace('.', r'\.')):
        validate_scenario(scenario)
