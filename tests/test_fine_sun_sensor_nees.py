"""An MEKF on gyro + fine sun sensor + magnetometer is consistent over 100 runs of the batch engine
(issue #32 item 3): the truth model's sensors (sensors.*) on a 500 km equatorial orbit in sunlight at
the March equinox, the filter's references from its own onboard Sun and IGRF models along the same
orbit, the spacecraft at rest (the gyro's sample is then the filter's model of the rate over the step).

Each run draws its sensor noise (sensors.seed), its gyro bias from the filter's bias prior, and the
filter's initial attitude error from its attitude prior, so the filter's initial covariance is the
truth's. Consistency bounds as tests/test_estimator_families.py and
tests/test_estimation_analysis.py (Bar-Shalom, Li & Kirubarajan, *Estimation with Applications to
Tracking and Navigation*, Wiley 2001, §5.4): the run-averaged 6-dof NEES at each step against the
two-sided 95 % bounds of the mean of 100 (adcs_sim.app.analysis.estimation.chi2_bounds), and each sensor's
2-dof NIS likewise (batch_consistency)."""
from __future__ import annotations

import copy

import numpy as np
import pytest
from support.estimation_truth import perturbed
from support.scenarios import make_scenario

from adcs_sim.app.analysis import estimation
from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.scenario.files import validate_scenario

pytestmark = pytest.mark.slow

RUNS = 100
ARW, RRW = 2.9e-5, 1e-8          # rad/s^0.5, rad/s^1.5
SIGMA_SUN = 2e-4                 # rad, each measured angle
SIGMA_FIELD = 1e-7               # T
SIGMA_ATT0, SIGMA_BIAS0 = 0.01, 1e-4   # rad, rad/s: the filter's priors, and the truth's dispersion
ENVIRONMENT = {'environment.enabled': True, 'environment.epoch': '2026-03-20T12:00:00Z',
               'environment.circular.altitude': 500e3, 'environment.circular.arg_latitude_deg': -60.0}


def _runs(tmp_path, steps: int, filter_sigma_sun: float = SIGMA_SUN) -> list[dict]:
    """The 100 runs' validated sections: the Sun at about 20 deg off the sensor's boresight."""
    scenario = make_scenario(tmp_path, {
        'dynamics': {'duration': float(steps), 'control_period': 1.0, 'integrator.max_step': 1.0,
                     'lockstep.commands': ['none'], 'initial.attitude': [0.0, 0.0, 0.0, 1.0],
                     'initial.rate': [0.0, 0.0, 0.0], **ENVIRONMENT,
                     'sensors.gyro.enabled': True, 'sensors.gyro.arw': ARW, 'sensors.gyro.rrw': RRW,
                     'sensors.fine_sun_sensor.enabled': True, 'sensors.fine_sun_sensor.std': SIGMA_SUN,
                     'sensors.fine_sun_sensor.boresight': [1.0, 0.3, -0.2],
                     'sensors.fine_sun_sensor.fov_deg': 60.0,
                     'sensors.magnetometer.enabled': True, 'sensors.magnetometer.std': SIGMA_FIELD},
        'mekf_estimator': {'sensors': ['gyro', 'fine_sun_sensor', 'magnetometer'],
                           'gyro.sigma_v': ARW, 'gyro.sigma_u': RRW,
                           'fine_sun_sensor.sigma': filter_sigma_sun, 'magnetometer.sigma': SIGMA_FIELD,
                           'references.model': 'environment', 'environment.epoch': ENVIRONMENT['environment.epoch'],
                           'environment.circular.altitude': 500e3, 'environment.circular.arg_latitude_deg': -60.0,
                           'initial.attitude_sigma': [SIGMA_ATT0] * 3, 'initial.bias_sigma': [SIGMA_BIAS0] * 3}},
        drop=('pd_controller',))
    base = validate_scenario(scenario)
    rng = np.random.default_rng(2032)
    runs = []
    for i in range(RUNS):
        v = copy.deepcopy(base)
        v['dynamics']['sensors.seed'] = 100 + i
        v['dynamics']['sensors.gyro.bias'] = list(SIGMA_BIAS0 * rng.normal(size=3))
        q0 = perturbed(np.array([[0.0, 0.0, 0.0, 1.0]]), SIGMA_ATT0 * rng.normal(size=(1, 3)))[0]
        v['mekf_estimator']['initial.attitude'] = list(q0)
        runs.append(v)
    return runs


def test_mekf_on_gyro_fine_sun_sensor_and_magnetometer_is_consistent_over_100_runs(tmp_path):
    """300 s, 100 runs (seeds chosen before looking). Ours: the 6-dof NEES grand mean 5.97 (within 10 %
    of 6, the existing tests' band; a consistent filter's scatters by ~4 % over seeds), the run-averaged
    NEES inside its 95 % bounds on 84 % of the steps: the errors are correlated over hundreds of steps
    (the bias), so that fraction scatters with the realisation (0.98, 0.97, 1.00 with three other seeds
    tried afterwards, not used): the test asks >= 80 %. The magnetometer's NIS inside on >= 90 % of the
    steps (ours 97 %). The fine sun sensor's NIS grand mean is below 2, as its model says it must be
    (tests/test_fine_sun_sensor.py): with the Sun θ = 19.8 deg off the boresight one of its two angles
    moves the vector by σ cos θ, not σ, so the filter's σ² is conservative across that axis and the
    expected NIS lies between 1 + cos² θ = 1.885 and 2 (ours 1.881, 0.05 of slack). Every run used the
    fine sun sensor at every step (in view, sunlit)."""
    result = BatchSimulation.from_runs(_runs(tmp_path, 300)).run()
    c = estimation.batch_consistency(result)
    assert c['nees_dof'] == 6
    assert abs(c['nees_grand_mean'] / 6.0 - 1.0) < 0.1, c['nees_grand_mean']
    assert c['nees_inside'] >= 0.8, c['nees_inside']
    assert c['nis_magnetometer_inside'] >= 0.9, c
    series = [estimation.series_from_batch(result, i) for i in range(result.n_runs)]
    nis = np.array([s.nis['fine_sun_sensor'] for s in series])
    theta = np.arccos(1.0 / np.linalg.norm([1.0, 0.3, -0.2]))   # the Sun near inertial +x at the equinox
    assert 1.0 + np.cos(theta) ** 2 - 0.05 <= np.nanmean(nis) < 2.0, np.nanmean(nis)
    assert all(s.status['used_fine_sun_sensor'].astype(bool).all() for s in series)


def test_the_same_nees_check_catches_a_filter_that_trusts_the_sun_sensor_too_much(tmp_path):
    """The same runs (100 s) with the filter's fine_sun_sensor.sigma a third of the truth's: the NEES
    grand mean leaves the 10 % band upwards and most steps are above the bounds (the test can fail)."""
    result = BatchSimulation.from_runs(_runs(tmp_path, 100, SIGMA_SUN / 3)).run()
    c = estimation.batch_consistency(result)
    assert c['nees_grand_mean'] > 6.6 and c['nees_inside'] < 0.5, (c['nees_grand_mean'], c['nees_inside'])
