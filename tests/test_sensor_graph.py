"""The sensors on the lockstep graph: the dynamics node publishes every fitted sensor's message each
step stamped t_k, equal bit for bit to the batch engine's Measurements of the same scenario (faults
included: a sensor fault stamped t_k acts from t_k on both paths), and never stops on a sensor edge
case (a saturated gyro, a star tracker out for the whole run). In-process graphs on a leased domain;
no sleeps (the tests wait on the recorder's message counts)."""
from __future__ import annotations

import numpy as np
from numpy.testing import assert_array_equal
from support.ros_graph import InProcessGraph, record_sensor_graph, run_lockstep_graph
from support.scenarios import make_scenario

from adcs_controllers.nodes.pd_controller import PdController
from adcs_msgs_py import conversions_determination as cd
from adcs_msgs_py import topics
from adcs_msgs_py.measurements import Reading
from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.scenario.files import validate_scenario
from adcs_sim.bag.reader import read_messages
from adcs_sim.nodes.dynamics import DynamicsNode
from adcs_sim.nodes.recorder import RecorderNode

SENSORS = {'sensors.seed': 11,
           'sensors.gyro.enabled': True, 'sensors.gyro.arw': 1e-4, 'sensors.gyro.rrw': 1e-6,
           'sensors.gyro.bias': [1e-3, -5e-4, 2e-4], 'sensors.gyro.scale_factor': [1e-4, 0.0, -1e-4],
           'sensors.star_tracker.enabled': True, 'sensors.star_tracker.cross_std': 2e-5,
           'sensors.star_tracker.about_std': 2e-4, 'sensors.star_tracker.boresight': [0.0, 1.0, 1.0],
           'sensors.star_tracker.latency': 2.0}
# star tracker out over [10, 15), gyro x bias jump at 5, gyro y stuck from 20, a wheel failure at 25
FAULTS = {'wheels.names': ['rw_x', 'rw_y', 'rw_z'], 'schedule.time': [5.0, 10.0, 15.0, 20.0, 25.0],
          'schedule.actuator': ['gyro.x', 'star_tracker', 'star_tracker', 'gyro.y', 'rw_z'],
          'schedule.mode': ['bias', 'failed', 'recovered', 'stuck', 'failed'],
          'schedule.value': [0.01, 0.0, 0.0, 0.0, 0.0]}


def _batch_readings(scenario):
    sections = validate_scenario(scenario)
    sim = BatchSimulation.from_runs([sections])
    sim.record_sensors = True
    return sim.run()


def _expected(name, rec, k, t_ns):
    reading = Reading(rec['value'][0, k], rec['cov'][0, k], np.bool_(rec['valid'][0, k]))
    return (cd.imu_to_msg if name == 'gyro' else cd.star_tracker_to_msg)(t_ns, reading)


def _assert_imu_equal(got, want):
    v = got.angular_velocity
    assert (v.x, v.y, v.z) == (want.angular_velocity.x, want.angular_velocity.y, want.angular_velocity.z)
    assert_array_equal(np.asarray(got.angular_velocity_covariance), np.asarray(want.angular_velocity_covariance))
    assert got.header.frame_id == want.header.frame_id


def _assert_pose_equal(got, want):
    o, p = got.pose.pose.orientation, want.pose.pose.orientation
    assert (o.x, o.y, o.z, o.w) == (p.x, p.y, p.z, p.w)
    assert_array_equal(np.asarray(got.pose.covariance), np.asarray(want.pose.covariance))


