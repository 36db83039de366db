"""The fine sun sensor on the lockstep graph equals its batch run bit for bit (issue #32 item 3; the
recipe of tests/test_sensor_graph.py): the dynamics node publishes its reading on sensors/fine_sun
every step from the environment it samples at t_k, as the batch engine measures it, through the Sun
leaving its field of view and a sensor failure of the fault schedule. In-process graph on a leased
domain; no sleeps (the test waits on the recorder's message counts)."""
from __future__ import annotations

import numpy as np
from numpy.testing import assert_array_equal
from support.ros_graph import InProcessGraph, record_sensor_graph
from support.scenarios import make_scenario

from adcs_msgs_py import conversions_determination as cd
from adcs_msgs_py.measurements import Reading
from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.scenario.files import validate_scenario
from adcs_sim.bag.reader import read_messages
from adcs_sim.nodes.dynamics import DynamicsNode
from adcs_sim.nodes.recorder import RecorderNode

# March equinox (the Sun along inertial +x), sunlit part of a 500 km equatorial orbit; the spacecraft
# turns about z at 0.005 rad/s, so the Sun (on the boresight +x at t = 0) leaves the 30 deg half-cone
# after about 105 s; the sensor fails over [20, 40) s.
SENSORS = {'environment.enabled': True, 'environment.epoch': '2026-03-20T12:00:00Z',
           'environment.circular.altitude': 500e3, 'environment.circular.arg_latitude_deg': -60.0,
           'initial.attitude': [0.0, 0.0, 0.0, 1.0], 'initial.rate': [0.0, 0.0, 0.005],
           'sensors.seed': 8, 'sensors.gyro.enabled': True, 'sensors.gyro.arw': 1e-4,
           'sensors.fine_sun_sensor.enabled': True, 'sensors.fine_sun_sensor.std': 2e-4,
           'sensors.fine_sun_sensor.boresight': [1.0, 0.0, 0.0], 'sensors.fine_sun_sensor.fov_deg': 30.0}
FAULTS = {'schedule.time': [20.0, 40.0], 'schedule.actuator': ['fine_sun_sensor', 'fine_sun_sensor'],
          'schedule.mode': ['failed', 'recovered']}


def test_fine_sun_sensor_messages_on_the_graph_equal_the_batch(ros_domain, tmp_path):
    n, period = 40, 5.0
    bag_dir = tmp_path / 'bag'
    expect = {'startup.expect_recorder': True, 'startup.expect_faults': True}
    scenario = make_scenario(tmp_path, {
        'dynamics': {'duration': n * period, 'control_period': period, 'integrator.max_step': period,
                     'lockstep.commands': ['none'], **expect, **SENSORS},
        'recorder': {'output': str(bag_dir)}, 'fault_injector': FAULTS}, drop=('pd_controller',))
    expected = {'/sensors/imu': n + 1, '/sensors/fine_sun': n + 1, '/dynamics/status': 2, '/faults': 3}
    dyn = record_sensor_graph(scenario, expected)
    assert dyn.rejects.total == 0 and dyn.missed_steps == 0 and dyn.faults.late == 0

    sim = BatchSimulation.from_runs([validate_scenario(scenario)])
    sim.record_sensors = True
    result = sim.run()
    rec_ = result.sensors['fine_sun_sensor']
    k = np.arange(n + 1)
    valid = rec_['valid'][0]
    assert_array_equal(valid[(k * period >= 20) & (k * period < 40)], False)   # failed
    assert valid[k * period < 20].all() and valid[(k * period >= 40) & (k * period < 100)].all()
    assert not valid[k * period >= 110].any()                                # out of the field of view
    seen = 0
    for _, _, msg in read_messages(bag_dir, {'/sensors/fine_sun'}):
        t_ns = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        step = int(round(t_ns / (period * 1e9)))
        want = cd.sun_to_msg(t_ns, Reading(rec_['value'][0, step], rec_['cov'][0, step], np.bool_(valid[step])))
        assert (msg.vector.x, msg.vector.y, msg.vector.z) == (want.vector.x, want.vector.y, want.vector.z)
        assert msg.header.frame_id == want.header.frame_id
        seen += 1
    assert seen == n + 1
    truth = [m for _, _, m in read_messages(bag_dir, {'/truth/state'})]
    q_graph = np.array([[m.pose.pose.orientation.x, m.pose.pose.orientation.y, m.pose.pose.orientation.z,
                         m.pose.pose.orientation.w] for m in truth])
    assert_array_equal(q_graph, result.q[0])          # the same truth, bit for bit


