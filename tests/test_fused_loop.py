"""The batch engine's fused compiled loop (adcs_sim.app.batch.fused) gives the general path's rows bit for bit.

The fused loop runs the PD law, the wheels' minimum-norm allocation and saturation and the plant's
RK4 for every control step of every run in one compiled call; the general path
(:meth:`BatchSimulation.run` step by step, the numpy law and actuation objects) is the reference.
Dispersed gains, inertias, targets, limits and durations, both saturation modes, the shortest-path
flip, wheel friction and speed limits, a run that diverges; the law and actuation kernels alone
against their numpy functions on awkward values (NaN, inf, signed zeros); and when the fused path
must not be taken. No ROS.
"""
from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_array_equal
from support.scenarios import make_scenario

from adcs_controllers.laws import pd_kernel
from adcs_controllers.laws.allocation import saturate, wheel_allocation_matrix
from adcs_controllers.laws.pd import pd_torque
from adcs_core.attitude import matvec, quat_normalize
from adcs_sim.app.batch import fused
from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.scenario.registry import NODES
from adcs_sim.app.scenario.files import validate_scenario

SERIES = ('q', 'w', 'u', 'wheel_speed', 'n_steps')


def batch(scenario, runs: list[dict]) -> BatchSimulation:
    nominal = validate_scenario(scenario)
    return BatchSimulation.from_runs([{name: NODES[name].schema.validate({**params, **o.get(name, {})})
                                       for name, params in nominal.items()} for o in runs])


def both_paths(scenario, runs: list[dict], monkeypatch):
    """(fused result, general result) of the same batch; the fused path was taken."""
    sim = batch(scenario, runs)
    x0 = np.zeros((len(runs), sim.plant.n_states))
    assert fused.plan(sim, x0) is not None
    fast = sim.run()
    monkeypatch.setattr(fused, 'ENABLED', False)
    slow = batch(scenario, runs).run()
    monkeypatch.setattr(fused, 'ENABLED', True)
    return fast, slow


def assert_same(fast, slow):
    for name in SERIES:
        assert_array_equal(getattr(fast, name), getattr(slow, name), err_msg=name)
    assert fast.failure == slow.failure


def dispersed_runs(n: int) -> list[dict]:
    rng = np.random.default_rng(18)
    runs = []
    for i in range(n):
        q = rng.normal(size=4)
        q_ref = rng.normal(size=4) if i % 3 == 1 else np.array([0.0, 0.0, 0.0, 1.0])
        runs.append({'dynamics': {'initial.attitude': (q / np.linalg.norm(q)).tolist(),
                                  'initial.rate': rng.normal(0.0, 0.01, 3).tolist(),
                                  'inertia': (np.array([12.0, 14.0, 10.0]) + rng.normal(0, 0.6, 3)).tolist(),
                                  'wheels.max_torque': rng.uniform(0.009, 0.011, 3).tolist(),
                                  'duration': 200.0 if i % 4 == 3 else 300.0},
                     'pd_controller': {'kp': float(rng.uniform(0.0015, 0.004)), 'kd': float(rng.uniform(0.03, 0.08)),
                                       'target.attitude': (q_ref / np.linalg.norm(q_ref)).tolist(),
                                       'target.rate': rng.normal(0.0, 1e-3, 3).tolist() if i % 2 else [0.0] * 3,
                                       'wheels.max_torque': rng.uniform(0.008, 0.012, 3).tolist()}})
    return runs


@pytest.mark.parametrize('saturation,shortest', [('clip', False), ('scale', True)])
def test_fused_loop_equals_the_general_path(tmp_path, monkeypatch, saturation, shortest):
    """Nine dispersed PD slews (some shorter, some to another target, some tracking a rate) with
    wheel friction and a speed limit they reach: the same series and failures bit for bit."""
    scenario = make_scenario(tmp_path, {
        'dynamics': {'duration': 300.0, 'integrator.max_step': 0.25, 'wheels.viscous_friction': [1e-6, 2e-6, 0.0],
                     'wheels.coulomb_friction': [1e-5, 0.0, 2e-5], 'wheels.max_speed': [60.0, 628.3, 40.0]},
        'pd_controller': {'saturation': saturation, 'shortest_path': shortest}})
    fast, slow = both_paths(scenario, dispersed_runs(9), monkeypatch)
    assert_same(fast, slow)
    assert fast.n_steps.tolist() == [300, 300, 300, 200, 300, 300, 300, 200, 300]
    assert np.nanmax(np.abs(fast.wheel_speed)) > 40.0   # the speed limit acted
    assert np.isnan(fast.q[3, 201:]).all()


