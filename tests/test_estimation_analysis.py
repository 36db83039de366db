"""Estimation analysis (adcs_sim/app/analysis/estimation.py) and its figures (adcs_sim/app/report/estimation.py):
from a bag (the estimate, status and truth messages an estimator run records) and from a batch."""
from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from support.estimation_truth import StateSensors
from support.estimator_runs import SECTION, write_run_bag
from support.scenarios import make_scenario

from adcs_controllers.estimators import mekf
from adcs_sim.app.analysis import estimation
from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.scenario.registry import NODES
from adcs_sim.app.report import estimation as figures
from adcs_sim.app.scenario.files import validate_scenario

def test_series_from_a_bag_is_the_estimators_output(tmp_path):
    """(Figure: estimation_figure of this bag, docs/determination.md.) What the analysis reads back from the bag is what the estimator computed: attitude, rate and
    bias bit for bit, NIS bit for bit (repr), the attitude covariance to rounding (rotated to the
    inertial axes in the message and back); errors and the 3-dof NEES are the mekf module's."""
    out = write_run_bag(tmp_path / 'bag')
    s = estimation.series_from_bag(tmp_path / 'bag')
    q = np.array([e.q for e, *_ in out])
    assert_array_equal(s.t, np.arange(len(out), dtype=float))
    assert_array_equal(s.w, np.array([e.w for e, *_ in out]))
    assert_array_equal(s.bias, np.array([e.bias for e, *_ in out]))
    assert_allclose(s.q, q, rtol=0, atol=2e-16)
    P = np.array([e.cov[:3, :3] for e, *_ in out])
    scale = np.trace(P, axis1=1, axis2=2)[:, None, None]
    assert np.abs((s.att_cov - P) / scale).max() < 1e-14
    assert_array_equal(s.nis['star_tracker'], np.array([st['nis_star_tracker'] for _, st, *_ in out]))
    err = estimation.estimation_errors(s)
    q_true = np.array([qt for *_, qt, _ in out])
    assert_allclose(err['attitude'], mekf.attitude_error(q, q_true), rtol=0, atol=1e-15)
    value, dof = estimation.nees(s)
    direct = np.array([d @ np.linalg.solve(Pk, d) for d, Pk in zip(mekf.attitude_error(q, q_true), P)])
    assert dof == 3
    assert_allclose(value, direct, rtol=1e-7)
    metrics = estimation.estimation_metrics(s, settle_s=20.0)
    assert 0.0 < metrics['estimation_attitude_error_rms_deg'] < 0.02
    assert metrics['nis_star_tracker_inside_95'] > 0.85 and metrics['nees3_inside_95'] > 0.85
    fig = figures.estimation_figure(s, settle_s=20.0)
    assert len(fig.axes) == 4      # attitude, rate, NEES, NIS (no true bias in a bag)
    assert all(p.stat().st_size > 1000 for p in figures.save(fig, tmp_path / 'fig' / 'estimation'))


def test_a_bag_without_an_estimate_is_a_value_error(tmp_path):
    from adcs_sim.bag.writer import BagWriter
    bag = BagWriter(tmp_path / 'bag')
    bag.add_topic('/state', 'nav_msgs/msg/Odometry', [])
    bag.close()
    with pytest.raises(ValueError, match='estimate/state'):
        estimation.series_from_bag(tmp_path / 'bag')


def test_batch_consistency_of_a_still_spacecraft(tmp_path):
    """40 runs of a spacecraft at rest (the gyro's instantaneous sample is then exact over the step,
    so the filter's model is the truth's): the batch's run-averaged 6-dof NEES is inside the 95 %
    bounds of the mean of 40 on >= 90 % of the 120 steps (ours: 97.5 %; correlated steps: a
    consistent filter scatters around 95 %), its grand mean within 15 % of 6 (ours: 5.95), and the
    star tracker NIS likewise (ours: 95.8 %); the analysis' per-run errors are the mekf module's."""
    scenario = make_scenario(tmp_path, {'dynamics': {'duration': 120.0, 'initial.attitude': [0.0, 0.0, 0.0, 1.0],
                                                     'sensors.gyro.enabled': True, 'sensors.star_tracker.enabled': True},
                                        'mekf_estimator': {**SECTION, 'sensors': ['gyro', 'star_tracker']}},
                             drop=('pd_controller',))
    v = validate_scenario(scenario)
    runs = [{name: NODES[name].schema.validate(p) for name, p in v.items()} for _ in range(40)]
    sensors = StateSensors(range(100, 140), 1.0, 1e-5, 1e-7, 1e-4, [0.0, 0.0, 0.0])
    result = BatchSimulation.from_runs(runs, sensors).run()
    c = estimation.batch_consistency(result)
    assert c['nees_dof'] == 6 and c['nees_inside'] >= 0.9, c['nees_inside']
    assert abs(c['nees_grand_mean'] / 6 - 1) < 0.15, c['nees_grand_mean']
    assert c['nis_star_tracker_inside'] >= 0.9
    s = estimation.series_from_batch(result, 7)
    assert_array_equal(estimation.estimation_errors(s)['attitude'], mekf.attitude_error(s.q, s.q_true))
    fig = figures.estimation_figure(s)
    assert len(fig.axes) == 5      # attitude, rate, bias, NEES, NIS
    assert len(figures.consistency_figure(c, result.t, 40).axes) == 1


def test_the_run_analysis_of_a_bag_with_an_estimate_reads_the_state_not_the_estimate(tmp_path):
    """estimate/state has the layout of state: the run analysis (RunData) must still read state (or
    truth/state), never the estimate, whatever the order of the topics in the bag."""
    from rclpy.serialization import serialize_message

    from adcs_msgs_py import conversions as cv
    from adcs_sim.app.analysis.metrics import RunData
    from adcs_sim.bag.writer import BagWriter
    bag = BagWriter(tmp_path / 'bag')
    for name in ('/estimate/state', '/state'):
        bag.add_topic(name, 'nav_msgs/msg/Odometry', [])
    for k in range(5):
        bag.write('/estimate/state', serialize_message(cv.state_to_msg(k * 10 ** 9, np.array([0.0, 0.0, 0.6, 0.8]),
                                                                       np.ones(3))))
        bag.write('/state', serialize_message(cv.state_to_msg(k * 10 ** 9, np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3))))
    bag.close()
    run = RunData.from_bag(tmp_path / 'bag')
    assert_array_equal(run.q, np.tile([0.0, 0.0, 0.0, 1.0], (5, 1)))
    assert_array_equal(run.w, np.zeros((5, 3)))


@pytest.mark.parametrize('dof', [1, 2, 3, 6, 9, 300, 600])
@pytest.mark.parametrize('runs', [1, 7, 100])
def test_chi2_bounds_are_scipy_stats_chi2_ppf(dof, runs):
    """chi2_bounds (scipy.special.gammaincinv, which imports in a fraction of scipy.stats' time)
    against the reference scipy.stats.chi2.ppf of the mean of ``runs`` values: the same bits."""
    from scipy.stats import chi2
    a = (1.0 - estimation.CONFIDENCE) / 2.0
    expected = chi2.ppf([a, 1.0 - a], dof * runs) / runs
    assert estimation.chi2_bounds(dof, runs) == (float(expected[0]), float(expected[1]))
