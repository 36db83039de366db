"""Actuator faults: the plant's fault modes, the fault schedule's validation, and the fault
injector driving the dynamics node and a controller in lockstep (in one process).

Plant tests need no ROS; the graph test runs on its own leased domain (``ros_domain``) and waits
on the graph's own events, never on sleeps.
"""
from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from support.ros_graph import run_fault_graph
from support.scenarios import make_scenario

from adcs_core.faults import FaultTracker
from adcs_msgs_py.params import ParameterError
from adcs_sim.truth.fault_schedule import FAULT_SCHEMA, fault_schedule
from adcs_sim.truth.plant import Plant, ReactionWheels, WheelCommand

INF = np.inf
J = np.diag([10.0, 12.0, 8.0])
Q0 = np.array([0.1, -0.2, 0.3, 0.9])
Q0 = Q0 / np.linalg.norm(Q0)
PYRAMID = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0, 1.0]])


def wheels(n=3, axes=None, spin_inertia=0.05, max_torque=0.01) -> ReactionWheels:
    axes = np.eye(3) if axes is None else axes
    return ReactionWheels(names=[f'rw{i}' for i in range(n)], axes=axes,
                          spin_inertia=np.broadcast_to(spin_inertia, np.shape(spin_inertia)[:-1] + (n,))
                          if np.ndim(spin_inertia) else [spin_inertia] * n,
                          max_torque=[max_torque] * n, max_speed=[INF] * n)


def cmd(values) -> WheelCommand:
    values = np.asarray(values, dtype=float)
    return WheelCommand(values, np.zeros(values.shape[-1], dtype=bool))


# --- plant ------------------------------------------------------------------------------------

def test_failed_wheel_gives_zero_motor_torque_and_recovers():
    rw = wheels()
    rw.apply_fault(2, 'failed')
    assert_array_equal(rw.available, [True, True, False])
    assert_array_equal(rw.motor_torque(np.zeros(3), cmd([0.005, -0.005, 0.008])), [0.005, -0.005, 0.0])
    rw.apply_fault(2, 'recovered')
    assert rw.modes == ['nominal'] * 3
    assert_array_equal(rw.motor_torque(np.zeros(3), cmd([0.005, -0.005, 0.008])), [0.005, -0.005, 0.008])


def test_degraded_limit_and_bias():
    rw = wheels()
    rw.apply_fault(0, 'degraded', 0.002)
    rw.apply_fault(1, 'bias', 0.0005)
    assert_array_equal(rw.motor_torque(np.zeros(3), cmd([0.008, 0.001, -0.02])),
                       [0.002, 0.0015, -0.01])
    assert_array_equal(rw.motor_torque(np.zeros(3), cmd([-0.008, 0.0, 0.0])), [-0.002, 0.0005, 0.0])
    # the bias acts after saturation (an offset of the drive electronics)
    assert_array_equal(rw.motor_torque(np.zeros(3), cmd([0.0, 0.02, 0.0]))[1], 0.0105)
    # a new mode replaces the previous one: a failed wheel has no bias either
    rw.apply_fault(1, 'failed')
    assert rw.motor_torque(np.zeros(3), cmd([0.0, 0.001, 0.0]))[1] == 0.0
    rw.apply_fault(0, 'recovered')
    assert rw.motor_torque(np.zeros(3), cmd([0.008, 0.0, 0.0]))[0] == 0.008
    with pytest.raises(ValueError, match='unknown wheel fault mode'):
        rw.apply_fault(0, 'melted')


def test_degraded_limit_applies_in_integration():
    """A degraded wheel spins up at its degraded limit, not at the commanded torque."""
    results = []
    for limit in (None, 0.002):
        plant = Plant(J, [wheels()])
        if limit is not None:
            plant.actuator('wheels').apply_fault(0, 'degraded', limit)
        x = plant.initial_state([0, 0, 0, 1.0], np.zeros(3))
        commands = plant.zero_commands()
        commands['wheels'] = cmd([0.008, 0.0, 0.0])
        for k in range(10):
            x = plant.step(float(k), x, commands, 1.0, 0.5)
        results.append(x)
    # body x rate from rest: J_s,x w_x = -tau t (J_s: without the wheel's spin inertia)
    assert_allclose(results[0][4], -0.008 * 10 / (10.0 - 0.05), rtol=1e-12)
    assert_allclose(results[1][4], -0.002 * 10 / (10.0 - 0.05), rtol=1e-12)


