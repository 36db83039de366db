"""The batch-axis metrics (adcs_sim/app/analysis/batch_metrics.py) equal run_metrics run by run, bit for bit.

* the vectorised settling / first-entry times equal analysis.settling_time / first_entry_time on
  the edge cases (always inside, last sample outside, a non-finite sample, never inside);
* batch_run_metrics of a batch with runs that end early, diverge, point an axis (seed 003) or
  have a fault schedule gives exactly ``[result.metrics(j) for j ...]`` (same keys, same order,
  same floats: compared by repr, so NaN and inf compare too).
"""
from __future__ import annotations

import math

import numpy as np
from support.scenarios import batch_of, make_scenario

from adcs_sim.app.analysis.metrics import first_entry_time, settling_time
from adcs_sim.app.analysis.batch_metrics import (
    batch_metric_columns,
    batch_run_metrics,
    first_entry_times,
    metric_columns,
    settling_times,
)

T = np.arange(6, dtype=float) * 0.5
ERRORS = np.array([
    [0.1, 0.2, 0.1, 0.0, 0.1, 0.2],        # always inside
    [3.0, 2.0, 1.5, 0.5, 0.2, 0.1],        # one crossing, interpolated
    [3.0, 0.5, 2.0, 0.5, 0.4, 2.0],        # last sample outside
    [np.nan, 3.0, np.inf, 0.1, 0.0, 0.0],  # non-finite before the last exit
    [5.0, 4.0, 3.0, 2.0, 2.0, 1.5],        # never inside
    [np.inf, 0.1, 2.0, 0.3, 0.2, 0.1],     # enters from inf
])


def test_vectorised_settling_and_first_entry_equal_the_scalar_ones():
    for tol in (1.0, 0.25, 2.0):
        assert repr(settling_times(T, ERRORS, tol).tolist()) == repr([settling_time(T, e, tol) for e in ERRORS])
        assert repr(first_entry_times(T, ERRORS, tol).tolist()) == repr(
            [first_entry_time(T, e, tol) for e in ERRORS])


def same_metrics(result, tol: float = 0.5) -> None:
    batch = batch_run_metrics(result, tol)
    loop = [result.metrics(j, tol) for j in range(result.n_runs)]
    assert repr(batch) == repr(loop)
    # a campaign's rows: the scalar columns straight from the batch arrays
    assert repr(batch_metric_columns(result, tol)) == repr([metric_columns(m) for m in loop])


def test_batch_metrics_equal_run_metrics_with_early_ends_and_divergence(tmp_path):
    """test_batch's masked batch (torquers, kd * period > 2 diverges) plus ordinary runs."""
    scenario = make_scenario(tmp_path, {
        'dynamics': {'duration': 200.0, 'torquers.enabled': True, 'wheels.names': None, 'wheels.axes': None,
                     'wheels.spin_inertia': None, 'wheels.max_torque': None, 'wheels.max_speed': None},
        'pd_controller': {'actuator': 'torquers', 'wheels.names': None, 'wheels.axes': None,
                          'wheels.max_torque': None}})
    runs = [{}, {'pd_controller': {'kd': 40.0}}, {'dynamics': {'duration': 150.0}}, {'pd_controller': {'kp': 0.004}},
            {'dynamics': {'initial.attitude': [0.3, -0.2, 0.1, math.sqrt(1 - 0.14)]}}]
    result = batch_of(scenario, runs).run()
    assert result.failure[1] is not None and result.n_steps[2] < result.n_steps[0]
    with np.errstate(all='ignore'):
        same_metrics(result)
        same_metrics(result, tol=2.0)
    wheels = make_scenario(tmp_path, {'dynamics': {'duration': 60.0}})
    same_metrics(batch_of(wheels, [{}, {'pd_controller': {'kp': 0.004}}]).run())


def test_batch_metrics_equal_run_metrics_for_pointing_and_faults(tmp_path):
    pointing = make_scenario(tmp_path, {'dynamics': {'duration': 40.0}}, base='pointing_controller_b.yaml')
    q = [[0.0, 0.0, 0.0, 1.0], [0.5, 0.5, -0.5, 0.5], [0.1, -0.7, 0.1, math.sqrt(1 - 0.51)]]
    same_metrics(batch_of(pointing, [{'dynamics': {'initial.attitude': v}} for v in q]).run(), tol=1.0)
    faulty = make_scenario(tmp_path, {'dynamics': {'duration': 520.0}}, base='uosat12_gsmn.yaml')  # rw_z fails at 500 s
    same_metrics(batch_of(faulty, [{}, {'dynamics': {'initial.attitude': q[2]}}]).run())


def test_the_compiled_error_quaternions_are_numpys():
    """error_quaternions (metrics_kernel's compiled kernel) against error_quaternion and the norm of
    its vector part (numpy) on (runs, samples) arrays: one target or one per run, random and
    awkward values (NaN, inf, signed zeros), the same bits."""
    from adcs_core.attitude import error_quaternion, quat_normalize
    from adcs_sim.app.analysis.metrics_kernel import error_quaternions
    rng = np.random.default_rng(11)
    q = rng.normal(size=(7, 301, 4)) * np.array([1.0, 1e-3, 1e3, 1.0])
    q[1, 5] = [np.nan, 0.0, 0.0, 1.0]
    q[2, 9] = [np.inf, 0.0, -0.0, 1.0]
    q[3, 4] = [-0.0, 0.0, -0.0, -1.0]
    for q_ref in (np.broadcast_to([0.0, 0.0, 0.0, 1.0], (7, 4)), quat_normalize(rng.normal(size=(7, 4)))):
        qe, vnorm = np.empty(q.shape), np.empty(q.shape[:2])
        error_quaternions(q, np.ascontiguousarray(q_ref), qe, vnorm)
        with np.errstate(all='ignore'):
            ref = error_quaternion(q, q_ref[:, None, :])
            ref_norm = np.linalg.norm(ref[..., :3], axis=-1)
        assert repr(qe.tolist()) == repr(ref.tolist())
        assert repr(vnorm.tolist()) == repr(ref_norm.tolist())
