"""Estimator nodes on the graph (in this process, their own ROS domain): the test publishes each step's
sensor messages (tests/support/estimation_truth.py through the contract conversions), the estimator answers
with estimate/state and estimator/status stamped with the step, and a PD controller flying on the
estimate (``feedback: estimate``, its only change) answers with its command. The estimates equal the
family's own step on the same readings bit for bit; the commands equal the law's on the estimates.

Start-up without sleeps: the controller subscribes to estimate/state once its command publisher is
matched, the estimator subscribes to the sensors once estimate/state is matched by the controller,
and the test publishes the first step once each sensor topic has its subscriber (what the dynamics
node waits for). Then each step waits for the answers to the previous one (lockstep). A NaN gyro
message and a repeated (stale) one are rejected and counted; the run goes on.
"""
from __future__ import annotations

import numpy as np
import pytest
from support.estimation_truth import Truth
from support.ros_graph import InProcessGraph
from support.scenarios import make_scenario

from adcs_controllers.estimators.families import MEKF, QUEST
from adcs_controllers.families import PD
from adcs_msgs_py import conversions as cv
from adcs_msgs_py import conversions_determination as cd
from adcs_msgs_py import topics
from adcs_msgs_py.measurements import Measurements
from adcs_msgs_py.names import SENSOR_TOPICS

TO_MSG = {'gyro': cd.imu_to_msg, 'star_tracker': cd.star_tracker_to_msg, 'sun': cd.sun_to_msg,
          'magnetometer': cd.magnetometer_to_msg}
FROM_MSG = {'gyro': cd.imu_from_msg, 'star_tracker': cd.star_tracker_from_msg, 'sun': cd.sun_from_msg,
            'magnetometer': cd.magnetometer_from_msg}
STEPS = 25
OMEGA = np.array([0.02, -0.01, 0.015])


CASES = {
    'mekf_estimator': (MEKF, {'sensors': ['gyro', 'star_tracker'], 'gyro.sigma_v': 1e-5, 'gyro.sigma_u': 1e-7,
                              'initial.attitude_sigma': [0.05] * 3}, ('gyro', 'star_tracker')),
    'quest_estimator': (QUEST, {'references.magnetometer': [0.0, 0.6, 0.8], 'magnetometer.sigma': 1e-3},
                        ('gyro', 'sun', 'magnetometer')),
}


@pytest.mark.parametrize('name', sorted(CASES))
def test_estimator_node_equals_its_family_and_a_controller_flies_on_it(name, ros_domain, tmp_path):
    from rclpy.qos import QoSProfile

    from adcs_controllers.nodes.mekf_estimator import MekfEstimator
    from adcs_controllers.nodes.pd_controller import PdController
    from adcs_controllers.nodes.quest_estimator import QuestEstimator
    family, section, sensors = CASES[name]
    node_class = {'mekf_estimator': MekfEstimator, 'quest_estimator': QuestEstimator}[name]
    scenario = make_scenario(tmp_path, {name: section, 'pd_controller': {'feedback': 'estimate'}}, drop=('recorder',))
    truth = Truth(1, 3, 1.0, OMEGA, 1e-5, 1e-7, sensors=sensors, star_every=2, outage=range(10, 14), batch=False)
    got = {'estimate': [], 'status': [], 'cmd': []}
    with InProcessGraph(scenario) as graph:
        est = graph.add(node_class)
        pd = graph.add(PdController)
        test = graph.plain('sensors_stand_in')
        pubs = {s: test.create_publisher(topics.spec(SENSOR_TOPICS[s]).msg_type, SENSOR_TOPICS[s],
                                         topics.QOS_LOCKSTEP) for s in sensors}
        for key, topic in (('estimate', topics.ESTIMATE_STATE), ('status', topics.ESTIMATOR_STATUS),
                           ('cmd', topics.WHEELS_CMD)):
            qos = topics.spec(topic).qos
            test.create_subscription(topics.spec(topic).msg_type, topic, got[key].append,
                                     QoSProfile(depth=100, reliability=qos.reliability, durability=qos.durability))
        pd.connect(graph.executor)      # its wheels/cmd is matched by the test: it subscribes to estimate/state
        est.connect(graph.executor)     # estimate/state is matched by the controller: it subscribes to the sensors
        graph.spin_until(lambda: all(p.get_subscription_count() >= 1 for p in pubs.values()), what='sensor subs')
        sent = []
        for k in range(STEPS):
            m = truth.step()
            msgs = {s: TO_MSG[s](m.t_ns, getattr(m, s)) for s in reversed(sensors)}   # any order
            if k == 5:   # a bad gyro message of this step first: rejected, counted, the step goes on
                bad = TO_MSG['gyro'](m.t_ns, m.gyro)
                bad.angular_velocity.x = float('nan')
                pubs['gyro'].publish(bad)
            if k == 6:   # the previous step's gyro message again: a stale stamp, rejected
                pubs['gyro'].publish(sent[-1]['gyro'])
            for s, msg in msgs.items():
                pubs[s].publish(msg)
            sent.append(msgs)
            graph.spin_until(lambda n=k + 1: len(got['estimate']) >= n and len(got['cmd']) >= n
                             and len(got['status']) >= n, what=f'the answers to step {k}')
        assert dict(est.rejects.counts) == {topics.SENSOR_IMU: 2} and pd.rejects.total == 0

    reference = family.build(family.schema.validate(section))
    law, actuation = PD.build(PD.schema.validate(dict(_pd_section(scenario), feedback='estimate')))
    for k, (msgs, e_msg, c_msg, s_msg) in enumerate(zip(sent, got['estimate'], got['cmd'], got['status'])):
        readings = {s: FROM_MSG[s](msg)[1] for s, msg in msgs.items()}
        e, status = reference.step(Measurements(k * 1_000_000_000, **readings))
        assert cv.ns_from_stamp(e_msg.header.stamp) == k * 1_000_000_000
        t_ns, q, w = cv.state_from_msg(e_msg)
        expected = cd.estimate_to_msg(e)
        np.testing.assert_array_equal(q, cv.state_from_msg(expected)[1])
        np.testing.assert_array_equal(w, e.w)
        np.testing.assert_array_equal(np.array(e_msg.pose.covariance), np.array(expected.pose.covariance))
        np.testing.assert_array_equal(np.array(e_msg.twist.covariance), np.array(expected.twist.covariance))
        values = cv.status_values(s_msg.status[0])
        for key, v in status.items():
            if isinstance(v, (bool, np.bool_)):
                assert values[key] == str(bool(v)), (k, key)
            else:
                assert np.array_equal(values[key], float(v), equal_nan=True), (k, key)
        torque, _ = law.control(k * 1.0, q, w)
        np.testing.assert_array_equal(np.array(c_msg.effort), actuation.command(torque)[0])
    assert values[f'used_{sensors[1]}'] == 'True' and values['rejected_messages'] == 2.0


def _pd_section(scenario):
    from adcs_msgs_py.params_file import load_params_file
    return load_params_file(str(scenario))['pd_controller']