def _stuck_run(plant, x, n=40, period=0.5):
    commands = plant.zero_commands()
    commands['wheels'] = cmd(np.array([0.004, -0.003, 0.002, 0.001]))
    states = [x]
    for k in range(n):
        x = plant.step(k * period, x, commands, period, 0.01)
        states.append(x)
    return np.array(states)


def _tumbling(plant):
    x = plant.initial_state(Q0, np.array([0.05, -0.03, 0.02]))
    x = np.array(x, copy=True)
    x[..., 7:11] = [30.0, -20.0, 12.0, 50.0]
    return x


def test_stuck_wheel_speed_constant_and_momentum_conserved():
    """A stuck wheel (relative speed frozen) on a tumbling body with spinning wheels and torque
    commands on the others: its speed stays exactly constant and the inertial angular momentum
    is conserved (to the RK4 truncation error, ~1e-15 with h = 0.01 s; it falls as h^4, so the
    coupled body/stuck-wheel system itself conserves it exactly)."""
    plant = Plant(J, [wheels(4, PYRAMID, 0.03)])
    rw = plant.actuator('wheels')
    rw.apply_fault(3, 'stuck')
    assert rw.motor_torque(np.zeros(4), cmd([0.0, 0.0, 0.0, 0.01]))[3] == 0.0
    x0 = _tumbling(plant)
    states = _stuck_run(plant, x0)
    assert_array_equal(states[:, 10], 50.0)                  # stuck wheel: relative speed frozen
    assert np.ptp(states[:, 7]) > 1e-3                        # the others move
    H = plant.inertial_momentum(states)
    assert_allclose(H, np.broadcast_to(H[0], H.shape), rtol=0, atol=1e-13 * np.abs(H[0]).max())
    # the body feels the stuck wheel: the run differs from the healthy one
    healthy = Plant(J, [wheels(4, PYRAMID, 0.03)])
    assert np.abs(_stuck_run(healthy, x0)[-1, 4:7] - states[-1, 4:7]).max() > 1e-6
    # recovering it frees the wheel again (the body equation is re-solved)
    rw.apply_fault(3, 'recovered')
    assert_array_equal(_stuck_run(plant, x0), _stuck_run(healthy, x0))


def test_stuck_wheel_batch_matches_single_runs():
    """A batch of two spacecraft (different inertias and wheel spin inertias) with a stuck wheel:
    every array keeps its leading batch axis and each run equals its own unbatched run."""
    Js = np.array([[0.03] * 4, [0.05, 0.04, 0.03, 0.02]])
    Jb = np.stack([J, np.diag([11.0, 9.0, 13.0])])
    batch = Plant(Jb, [wheels(4, PYRAMID, Js)])
    batch.actuator('wheels').apply_fault(3, 'stuck')
    x0 = np.broadcast_to(_tumbling(Plant(J, [wheels(4, PYRAMID, 0.03)])), (2, 15)).copy()
    states = _stuck_run(batch, x0, n=10)
    assert states.shape == (11, 2, 15)
    assert_array_equal(states[:, :, 10], 50.0)
    for i in range(2):
        single = Plant(Jb[i], [wheels(4, PYRAMID, Js[i])])
        single.actuator('wheels').apply_fault(3, 'stuck')
        assert_allclose(states[:, i], _stuck_run(single, x0[i], n=10), rtol=0, atol=1e-13)
    H = batch.inertial_momentum(states)
    assert H.shape == (11, 2, 3)
    assert_allclose(H, np.broadcast_to(H[0], H.shape), rtol=0, atol=1e-13)


# --- schedule and its validation ---------------------------------------------------------------

WHEELS = ['rw_x', 'rw_y', 'rw_z']


def section(**overrides):
    v = {'wheels.names': WHEELS, 'schedule.time': [100.0, 200.0], 'schedule.actuator': ['rw_z', 'rw_z'],
         'schedule.mode': ['failed', 'recovered'], 'schedule.value': [0.0, 0.0]}
    v.update(overrides)
    return v