def test_graph_sensor_messages_equal_the_batch_measurements(ros_domain, tmp_path):
    n = 40
    bag_dir = tmp_path / 'bag'
    expect = {'startup.expect_recorder': True, 'startup.expect_faults': True}
    scenario = make_scenario(tmp_path, {'dynamics': {'duration': float(n), **expect, **SENSORS},
                                        'pd_controller': expect, 'recorder': {'output': str(bag_dir)},
                                        'fault_injector': FAULTS})
    expected = {'/state': n + 1, '/controller/status': n + 1, '/wheels/cmd': n + 1, '/wheels/state': n + 1,
                '/truth/state': n + 1, '/sensors/imu': n + 1, '/sensors/star_tracker': n + 1,
                '/dynamics/status': 2, '/faults': 6}
    dyn, pd = run_lockstep_graph(scenario, PdController, expected, faults=True)
    assert dyn.missed_steps == 0 and dyn.rejects.total == 0 and pd.rejects.total == 0 and dyn.faults.late == 0
    assert dyn.wheels.modes == ['nominal', 'nominal', 'failed']

    result = _batch_readings(scenario)
    st_valid = result.sensors['star_tracker']['valid'][0]
    k = np.arange(n + 1)
    assert_array_equal(st_valid, (k >= 2) & ~((k >= 10) & (k < 15)))   # latency 2 steps, outage [10, 15)
    gyro = result.sensors['gyro']['value'][0]
    assert np.all(gyro[21:, 1] == gyro[20, 1]) and gyro[19, 1] != gyro[20, 1]   # stuck from t = 20

    truth = {t: m for _, t, m in read_messages(bag_dir, {'/truth/state'})}
    q_graph = np.array([[m.pose.pose.orientation.x, m.pose.pose.orientation.y, m.pose.pose.orientation.z,
                         m.pose.pose.orientation.w] for _, m in sorted(truth.items())])
    assert_array_equal(q_graph, result.q[0])           # the same truth, bit for bit
    checks = {'/sensors/imu': ('gyro', _assert_imu_equal),
              '/sensors/star_tracker': ('star_tracker', _assert_pose_equal)}
    seen = {topic: 0 for topic in checks}
    for topic, _, msg in read_messages(bag_dir, set(checks)):
        name, check = checks[topic]
        t_ns = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        step = t_ns // 10**9
        check(msg, _expected(name, result.sensors[name], step, t_ns))
        seen[topic] += 1
    assert seen == {topic: n + 1 for topic in checks}


def test_node_survives_sensor_edge_cases(ros_domain, tmp_path):
    """Free flight at zero rate with a gyro saturating at a tiny limit, a star tracker whose latency
    exceeds the run and that fails at t = 0: every step is published (no measurement marked), the run
    ends normally, nothing is rejected."""
    n = 12
    bag_dir = tmp_path / 'bag'
    scenario = make_scenario(tmp_path, {
        'dynamics': {'duration': float(n), 'lockstep.commands': ['none'], 'startup.expect_recorder': True,
                     'startup.expect_faults': True, 'initial.rate': [0.0, 0.0, 0.0],
                     'sensors.gyro.enabled': True, 'sensors.gyro.bias': [1.0, -1.0, 0.0],
                     'sensors.gyro.max_rate': 1e-9, 'sensors.star_tracker.enabled': True,
                     'sensors.star_tracker.latency': 100.0},
        'recorder': {'output': str(bag_dir)},
        'fault_injector': {'schedule.time': [0.0], 'schedule.actuator': ['star_tracker'],
                           'schedule.mode': ['failed']}}, drop=('pd_controller',))
    expected = {'/sensors/imu': n + 1, '/sensors/star_tracker': n + 1, '/dynamics/status': 2}
    dyn = record_sensor_graph(scenario, expected)
    assert dyn.rejects.total == 0 and dyn.missed_steps == 0
    imu = [m for _, _, m in read_messages(bag_dir, {'/sensors/imu'})]
    assert all((m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z) == (1e-9, -1e-9, 0.0) for m in imu)
    stars = [m for _, _, m in read_messages(bag_dir, {'/sensors/star_tracker'})]
    assert all(m.pose.covariance[21] == cd.NO_MEASUREMENT for m in stars)


def test_node_waits_for_the_sensor_subscribers(ros_domain, tmp_path):
    """startup.sensor_subscribers: 1 (what the runner sets for an estimator): the run starts only once
    sensors/imu and sensors/star_tracker each have a subscriber, which then gets every step from t = 0."""
    n = 6
    scenario = make_scenario(tmp_path, {
        'dynamics': {'duration': float(n), 'lockstep.commands': ['none'], 'startup.sensor_subscribers': 1,
                     'startup.timeout': 60.0, 'sensors.gyro.enabled': True, 'sensors.gyro.arw': 1e-4,
                     'sensors.star_tracker.enabled': True, 'sensors.star_tracker.cross_std': 1e-5}},
        drop=('pd_controller',))
    got = {topics.SENSOR_IMU: [], topics.SENSOR_STAR_TRACKER: []}
    with InProcessGraph(scenario) as graph:
        listener = graph.plain('sensor_listener')
        for name, out in got.items():
            spec = topics.spec(name)
            listener.create_subscription(spec.msg_type, name, lambda m, out=out: out.append(m),
                                         topics.subscriber_qos(spec.qos))
        dyn = graph.add(DynamicsNode)
        dyn.run(graph.executor)
        graph.spin_until(lambda: all(len(v) == n + 1 for v in got.values()))
    for msgs in got.values():
        assert [m.header.stamp.sec for m in msgs] == list(range(n + 1))


