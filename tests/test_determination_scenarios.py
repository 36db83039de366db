"""The attitude-determination scenarios of issue #20, end to end: sensors (truth model) -> estimator
(flight software) -> controller flying on the estimate -> actuators, through the graph (a committed
bag) and through the batch engine (the same code).

* config/microsat_gsmn_slew_mekf.yaml: seed 004's GSMN slew (III.F) on a star tracker + gyro MEKF
  estimate; its bag (bags/microsat_gsmn_slew_mekf, a lockstep graph run: dynamics, mekf_estimator,
  gsmn_controller, recorder) equals its batch run, truth and estimate alike;
* config/microsat_pd_slew_star_tracker_outage.yaml: a 100 s star tracker outage in the middle of the PD
  slew (recorded too);
* config/leo_tle_sun_magnetometer_mekf.yaml: sun sensor + magnetometer + gyro on a TLE orbit through an
  eclipse, the filter's references from its onboard Sun and IGRF models (batch engine).
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest
from support.comparison import assert_recorded_run_equal

from adcs_sim.app.analysis import estimation
from adcs_sim.app.analysis.metrics import RunData, run_metrics
from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.scenario.files import validate_scenario

ROOT = Path(__file__).resolve().parents[1]
BAGS, CONFIG = ROOT / 'bags', ROOT / 'config'


@lru_cache(maxsize=None)
def batch(scenario: Path):
    return BatchSimulation.from_runs([validate_scenario(scenario)]).run()


@lru_cache(maxsize=None)
def recorded(name: str) -> RunData:
    return RunData.from_bag(BAGS / name / 'bag')


def _degrees(errors: dict, key: str) -> np.ndarray:
    return np.degrees(np.linalg.norm(errors[key], axis=-1))


@pytest.mark.parametrize('name', [pytest.param('microsat_gsmn_slew_mekf', marks=pytest.mark.slow),
                                  'microsat_pd_slew_star_tracker_outage'])
def test_graph_recording_of_the_estimator_chain_equals_its_batch_run(name):
    """dynamics (sensors) -> mekf_estimator -> controller on estimate/state -> dynamics, in lockstep:
    the bag's truth, torques and every estimate (attitude, rate, attitude covariance) are the batch
    engine's, bit for bit on the CPU that recorded them (tests/support/comparison.py CROSS_CPU_RTOL elsewhere)."""
    result = batch(BAGS / name / 'scenario.yaml')
    graph = recorded(name)
    assert graph.missed_steps == 0
    run = result.run_data(0)
    assert_recorded_run_equal(run.q, graph.q)
    assert_recorded_run_equal(run.u, graph.u)
    bag = estimation.series_from_bag(BAGS / name / 'bag')
    ours = estimation.series_from_batch(result, 0)
    n = ours.t.size   # the batch's estimates of t_0 .. t_K-1; the graph's estimator also answers the last state
    assert bag.t.size in (n, n + 1) and np.array_equal(bag.t[:n], ours.t)
    assert_recorded_run_equal(ours.q, bag.q[:n])
    assert_recorded_run_equal(ours.w, bag.w[:n])
    # the bag's covariance went through the message (rotated to inertial axes and back): rounding only,
    # relative to each step's largest variance
    scale = np.abs(ours.att_cov).max(axis=(1, 2))[:, None, None]
    assert np.all(np.abs(ours.att_cov - bag.att_cov[:n]) <= 1e-12 * scale)


def test_gsmn_slew_on_the_mekf_estimate_settles_within_a_few_percent_of_the_slew_on_the_truth():
    """Issue #20: "settles within a few percent of the same slew on the truth". The same GSMN slew
    (III.F, 0.1 s period) on the truth (bags/microsat_gsmn_slew): 0.5 deg on all 2-1-3 axes at 119.8 s;
    on the MEKF estimate (star tracker 5/40 arcsec, gyro 0.1 deg/sqrt(h) with a 0.1 deg/s-class bias
    the filter starts without, 10 deg initial estimate error): 120.4 s (+0.5 %). Tolerance 3 %: the
    estimate's error (~0.005 deg after acquisition) is 1 % of the 0.5 deg band, so only the last approach
    to the band can move."""
    on_estimate = run_metrics(recorded('microsat_gsmn_slew_mekf'))
    on_truth = run_metrics(recorded('microsat_gsmn_slew'))
    key = 'settling_euler213_0.5deg_s'
    assert on_estimate[key] == pytest.approx(on_truth[key], rel=0.03)
    assert on_estimate['final_eigenaxis_error_deg'] < 0.05


