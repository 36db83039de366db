"""The estimator node's sensor subscriptions fuzzed (as tests/test_message_fuzz.py does for the other
nodes): whatever the message (NaN, Inf, huge values, bad stamps, wrong frames, non-unit quaternions,
covariances that are not PSD), it is applied or rejected and counted exactly once, nothing escapes a
callback, and the estimator's state stays finite (steps with garbage but valid readings included).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from geometry_msgs.msg import PoseWithCovarianceStamped, Vector3Stamped
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from sensor_msgs.msg import Imu, MagneticField
from support.ros_graph import InProcessGraph, refused
from support.scenarios import make_scenario

from adcs_msgs_py import conversions as cv
from adcs_msgs_py import conversions_determination as cd

FUZZ = settings(derandomize=True, max_examples=40, deadline=None, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
ANY_FLOAT = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.floats(-2.0, 2.0),
                      st.sampled_from([0.0, 1e308, -1e308, 1e-320, math.nan, math.inf, -1.0]))
SEC = st.one_of(st.integers(-2**31, 2**31 - 1), st.integers(0, 5))
NANOSEC = st.one_of(st.integers(0, 2**32 - 1), st.just(0))
FRAME = st.sampled_from([cv.BODY_FRAME, cv.INERTIAL_FRAME, '', 'map'])


def _head(draw, msg):
    msg.header.stamp.sec, msg.header.stamp.nanosec = draw(SEC), draw(NANOSEC)
    msg.header.frame_id = draw(FRAME)
    return msg


def _three(draw, v):
    v.x, v.y, v.z = draw(st.one_of(st.lists(ANY_FLOAT, min_size=3, max_size=3), st.just([0.0, 0.6, 0.8])))


@st.composite
def imus(draw):
    msg = _head(draw, Imu())
    _three(draw, msg.angular_velocity)
    msg.angular_velocity_covariance = draw(st.one_of(st.lists(ANY_FLOAT, min_size=9, max_size=9),
                                                     st.just([1e-10, 0, 0, 0, 1e-10, 0, 0, 0, 1e-10])))
    return msg


@st.composite
def poses(draw):
    msg = _head(draw, PoseWithCovarianceStamped())
    o = msg.pose.pose.orientation
    o.x, o.y, o.z, o.w = draw(st.one_of(st.lists(ANY_FLOAT, min_size=4, max_size=4), st.just([0.0, 0.0, 0.0, 1.0])))
    msg.pose.covariance = draw(st.one_of(st.lists(ANY_FLOAT, min_size=36, max_size=36), st.just([0.0] * 36)))
    return msg


@st.composite
def vectors(draw):
    msg = _head(draw, Vector3Stamped())
    _three(draw, msg.vector)
    return msg


@st.composite
def fields(draw):
    msg = _head(draw, MagneticField())
    _three(draw, msg.magnetic_field)
    msg.magnetic_field_covariance = draw(st.one_of(st.lists(ANY_FLOAT, min_size=9, max_size=9), st.just([0.0] * 9)))
    return msg


@pytest.fixture(scope='module')
def estimator(tmp_path_factory):
    from adcs_controllers.nodes.mekf_estimator import MekfEstimator
    from adcs_sim.app.graph.domains import DomainLease
    tmp = tmp_path_factory.mktemp('fuzz')
    scenario = make_scenario(tmp, {'mekf_estimator': {'sensors': ['gyro', 'star_tracker', 'sun', 'magnetometer'],
                                                      'startup.estimate_subscribers': 0}}, drop=('recorder',))
    lease = DomainLease(100, 232)
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
        mp.setenv('ROS_DOMAIN_ID', str(lease.domain_id))
        with InProcessGraph(scenario) as graph:
            node = graph.add(MekfEstimator)
            node.connect(graph.executor)
            yield node
    lease.release()


@pytest.mark.graph
def test_estimator_survives_any_sensor_message(estimator):
    """The fuzz below (every example), which also reaches the estimator's step, not only the
    conversions: checked on this very run, so it holds whatever ran before or after."""
    before = estimator.steps
    _fuzz(estimator)   # a hypothesis test called directly runs all its examples
    assert estimator.steps > before


@FUZZ
@given(imu=imus(), pose=poses(), sun=vectors(), field=fields(), step=st.integers(0, 10 ** 6))
def _fuzz(estimator, imu, pose, sun, field, step):
    if step % 2:   # half of the examples: one step's four messages, stamped alike in their frames
        for msg, frame in ((imu, cv.BODY_FRAME), (pose, cv.INERTIAL_FRAME), (sun, cv.BODY_FRAME),
                           (field, cv.BODY_FRAME)):
            msg.header.stamp.sec, msg.header.stamp.nanosec = step, 0
            msg.header.frame_id = frame
        # ... with well-formed covariances and a unit quaternion: the fuzzed values reach the step
        imu.angular_velocity_covariance = [0.0] * 9
        field.magnetic_field_covariance = [0.0] * 9
        pose.pose.covariance = [0.0] * 36
        o = pose.pose.pose.orientation
        q = np.array([o.x, o.y, o.z, o.w])
        with np.errstate(all='ignore'):
            n = np.sqrt((q * q).sum())
        o.x, o.y, o.z, o.w = (q / n) if np.isfinite(n) and n > 0 else (0.0, 0.0, 0.0, 1.0)
    for name, msg, convert in (('gyro', imu, cd.imu_from_msg), ('star_tracker', pose, cd.star_tracker_from_msg),
                               ('sun', sun, cd.sun_from_msg), ('magnetometer', field, cd.magnetometer_from_msg)):
        before = estimator.rejects.total
        estimator.subs[name].callback(msg, {})
        if refused(lambda: convert(msg)):
            assert estimator.rejects.total == before + 1, (name, msg)
    e = estimator.estimator
    assert e.t_ns is None or np.shape(e.q) == (4,)
    assert np.isfinite(e.q).all() and np.isfinite(e.beta).all() and np.isfinite(e.P).all()