ENVIRONMENT = {'environment.enabled': True, 'environment.epoch': '2026-03-20T12:00:00Z',
               'environment.circular.altitude': 500e3, 'environment.circular.arg_latitude_deg': 100.0,
               'sensors.seed': 5, 'sensors.gyro.enabled': True, 'sensors.gyro.arw': 1e-4,
               'sensors.sun.enabled': True, 'sensors.sun.std': 1e-3, 'sensors.sun.fov_deg': 180.0,
               'sensors.magnetometer.enabled': True, 'sensors.magnetometer.std': 1e-7}


def _assert_sun_equal(got, want):
    assert (got.vector.x, got.vector.y, got.vector.z) == (want.vector.x, want.vector.y, want.vector.z)


def _assert_field_equal(got, want):
    f, g = got.magnetic_field, want.magnetic_field
    assert (f.x, f.y, f.z) == (g.x, g.y, g.z)
    assert_array_equal(np.asarray(got.magnetic_field_covariance), np.asarray(want.magnetic_field_covariance))


def test_environment_sensors_on_the_graph_equal_the_batch_through_an_eclipse(ros_domain, tmp_path):
    """environment.enabled: the dynamics node samples the orbit, Sun, shadow and IGRF field at each t_k
    for the sun sensor and the magnetometer, as the batch engine does: every message equal bit for bit.
    Equatorial 500 km orbit at the March equinox, starting 100 deg from the Sun line: the satellite
    enters the umbra (argument of latitude 180 - asin(R/r) = 112 deg, about 190 s in), so the sun
    sensor's readings go from valid to none on both paths."""
    n, period = 60, 5.0
    bag_dir = tmp_path / 'bag'
    scenario = make_scenario(tmp_path, {
        'dynamics': {'duration': n * period, 'control_period': period, 'integrator.max_step': period,
                     'lockstep.commands': ['none'], 'startup.expect_recorder': True, **ENVIRONMENT},
        'recorder': {'output': str(bag_dir)}}, drop=('pd_controller',))
    expected = {'/sensors/imu': n + 1, '/sensors/sun': n + 1, '/sensors/magnetometer': n + 1, '/dynamics/status': 2}
    with InProcessGraph(scenario) as graph:
        rec = graph.add(RecorderNode)
        dyn = graph.add(DynamicsNode)
        dyn.run(graph.executor)
        counts = rec.bag.topics
        graph.spin_until(lambda: all(t in counts and counts[t].count == c for t, c in expected.items()))
        rec.close()
    result = _batch_readings(scenario)
    sun_valid = result.sensors['sun']['valid'][0]
    assert sun_valid[0] and not sun_valid[-1]            # lit at the start, in the umbra at the end
    convert = {'/sensors/sun': ('sun', cd.sun_to_msg, _assert_sun_equal),
               '/sensors/magnetometer': ('magnetometer', cd.magnetometer_to_msg, _assert_field_equal)}
    seen = {topic: 0 for topic in convert}
    for topic, _, msg in read_messages(bag_dir, set(convert)):
        name, to_msg, check = convert[topic]
        t_ns = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        k = int(round(t_ns / (period * 1e9)))
        rec_ = result.sensors[name]
        check(msg, to_msg(t_ns, Reading(rec_['value'][0, k], rec_['cov'][0, k], np.bool_(rec_['valid'][0, k]))))
        seen[topic] += 1
    assert seen == {topic: n + 1 for topic in convert}
    field = np.linalg.norm(result.sensors['magnetometer']['value'][0], axis=-1)
    assert np.all((2e-5 < field) & (field < 6e-5))       # the geomagnetic field's size at 500 km