@pytest.mark.parametrize('overrides, key, text', [
    ({'schedule.mode': ['failed', 'exploded']}, 'schedule.mode', 'exploded'),
    ({'schedule.actuator': ['rw_z']}, 'schedule.actuator', 'one entry per scheduled event'),
    ({'schedule.mode': ['failed']}, 'schedule.mode', 'one entry per scheduled event'),
    ({'schedule.value': [0.0]}, 'schedule.value', 'one entry per scheduled event'),
    ({'schedule.time': [-1.0, 200.0]}, 'schedule.time', '>= 0'),
    ({'schedule.actuator': ['rw_z', 'rw_w']}, 'schedule.actuator', 'rw_w'),
    ({'schedule.mode': ['degraded', 'recovered'], 'schedule.value': [-0.001, 0.0]}, 'schedule.value', '>= 0'),
])
def test_fault_schema_errors_name_the_key(overrides, key, text):
    with pytest.raises(ParameterError, match=text) as err:
        FAULT_SCHEMA.validate(section(**overrides))
    assert err.value.key == key
    assert f'fault_injector.ros__parameters.{key}' in str(err.value)


def test_fault_schedule_snapshots():
    v = FAULT_SCHEMA.validate(section(**{
        'schedule.time': [200.0, 100.0, 100.0], 'schedule.actuator': ['rw_z', 'rw_x', 'rw_z'],
        'schedule.mode': ['recovered', 'bias', 'failed'], 'schedule.value': [0.0, 0.001, 5.0]}))
    snaps = fault_schedule(v)
    assert [t for t, _ in snaps] == [0, 100_000_000_000, 200_000_000_000]
    assert snaps[0][1] == {w: ('nominal', 0.0, 0.0) for w in WHEELS}
    assert snaps[1][1] == {'rw_x': ('bias', 0.001, 100.0), 'rw_y': ('nominal', 0.0, 0.0),
                           'rw_z': ('failed', 0.0, 100.0)}
    assert snaps[2][1]['rw_z'] == ('recovered', 0.0, 200.0) and snaps[2][1]['rw_x'][0] == 'bias'


def test_fault_tracker_applies_at_stamp_and_counts_late():
    tr = FaultTracker()
    tr.add(0, 0, 3, {'a': ('nominal', 0.0)})
    tr.add(10, 1, 3, {'a': ('failed', 0.0)})
    assert not tr.complete
    assert tr.due(0) == {'a': ('nominal', 0.0)}
    assert tr.due(0) is None and tr.due(5) is None
    assert tr.due(10) == {'a': ('failed', 0.0)} and tr.late == 0
    tr.add(15, 2, 3, {'a': ('recovered', 0.0)})   # arrives after step 15 has been handled
    assert tr.complete
    assert tr.due(15) == {'a': ('recovered', 0.0)} and tr.late == 0  # same step: in time
    tr2 = FaultTracker()
    tr2.add(0, 0, 2, {})
    tr2.due(0), tr2.due(10)
    tr2.add(10, 1, 2, {'a': ('failed', 0.0)})
    assert tr2.due(20) == {'a': ('failed', 0.0)} and tr2.late == 1


def test_runner_cross_checks_fault_actuators(tmp_path):
    from adcs_sim.app.scenario.files import validate_scenario
    fault = {'wheels.names': WHEELS + ['rw_w'], 'schedule.time': [10.0], 'schedule.actuator': ['rw_w'],
             'schedule.mode': ['failed'], 'schedule.value': [0.0]}
    with pytest.raises(ParameterError, match='rw_w') as err:
        validate_scenario(make_scenario(tmp_path, {'fault_injector': fault}))
    assert 'fault_injector.ros__parameters.schedule.actuator' in str(err.value)
    # the node's own check (its wheels.names) also names it
    fault['wheels.names'] = WHEELS
    with pytest.raises(ParameterError, match='rw_w') as err:
        validate_scenario(make_scenario(tmp_path, {'fault_injector': fault}))
    assert 'fault_injector.ros__parameters.schedule.actuator' in str(err.value)
    fault['schedule.actuator'] = ['rw_z']
    assert 'fault_injector' in validate_scenario(make_scenario(tmp_path, {'fault_injector': fault}))