def test_gsmn_on_the_estimate_spends_more_torque_than_on_the_truth_pinned():
    """Not a paper claim, a finding pinned: GSMN's derivative and projection terms pass the gyro's white
    noise (2.9e-5 rad/s^0.5 -> 9e-5 rad/s per 0.1 s sample) straight into the command, so the slew on
    the estimate integrates 0.299 N m s against 0.181 on the truth (+65 %) while settling as fast. The
    test pins that it costs more (a filter cannot remove white rate noise the law differentiates)."""
    on_estimate = run_metrics(recorded('microsat_gsmn_slew_mekf'))['integrated_torque_Nms']
    on_truth = run_metrics(recorded('microsat_gsmn_slew'))['integrated_torque_Nms']
    assert on_estimate > 1.3 * on_truth


@pytest.mark.slow
def test_mekf_of_the_gsmn_slew_converges_and_its_attitude_is_consistent():
    """From 10 deg off and without the 0.1 deg/s-class bias: after 60 s the attitude error stays below
    0.02 deg and inside the filter's 3 sigma (per axis) on >= 99 % of the steps, the bias error below
    0.002 deg/s (1 % of the bias). The gyro is rate-integrating and the filter propagates each step
    with the sample that covers it (the defaults), so the attitude part is consistent: its 3-dof NEES
    mean after 60 s is 2.98 (asserted within 20 % of 3: one run of 600 correlated steps). The 6-dof
    NEES mean is lower (3.7): the bias error of one run varies over hundreds of seconds, so its time
    average is one draw of a slowly varying error, here 0.7 of its 3 dof. Asserted: not overconfident
    (6-dof mean <= 1.25 x 6, at most 5 % of the steps above the single-run 95 % bound) and not
    uselessly loose (mean >= 0.4 x 6)."""
    s = estimation.series_from_batch(batch(CONFIG / 'microsat_gsmn_slew_mekf.yaml'), 0)
    e = estimation.estimation_errors(s)
    after = s.t >= 60.0
    assert _degrees(e, 'attitude')[after].max() < 0.02
    inside = (np.abs(e['attitude'][after]) <= 3 * e['sigma_attitude'][after]).mean()
    assert inside >= 0.99
    assert np.degrees(np.abs(e['bias'][-1])).max() < 0.002
    attitude_nees = estimation._quadratic(e['attitude'], s.cov[..., :3, :3])
    assert 0.8 * 3 <= np.nanmean(attitude_nees[after]) <= 1.2 * 3
    value, dof = estimation.nees(s)
    mean = np.nanmean(value[after])
    assert dof == 6 and 0.4 * 6 <= mean <= 1.25 * 6
    assert (value[after] > estimation.chi2_bounds(6)[1]).mean() <= 0.05


