"""Scenarios with an estimator: a controller flies on the estimate by one setting (``feedback:
estimate``), the runner's start-up handshake counts the right subscribers, and sections that cannot
work together are refused before anything starts, naming the key."""
from __future__ import annotations

import pytest
from support.scenarios import make_scenario

from adcs_msgs_py.params import ParameterError
from adcs_sim.app.graph.runner import allowed_publishers, startup_counts
from adcs_sim.app.scenario.files import validate_scenario

MEKF = {'sensors': ['gyro', 'star_tracker']}
FITTED = {'sensors.gyro.enabled': True, 'sensors.star_tracker.enabled': True}   # in the dynamics section


def test_startup_counts_follow_the_feedback(tmp_path):
    plain = validate_scenario(make_scenario(tmp_path))
    assert startup_counts(plain) == {'state': 2, 'estimate': 0, 'sensors': 0}
    on_truth = validate_scenario(make_scenario(tmp_path, {'mekf_estimator': MEKF, 'dynamics': FITTED}))
    assert startup_counts(on_truth) == {'state': 2, 'estimate': 0, 'sensors': 2}
    on_estimate = validate_scenario(make_scenario(tmp_path, {'mekf_estimator': MEKF, 'dynamics': FITTED,
                                                             'pd_controller': {'feedback': 'estimate'}}))
    # the controller no longer subscribes to state (only the recorder does); the estimator waits for it
    assert startup_counts(on_estimate) == {'state': 1, 'estimate': 1, 'sensors': 2}
    allowed = dict(entry.split('=') for entry in allowed_publishers(on_estimate))
    assert allowed['estimate/state'] == 'mekf_estimator' and allowed['sensors/imu'] == 'dynamics'


def test_flying_on_the_estimate_needs_an_estimator(tmp_path):
    with pytest.raises(ParameterError, match=r"'pd_controller.ros__parameters.feedback'.*estimator section"):
        validate_scenario(make_scenario(tmp_path, {'pd_controller': {'feedback': 'estimate'}}))
    with pytest.raises(ParameterError, match='feedback'):
        validate_scenario(make_scenario(tmp_path, {'pd_controller': {'feedback': 'truth'}}))


def test_one_estimator_only(tmp_path):
    with pytest.raises(ParameterError, match='more than one estimator'):
        validate_scenario(make_scenario(tmp_path, {'mekf_estimator': MEKF, 'quest_estimator': {}}))


def test_an_estimator_using_a_sensor_the_dynamics_does_not_fit_is_refused(tmp_path):
    """It would wait for that sensor's messages at every step (a missed step each time)."""
    with pytest.raises(ParameterError, match=r"mekf_estimator.*sensors.*\['star_tracker'\].*does not fit"):
        validate_scenario(make_scenario(tmp_path, {'mekf_estimator': MEKF,
                                                   'dynamics': {'sensors.gyro.enabled': True}}))