def test_batch_applies_the_fault_schedule(tmp_path):
    """The batch engine applies the schedule as the graph does: rw_z fails at 100 s and recovers
    at 200 s; the body gets no z torque over [100, 200) (the only wheel on z is gone and the
    allocation knows it), z torque before and after, and the faults are in the run's data."""
    from adcs_sim.app.batch.engine import BatchSimulation
    from adcs_sim.app.scenario.files import validate_scenario
    sections = validate_scenario(make_scenario(tmp_path, {'fault_injector': section(),
                                                          'dynamics': {'duration': 300.0}}))
    sim = BatchSimulation.from_runs([sections])
    result = sim.run()
    t_u, u = result.t[:-1], result.u[0]
    out = (t_u >= 100.0) & (t_u < 200.0)
    assert np.all(u[out, 2] == 0.0)
    assert u[t_u == 99.0, 2][0] != 0.0 and np.any(u[t_u >= 200.0, 2] != 0.0)
    run = result.run_data(0)
    assert (100.0, 2, 'rw_z', 'failed') in run.faults and (200.0, 0, 'rw_z', 'recovered') in run.faults
    assert sim.wheels.modes == ['nominal'] * 3  # recovered by the end
    # a second run starts from the nominal wheels again and gives the same numbers
    assert_array_equal(sim.run().u, result.u)


# --- the graph ----------------------------------------------------------------------------------

def test_wheel_failure_in_lockstep_graph(ros_domain, tmp_path):
    """PD slew, rw_z fails at t = 100 s: from that step on rw_z produces no torque and is
    commanded none (the controller re-allocates), the body gets no z torque over [100, 101] but
    did over [99, 100], and the fault is in the bag."""
    from adcs_controllers.nodes.pd_controller import PdController
    from adcs_sim.app.analysis.metrics import RunData
    from adcs_sim.bag.reader import read_messages

    n, t_fault = 300, 100.0
    bag_dir = tmp_path / 'bag'
    expect = {'startup.expect_recorder': True, 'startup.expect_faults': True}
    scenario = make_scenario(tmp_path, {
        'dynamics': {'duration': float(n), **expect},
        'pd_controller': expect,
        'recorder': {'output': str(bag_dir)},
        'fault_injector': {'wheels.names': WHEELS, 'schedule.time': [t_fault],
                           'schedule.actuator': ['rw_z'], 'schedule.mode': ['failed'],
                           'schedule.value': [0.0]}})
    dyn, pd = run_fault_graph(scenario, PdController, n)
    assert dyn.missed_steps == 0 and dyn.faults.late == 0 and pd.faults.late == 0
    assert dyn.rejects.total == 0 and pd.rejects.total == 0
    assert dyn.wheels.modes == ['nominal', 'nominal', 'failed']
    assert_array_equal(pd.actuation.available, [True, True, False])

    run = RunData.from_bag(bag_dir)
    assert (t_fault, 2, 'rw_z', 'failed') in run.faults
    assert all(level == 0 for t, level, _, _ in run.faults if t < t_fault)
    z = run.wheel_names.index('rw_z')
    before, after = run.t_wheels < t_fault, run.t_wheels >= t_fault
    assert np.all(run.wheel_torque[after, z] == 0.0)
    assert run.wheel_torque[before, z][-1] != 0.0
    # applied body torque over [t_k, t_k+1], stamped t_k: z torque up to 99, none from 100
    k = int(np.flatnonzero(run.t_u == t_fault)[0])
    assert run.u[k - 1, 2] != 0.0
    assert np.all(run.u[k:, 2] == 0.0)

    cmds = [(t, msg) for _, t, msg in read_messages(bag_dir, {'/wheels/cmd'})]
    assert len(cmds) == n + 1
    z_cmd = {t / 1e9: msg.effort[list(msg.name).index('rw_z')] for t, msg in cmds}
    assert z_cmd[t_fault - 1] != 0.0
    assert all(v == 0.0 for t, v in z_cmd.items() if t >= t_fault)
    status = {t: values for t, _, values in run.controller_status}
    assert status[t_fault - 1]['available_wheels'] == 'rw_x,rw_y,rw_z'
    assert status[t_fault]['available_wheels'] == 'rw_x,rw_y'


