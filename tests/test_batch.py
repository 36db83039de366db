"""The batch engine (adcs_sim/app/batch/engine.py): the graph's plant, sensor, law and actuation code with a
leading batch axis.

* one run of the batch equals the same run through the ROS graph (recorded bag) to round-off;
* a run's numbers do not depend on the batch it shares (bit for bit);
* runs that end early or diverge are masked and do not disturb the others;
* the batched plant conserves momentum per run with per-run inertias.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from support.ros_graph import record_pd_loop
from support.scenarios import batch_of, make_scenario

from adcs_msgs_py.params import ParameterError
from adcs_sim.app.analysis.metrics import RunData, run_metrics
from adcs_sim.app.scenario.registry import NODES
from adcs_sim.app.scenario.files import validate_scenario

NOISE = {'noise.seed': 7, 'noise.attitude_std': 1e-4, 'noise.rate_std': 1e-6}
# Q0 of the paper's slew and two other attitudes to share its batch.
Q_OTHERS = [[0.1, -0.2, 0.05, math.sqrt(1 - 0.0525)], [-0.3, 0.1, 0.2, math.sqrt(1 - 0.14)]]


def test_batch_run_matches_the_graph_run(ros_domain, tmp_path):
    """The PD slew with star-tracker and gyro noise, through the graph (dynamics + PD controller
    + recorder in lockstep) and as run 1 of a batch of 3: same truth trajectory, same applied
    torque, same wheel speeds, same metrics — to round-off (the controller renormalises the
    received quaternion, the only operation the batch does not repeat)."""
    n = 400
    bag_dir, dyn = record_pd_loop(tmp_path, n, NOISE, {'/truth/state': n + 1, '/actuators/torque': n,
                                                       '/wheels/state': n + 1})
    assert dyn.missed_steps == 0
    scenario = make_scenario(tmp_path, {'dynamics': {'duration': float(n), **NOISE}})
    graph_run = RunData.from_bag(bag_dir)

    overrides = [{'dynamics': {'initial.attitude': Q_OTHERS[0]}}, {},
                 {'dynamics': {'initial.attitude': Q_OTHERS[1], 'noise.seed': 8}}]
    result = batch_of(scenario, overrides).run()
    run = result.run_data(1)
    assert_array_equal(run.t, graph_run.t)
    assert_array_equal(run.t_u, graph_run.t_u)
    assert_allclose(run.q, graph_run.q, rtol=0, atol=1e-13)
    assert_allclose(run.w, graph_run.w, rtol=0, atol=1e-15)
    assert_allclose(run.u, graph_run.u, rtol=0, atol=1e-16)
    assert_allclose(run.wheel_speed, graph_run.wheel_speed, rtol=0, atol=1e-11)
    # the noise really entered the loop: a noise-free batch differs by far more than the tolerance
    assert np.abs(batch_of(scenario, [{'dynamics': {'noise.attitude_std': 0.0, 'noise.rate_std': 0.0}}])
                  .run().u[0] - run.u).max() > 1e-7
    ours, theirs = run_metrics(run), run_metrics(graph_run)
    for key in ('settling_euler213_0.5deg_s', 'settling_eigenaxis_0.5deg_s', 'integrated_torque_Nms'):
        assert ours[key] == pytest.approx(theirs[key], rel=1e-12, abs=1e-12)


def test_a_run_does_not_depend_on_its_batch(tmp_path):
    """Run k alone and inside batches of other sizes and other runs: identical bits."""
    scenario = make_scenario(tmp_path, {'dynamics': {'duration': 120.0, **NOISE}})
    runs = [{'dynamics': {'initial.attitude': Q_OTHERS[i % 2], 'inertia': [12.0 + i, 14.0, 10.0 + 0.5 * i],
                          'noise.seed': i},
             'pd_controller': {'kp': 0.002 * (1 + 0.1 * i), 'wheels.max_torque': [0.01, 0.01 + 0.001 * i, 0.01]}}
            for i in range(7)]
    whole = batch_of(scenario, runs).run()
    for k in (0, 3, 6):
        alone = batch_of(scenario, [runs[k]]).run()
        for name in ('q', 'w', 'u', 'wheel_speed'):
            assert_array_equal(getattr(alone, name)[0], getattr(whole, name)[k], err_msg=name)
    pair = batch_of(scenario, [runs[5], runs[2]]).run()
    assert_array_equal(pair.q[1], whole.q[2])


def test_runs_that_end_early_or_diverge_are_masked(tmp_path):
    """Torquers with unlimited torque and kd * period > 2: the discrete rate loop is unstable and
    overflows. The diverging run is recorded as failed at the step it went non-finite; a shorter
    run stops at its own duration; the others are exactly what they are alone."""
    scenario = make_scenario(tmp_path, {
        'dynamics': {'duration': 400.0, 'torquers.enabled': True, 'wheels.names': None, 'wheels.axes': None,
                     'wheels.spin_inertia': None, 'wheels.max_torque': None, 'wheels.max_speed': None},
        'pd_controller': {'actuator': 'torquers', 'wheels.names': None, 'wheels.axes': None,
                          'wheels.max_torque': None}})
    runs = [{}, {'pd_controller': {'kd': 40.0}}, {'dynamics': {'duration': 150.0}}]
    result = batch_of(scenario, runs).run()
    assert result.failure[0] is None and result.failure[2] is None
    assert result.failure[1] is not None and 'non-finite' in result.failure[1]
    k_fail = int(result.n_steps[1])
    assert 0 < k_fail < 400
    assert np.all(np.isfinite(result.q[1, :k_fail]))       # recorded up to the divergence...
    assert np.all(np.isnan(result.q[1, k_fail + 1:]))      # ...and nothing after it
    assert result.n_steps[2] == 150 and np.all(np.isnan(result.q[2, 151:]))
    assert result.n_steps[0] == 400
    assert_array_equal(result.q[0], batch_of(scenario, [runs[0]]).run().q[0])
    assert_array_equal(result.q[2, :151], batch_of(scenario, [runs[2]]).run().q[0])
    with np.errstate(all='ignore'):  # its torque overflowed: the metrics say so (inf), no warning
        failed = result.metrics(1)
    assert failed['settling_euler213_0.5deg_s'] == math.inf


def test_batched_plant_conserves_each_runs_momentum(tmp_path):
    """Free flight of 3 spacecraft with different inertias and spinning wheels in one batch: each
    run's inertial angular momentum is conserved, and equals the solo run's bit for bit."""
    from adcs_sim.truth.schema import build_plant, initial_state
    given = validate_scenario(make_scenario(tmp_path))['dynamics']
    inertias = np.array([[12.0, 14.0, 10.0], [20.0, 15.0, 10.0], [5.0, 6.0, 7.0]])
    speeds = np.array([[50.0, -30.0, 10.0], [0.0, 100.0, 0.0], [-20.0, 20.0, 40.0]])
    v = {**given, 'inertia': inertias, 'wheels.initial_speed': speeds,
         'initial.rate': np.array([[0.01, -0.02, 0.03]] * 3)}
    plant = build_plant(v)
    x = initial_state(plant, v)
    assert x.shape == (3, plant.n_states)
    H0 = plant.inertial_momentum(x)
    cmds = plant.zero_commands()
    xs = x
    for k in range(200):
        xs = plant.step(k * 1.0, xs, cmds, 1.0, 0.1)
    assert_allclose(plant.inertial_momentum(xs), H0, rtol=0, atol=1e-9)
    for i in range(3):
        solo_v = {**given, 'inertia': inertias[i].tolist(), 'wheels.initial_speed': speeds[i].tolist(),
                  'initial.rate': [0.01, -0.02, 0.03]}
        solo = build_plant(solo_v)
        xi = initial_state(solo, solo_v)
        for k in range(200):
            xi = solo.step(k * 1.0, xi, solo.zero_commands(), 1.0, 0.1)
        assert_array_equal(xi, xs[i])


def test_stack_refuses_to_vary_a_parameter_the_engine_cannot(tmp_path):
    nominal = validate_scenario(make_scenario(tmp_path))['dynamics']
    other = {**nominal, 'control_period': 0.5}
    with pytest.raises(ParameterError, match='control_period.*differs between the runs'):
        NODES['dynamics'].schema.stack([nominal, other])
    stacked = NODES['dynamics'].schema.stack([nominal, {**nominal, 'inertia': [13.0, 14.0, 10.0]}])
    assert stacked['inertia'].shape == (2, 3) and stacked['control_period'] == 1.0