def test_star_tracker_outage_grows_the_error_as_the_gyro_model_predicts_then_recovers():
    """Outage over [60, 160) s: the filter propagates on the gyro alone, so its attitude sigma grows
    (0.005 -> 0.05 deg: angle random walk plus the bias uncertainty integrated along the slew) and the
    true error grows with it, staying inside 3 sigma; at the first update after recovery both fall back
    below the pre-outage level within 5 s. The closed form of that growth is tested on the filter alone
    (tests/test_estimator_families.py::test_mekf_steady_state_and_outage_covariance_follow_the_gyro_model)."""
    result = batch(CONFIG / 'microsat_pd_slew_star_tracker_outage.yaml')
    s = estimation.series_from_batch(result, 0)
    e = estimation.estimation_errors(s)
    sigma = np.degrees(np.linalg.norm(e['sigma_attitude'], axis=-1))
    error = _degrees(e, 'attitude')
    used = s.status['used_star_tracker']
    k = np.round(s.t).astype(int)
    assert not used[(k >= 60) & (k < 160)].any() and used[(k >= 1) & (k < 60)].all() and used[k >= 160].all()
    assert np.all(np.diff(sigma[(k >= 60) & (k < 160)]) > 0)      # grows at every step of the outage
    assert sigma[k == 159][0] > 5 * sigma[k == 59][0]
    outage = (k >= 60) & (k < 160)
    assert (np.abs(e['attitude'][outage]) <= 3 * e['sigma_attitude'][outage]).mean() >= 0.99
    assert sigma[k == 165][0] < sigma[k == 59][0] * 2 and error[k == 165][0] < 3 * sigma[k == 165][0]
    assert run_metrics(result.run_data(0))['settling_eigenaxis_0.5deg_s'] < 400.0   # the slew completes


def test_star_tracker_outage_with_the_default_gyro_propagation_is_nees_consistent():
    """The outage scenario sets no gyro.propagation: the defaults (rate-integrating gyro, ``increment``)
    keep the 6-dof NEES inside its single-run 95 % chi-square bounds on every step of the outage
    (ours: mean 7.7, 100 % of the 100 steps; the bounds 1.24-14.45) and its mean over the outage
    inside them. Before, with an instantaneous-rate gyro and ``hold``: mean ~510, no step inside."""
    assert 'propagation' not in (CONFIG / 'microsat_pd_slew_star_tracker_outage.yaml').read_text()
    s = estimation.series_from_batch(batch(CONFIG / 'microsat_pd_slew_star_tracker_outage.yaml'), 0)
    value, dof = estimation.nees(s)
    lo, hi = estimation.chi2_bounds(dof)
    k = np.round(s.t).astype(int)
    outage = value[(k >= 60) & (k < 160)]
    assert dof == 6 and outage.size == 100
    assert np.all((outage >= lo) & (outage <= hi))
    assert lo <= outage.mean() <= hi


@pytest.mark.slow
def test_sun_and_magnetometer_mekf_on_a_tle_orbit_through_an_eclipse():
    """LEO (SGP4 of the scenario's TLE), umbra from ~380 s to ~2400 s: the sun sensor is used only in
    sunlight, the magnetometer throughout. Consistency over the 3000 s: the 6-dof NEES mean within 15 %
    of 6 and inside its single-run 95 % bounds on >= 90 % of the steps (ours: 6.23, 94 %), each NIS
    likewise (2 dof); the attitude error inside 3 sigma on >= 99 % of the steps, below 0.1 deg after the
    first 100 s; in the umbra, the rotation about the field is unobservable: the attitude sigma grows
    (its largest in the umbra, over twice its value in the minute before the umbra)."""
    result = batch(CONFIG / 'leo_tle_sun_magnetometer_mekf.yaml')
    s = estimation.series_from_batch(result, 0)
    m = estimation.estimation_metrics(s)
    assert abs(m['nees6_mean'] / 6 - 1) < 0.15 and m['nees6_inside_95'] >= 0.9
    assert m['nis_sun_inside_95'] >= 0.9 and m['nis_magnetometer_inside_95'] >= 0.9
    e = estimation.estimation_errors(s)
    assert (np.abs(e['attitude']) <= 3 * e['sigma_attitude']).mean() >= 0.99
    assert _degrees(e, 'attitude')[s.t >= 100].max() < 0.1
    sun = s.status['used_sun'].astype(bool)
    dark = ~sun
    assert 0.3 < dark.mean() < 0.8 and sun[:300].all() and sun[-300:].all()   # lit, umbra, lit again
    assert s.status['used_magnetometer'].all()
    sigma = np.degrees(np.linalg.norm(e['sigma_attitude'], axis=-1))
    before = (s.t >= 300) & (s.t < 370)
    assert sun[before].all() and sigma[dark].max() > 2 * sigma[before].max()