def test_the_fault_injector_publishes_its_schedule_only_once_the_recorder_is_matched(ros_domain, tmp_path):
    """With ``startup.expect_recorder`` (the runner sets it) the schedule goes out only once the
    recorder's subscription is matched: a subscriber that is not the recorder gets nothing (the
    dynamics node and the controllers, which wait for the whole schedule, cannot start t = 0
    before the recorder holds it), and once the recorder joins both receive all of it. The
    CI failure this pins: on a loaded machine a 40-step run ended before the recorder's
    participant had discovered the injector, and the bag had the fault's torques, not the fault."""
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.qos import QoSProfile
    from support.ros_graph import InProcessGraph

    from adcs_msgs_py import topics
    from adcs_sim.nodes.fault_injector import FaultInjectorNode
    from adcs_sim.nodes.recorder import RecorderNode

    bag_dir = tmp_path / 'bag'
    scenario = make_scenario(tmp_path, {
        'recorder': {'output': str(bag_dir)},
        'fault_injector': {'wheels.names': WHEELS, 'schedule.time': [20.0], 'schedule.actuator': ['rw_z'],
                           'schedule.mode': ['failed'], 'schedule.value': [0.0],
                           'startup.expect_recorder': True, 'startup.timeout': 60.0}})
    got = []
    with InProcessGraph(scenario) as graph:
        injector = graph.add(FaultInjectorNode)
        listener = graph.plain('listener')
        sub = listener.create_subscription(DiagnosticArray, topics.FAULTS, got.append,
                                           QoSProfile(**{k: getattr(topics.QOS_LATCHED, k) for k in
                                                         ('history', 'depth', 'reliability', 'durability')}))
        graph.spin_until(lambda: sub.get_publisher_count() >= 1 and injector.pub_faults.get_subscription_count() >= 1,
                         what='the listener matched with the injector')
        for _ in range(20):   # matched, spun: a schedule written at construction would be here now
            graph.executor.spin_once(timeout_sec=0.01)
        assert got == [] and not injector._recorder_matched()
        rec = graph.add(RecorderNode)
        injector.publish_once_recorded()   # returns once the recorder is matched and has acked it
        graph.spin_until(lambda: len(got) == 2 and rec.bag.topics['/faults'].count == 2,
                         what='the schedule at the listener and in the bag')
        rec.close()
    from adcs_sim.bag.reader import read_messages
    recorded = [(t, [(s.name, s.message) for s in msg.status]) for _, t, msg in read_messages(bag_dir, {'/faults'})]
    assert [t for t, _ in recorded] == [0, 20_000_000_000] and ('rw_z', 'failed') in recorded[1][1]


def test_runner_with_fault_injector_is_deterministic(ros_domain, tmp_path):
    """The runner starts the fault injector as its own process and tells the dynamics and the
    controller to collect the schedule first: two runs of a scenario with a fault at t = 20 s
    record identical wheel torques, and rw_z is commanded nothing from t = 20 s on."""
    from adcs_sim.app.analysis.metrics import RunData
    from adcs_sim.app.graph.runner import run_scenario
    scenario = make_scenario(tmp_path, {
        'dynamics': {'duration': 40.0},
        'fault_injector': {'wheels.names': WHEELS, 'schedule.time': [20.0],
                           'schedule.actuator': ['rw_z'], 'schedule.mode': ['failed'],
                           'schedule.value': [0.0]}})
    runs = []
    for name in ('run1', 'run2'):
        m = run_scenario(scenario, tmp_path / name, progress=False)
        assert m['missed_steps'] == 0
        runs.append(RunData.from_bag(tmp_path / name / 'bag'))
    assert_array_equal(runs[0].wheel_torque, runs[1].wheel_torque)
    assert_array_equal(runs[0].q, runs[1].q)
    r = runs[0]
    z = r.wheel_names.index('rw_z')
    assert np.all(r.wheel_torque[r.t_wheels >= 20.0, z] == 0.0)
    assert r.wheel_torque[r.t_wheels == 19.0, z][0] != 0.0
    assert (20.0, 2, 'rw_z', 'failed') in r.faults
    # the batch engine applies the same schedule at the same step: the same run
    from adcs_sim.app.batch.engine import BatchSimulation
    from adcs_sim.app.scenario.files import validate_scenario
    batch = BatchSimulation.from_runs([validate_scenario(scenario)]).run().run_data(0)
    assert_allclose(batch.q, r.q, rtol=0, atol=1e-13)
    assert_allclose(batch.u, r.u, rtol=0, atol=1e-16)