def test_estimator_chain_on_the_fine_sun_sensor_in_lockstep_equals_the_batch(ros_domain, tmp_path):
    """dynamics (gyro, fine sun sensor, magnetometer on the LEO scenario's TLE orbit) -> mekf_estimator
    on the three -> PD controller on estimate/state -> dynamics, in lockstep with a recorder: the bag's
    truth and every estimate (attitude, rate) are the batch engine's, bit for bit."""
    from adcs_controllers.nodes.mekf_estimator import MekfEstimator
    from adcs_controllers.nodes.pd_controller import PdController
    from adcs_sim.app.analysis import estimation
    n = 30
    bag_dir = tmp_path / 'bag'
    recorder = {'startup.expect_recorder': True}
    scenario = make_scenario(tmp_path, {
        'dynamics': {'duration': float(n), 'startup.sensor_subscribers': 2, 'startup.state_subscribers': 1, **recorder,
                     'sensors.sun.enabled': False, 'sensors.fine_sun_sensor.enabled': True,
                     'sensors.fine_sun_sensor.std': 2e-4, 'sensors.fine_sun_sensor.boresight': [1.0, 0.2, 0.0]},
        'mekf_estimator': {'sensors': ['gyro', 'fine_sun_sensor', 'magnetometer'], 'fine_sun_sensor.sigma': 2e-4,
                           'startup.estimate_subscribers': 1, **recorder},
        'pd_controller': recorder, 'recorder': {'output': str(bag_dir)}}, base='leo_tle_sun_magnetometer_mekf.yaml')
    expected = {'/state': n + 1, '/estimate/state': n + 1, '/wheels/cmd': n + 1, '/sensors/fine_sun': n + 1,
                '/sensors/magnetometer': n + 1, '/dynamics/status': 2}
    with InProcessGraph(scenario) as graph:
        rec = graph.add(RecorderNode)
        dyn = graph.add(DynamicsNode)
        est = graph.add(MekfEstimator)
        pd = graph.add(PdController)
        pd.connect(graph.executor)      # its wheels/cmd is matched: it subscribes to estimate/state
        est.connect(graph.executor)     # estimate/state is matched by the controller: it subscribes to the sensors
        dyn.run(graph.executor)
        counts = rec.bag.topics
        graph.spin_until(lambda: all(t in counts and counts[t].count == c for t, c in expected.items()),
                         timeout=120.0)
        rec.close()
    assert dyn.missed_steps == 0 and dyn.rejects.total == 0 and est.rejects.total == 0

    result = BatchSimulation.from_runs([validate_scenario(scenario)]).run()
    bag, ours = estimation.series_from_bag(bag_dir), estimation.series_from_batch(result, 0)
    k = ours.t.size   # the batch's estimates of t_0 .. t_K-1; the graph's estimator also answers the last state
    assert bag.t.size in (k, k + 1) and np.array_equal(bag.t[:k], ours.t)
    assert_array_equal(ours.q, bag.q[:k])
    assert_array_equal(ours.w, bag.w[:k])
    assert ours.status['used_fine_sun_sensor'].astype(bool).all()
    truth = [m for _, _, m in read_messages(bag_dir, {'/truth/state'})]
    q_graph = np.array([[m.pose.pose.orientation.x, m.pose.pose.orientation.y, m.pose.pose.orientation.z,
                         m.pose.pose.orientation.w] for m in truth])
    assert_array_equal(q_graph, result.q[0])