def test_a_diverging_run_stops_where_the_general_path_stops_it(tmp_path, monkeypatch):
    """Wheels without torque limits and kd * period > 2: the discrete rate loop is unstable and
    overflows; the fused loop stops that run at the same step with the same reason, the other run
    goes on, and a run's rows do not depend on its batch."""
    scenario = make_scenario(tmp_path, {
        'dynamics': {'duration': 400.0, 'wheels.max_torque': [1e308] * 3, 'wheels.max_speed': [1e308] * 3},
        'pd_controller': {'wheels.max_torque': [1e308] * 3}})
    runs = [{}, {'pd_controller': {'kd': 40.0}}]
    fast, slow = both_paths(scenario, runs, monkeypatch)
    assert_same(fast, slow)
    assert fast.failure[0] is None and 'non-finite' in fast.failure[1]
    assert 0 < fast.n_steps[1] < 400 and fast.n_steps[0] == 400
    alone = batch(scenario, runs[:1]).run()
    assert_array_equal(alone.q[0], fast.q[0])


def test_the_law_and_actuation_kernels_are_numpys_operations(monkeypatch):
    """pd_torque_row / wheel_command_row against pd_torque / Actuation's matvec + saturate, on
    batches of 1 and 500 (numpy's 3-term sums and its clip's NaN rule included), with NaN, inf and
    signed zeros among the inputs."""
    rng = np.random.default_rng(4)
    for n in (1, 500):
        q = rng.normal(size=(n, 4))
        q[::7] *= -1.0
        w = rng.normal(0, 0.05, (n, 3))
        q[3 % n, 2], w[5 % n, 1], q[9 % n, 3] = np.nan, np.inf, -0.0
        I = rng.normal(0, 1, (n, 3, 3)) + np.eye(3) * 12.0
        kp, kd = rng.uniform(0.001, 0.01, n), rng.uniform(0.01, 0.1, n)
        q_ref = quat_normalize(rng.normal(size=(n, 4)))
        w_ref = rng.normal(0, 1e-3, (n, 3))
        qm = np.empty(4)
        for shortest in (False, True):
            with np.errstate(all='ignore'):
                qn = quat_normalize(q)
                ref = pd_torque(qn, w, I, kp, kd, q_ref, w_ref, shortest)
            got = np.empty((n, 3))
            for r in range(n):
                pd_kernel.normalize_row(q[r], 0, qm)
                assert_array_equal(qm, qn[r])
                pd_kernel.pd_torque_row(qm, w[r], 0, I[r].reshape(9), kp[r], kd[r], q_ref[r], w_ref[r], shortest,
                                        got[r])
            assert_array_equal(got, ref)
        axes = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0], [0.577, 0.577, 0.577]])
        axes /= np.linalg.norm(axes, axis=1, keepdims=True)
        M = wheel_allocation_matrix(axes, np.array([True, True, False, True]))
        limit = rng.uniform(0.005, 0.02, (n, 4))
        u = rng.normal(0, 0.03, (n, 3))
        u[2 % n] = [np.nan, 0.0, 0.0]
        u[4 % n] = [-0.0, -0.0, -0.0]
        for mode, name in ((pd_kernel.CLIP, 'clip'), (pd_kernel.SCALE, 'scale')):
            with np.errstate(all='ignore'):
                ref = saturate(matvec(M, u), limit, name)
            got = np.empty((n, 4))
            for r in range(n):
                pd_kernel.wheel_command_row(u[r], M, limit[r], mode, got[r], 0)
            assert_array_equal(got, ref)
            assert (np.signbit(got) == np.signbit(ref)).all()


def test_the_general_path_runs_when_the_fused_loop_does_not_apply(tmp_path, monkeypatch):
    """Noise in the loop, an observer, or ADCS_FUSED_LOOP=0 semantics: no fused plan."""
    plain = batch(make_scenario(tmp_path, {'dynamics': {'duration': 20.0}}), [{}])
    noisy = batch(make_scenario(tmp_path, {'dynamics': {'duration': 20.0, 'noise.seed': 3,
                                                        'noise.attitude_std': 1e-4}}), [{}])
    x0 = np.zeros((1, plain.plant.n_states))
    assert fused.plan(plain, x0) is not None
    assert fused.plan(noisy, x0) is None
    assert fused.plan(plain, x0, observe=lambda k, t, s: None) is None
    monkeypatch.setattr(fused, 'ENABLED', False)
    assert fused.plan(plain, x0) is None
    seen = []
    monkeypatch.setattr(fused, 'ENABLED', True)
    plain.run(observe=lambda k, t, status: seen.append(k))
    assert seen == list(range(20))
