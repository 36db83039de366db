"""Seed 002 on the graph: dynamics with thrusters + backstepping controller in lockstep.

The node-pair test of issue 8: the dynamics node (thrusters, pitch wheel, gravity gradient) and
the backstepping controller close the loop over DDS in this process; the recorded run (attitude,
applied torque, thruster impulse and on-times) is the batch engine's run of the same scenario
bit for bit. Also: the thruster command is validated (bad ones counted, the run goes on), bad
parameter files are refused naming the key, and the scenario files hold the paper's numbers.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose, assert_array_equal
from support.paths import CONFIG
from support.ros_graph import InProcessGraph, run_lockstep_graph
from support.scenarios import make_scenario

from adcs_msgs_py import conversions as cv
from adcs_msgs_py import topics
from adcs_msgs_py.params import ParameterError

SLEW = 'eseo_backstepping_slew.yaml'
NAMES = ['thr_1', 'thr_2', 'thr_3', 'thr_4']


def test_backstepping_pair_in_lockstep_equals_batch(ros_domain, tmp_path):
    """80 steps (8 s) of the ESEO slew through dynamics + backstepping controller + recorder: no
    missed step, nothing rejected, the thrusters fire, and the bag equals the batch engine's run
    of the same file (attitude, rate, applied torque, wheel speed, thruster on-times and impulses)."""
    from adcs_controllers.nodes.backstepping_controller import BacksteppingController
    from adcs_sim.app.analysis.metrics import RunData
    from adcs_sim.app.batch.engine import BatchSimulation
    from adcs_sim.app.scenario.files import validate_scenario

    n = 80
    bag = tmp_path / 'bag'
    expect = {'startup.expect_recorder': True}
    scenario = make_scenario(tmp_path, {'dynamics': {'duration': n * 0.1, **expect},
                                        'backstepping_controller': expect,
                                        'recorder': {'output': str(bag)}}, base=SLEW)
    expected = {'/state': n + 1, '/controller/status': n + 1, '/thrusters/cmd': n + 1,
                '/wheels/cmd': n + 1, '/thrusters/state': n, '/actuators/torque': n}
    dyn, ctrl = run_lockstep_graph(scenario, BacksteppingController, expected)
    assert dyn.missed_steps == 0 and dyn.stale_commands == 0
    assert dyn.rejects.total == 0 and ctrl.rejects.total == 0
    run = RunData.from_bag(bag)
    assert run.thruster_names == NAMES and run.thruster_on_time.shape == (n, 4)
    # the controller answered n + 1 states; the last answer is after the run's end
    fired = int(np.count_nonzero(run.thruster_on_time > 0))
    assert fired > 0 and ctrl.actuation.firings - fired == status_last_firing(run)
    first, last = run.controller_status[0][2], run.controller_status[-1][2]
    assert float(first['angle_deg']) == pytest.approx(135.68, abs=0.01)
    assert float(last['V2']) < float(first['V2'])

    batch = BatchSimulation.from_runs([validate_scenario(scenario)]).run()
    b = batch.run_data(0)
    assert_array_equal(b.q, run.q)
    assert_array_equal(b.w, run.w)
    assert_array_equal(b.u, run.u)
    assert_array_equal(b.wheel_speed, run.wheel_speed)
    assert_array_equal(batch.thruster_on_time[0], run.thruster_on_time)
    assert_array_equal(batch.thruster_impulse[0, 1:], run.thruster_impulse)
    # impulse accounting on the graph: each thruster's impulse = F x its total on-time
    assert_allclose(run.thruster_impulse[-1], 0.13 * run.thruster_on_time.sum(axis=0), rtol=1e-12)


def status_last_firing(run) -> int:
    t, _, values = run.controller_status[-1]
    return int(float(values['firing_now']))


def _bad_thruster_commands(t_ns: int):
    nan = cv.thruster_cmd_to_msg(t_ns, NAMES, [math.nan, 0.0, 0.0, 0.0])
    inf = cv.thruster_cmd_to_msg(t_ns, ['thr_1'], [math.inf])
    negative = cv.thruster_cmd_to_msg(t_ns, ['thr_2'], [-0.1])
    short = cv.thruster_cmd_to_msg(t_ns, NAMES, [0.1, 0.1])
    unknown = cv.thruster_cmd_to_msg(t_ns, ['thr_9'], [0.1])
    duplicate = cv.thruster_cmd_to_msg(t_ns, ['thr_1', 'thr_1'], [0.1, 0.1])
    velocity = cv.thruster_cmd_to_msg(t_ns, ['thr_1'], [0.1])
    velocity.velocity = [1.0]
    return [nan, inf, negative, short, unknown, duplicate, velocity]


def test_dynamics_rejects_bad_thruster_commands_and_runs_on(ros_domain, tmp_path):
    """NaN, Inf, negative on-times, wrong lengths, unknown or duplicate names, a filled velocity:
    each rejected and counted, the run goes on; the good command (thr_1 on for the whole period,
    the others off) gives exactly 0.13 N x 0.1 s per step on thr_1."""
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import JointState

    from adcs_sim.nodes.dynamics import DynamicsNode

    steps = 4
    scenario = make_scenario(tmp_path, {'dynamics': {'duration': steps * 0.1, 'lockstep.timeout': 10.0,
                                                     'lockstep.commands': ['thrusters/cmd']}},
                             base=SLEW, drop=('backstepping_controller', 'recorder'))
    with InProcessGraph(scenario) as graph:
        dyn = graph.add(DynamicsNode)
        ctl = graph.plain('bad_controller')
        pub = ctl.create_publisher(JointState, topics.THRUSTERS_CMD, topics.QOS_LOCKSTEP)

        def on_state(msg):
            t_ns = cv.ns_from_stamp(msg.header.stamp)
            for bad in _bad_thruster_commands(t_ns):
                pub.publish(bad)
            pub.publish(cv.thruster_cmd_to_msg(t_ns, ['thr_1'], [0.1]))
        # a thruster controller reads the wheel state too: the dynamics node waits for it
        ctl.create_subscription(JointState, topics.WHEELS_STATE, lambda msg: None, topics.QOS_LOCKSTEP)
        ctl.create_subscription(Odometry, topics.STATE, on_state, topics.QOS_LOCKSTEP)
        dyn.run(graph.executor)
    assert dyn.rejects.counts[topics.THRUSTERS_CMD] == steps * len(_bad_thruster_commands(0))
    assert dyn.missed_steps == 0 and np.all(np.isfinite(dyn.x))
    assert_allclose(dyn.x[dyn.plant.slices['thrusters']], [0.13 * 0.1 * steps, 0.0, 0.0, 0.0], rtol=1e-12)


# --- parameters --------------------------------------------------------------------------------

@pytest.mark.parametrize('section, overrides, key, text', [
    ('dynamics', {'thrusters.positions': [0.3, 0.3, 0.4]}, 'thrusters.positions', '3 values per thruster'),
    ('dynamics', {'thrusters.directions': [0.0] * 12}, 'thrusters.directions', 'zero length'),
    ('dynamics', {'thrusters.max_force': [0.13, 0.13, -0.13, 0.13]}, 'thrusters.max_force', '> 0'),
    ('dynamics', {'thrusters.max_force': [0.13, 0.13]}, 'thrusters.max_force', 'one value per thruster'),
    ('dynamics', {'thrusters.min_on_time': 0.5}, 'thrusters.min_on_time', 'control_period'),
    ('dynamics', {'thrusters.names': ['a', 'a', 'b', 'c']}, 'thrusters.names', 'unique'),
    ('dynamics', {'thrusters.min_on_rule': 'stretch'}, 'thrusters.min_on_rule', 'one of'),
    ('backstepping_controller', {'K1': 0.0}, 'K1', '> 0'),
    ('backstepping_controller', {'K2': float('nan')}, 'K2', 'finite'),
    ('backstepping_controller', {'firing.off_level': 0.02}, 'firing.off_level', 'on_level'),
    ('backstepping_controller', {'thrusters.positions': [-0.3, 0.3, 0.4, -0.3, -0.3, 0.4,
                                                         0.3, 0.3, 0.4, 0.3, -0.3, 0.4][:9]},
     'thrusters.positions', '3 values per thruster'),
    ('backstepping_controller', {'wheels.names': ['a', 'b'], 'wheels.axes': [0.0, 1.0, 0.0, 1.0, 0.0, 0.0],
                                 'wheels.max_torque': [0.4, 0.4], 'wheels.spin_inertia': [4e-5, 4e-5],
                                 'wheels.max_speed': [500.0, 500.0]}, 'wheels.names', 'exactly one'),
    # readings R3: thrust through the z axis from the face corners -> no yaw torque, B_a singular
    ('backstepping_controller', {'thrusters.directions': [0.7071067811865476, -0.7071067811865476, 0.0,
                                                          0.7071067811865476, 0.7071067811865476, 0.0,
                                                          -0.7071067811865476, -0.7071067811865476, 0.0,
                                                          -0.7071067811865476, 0.7071067811865476, 0.0],
                                 'wheels.axes': [1.0, 0.0, 0.0]}, 'thrusters.positions', 'singular'),
    ('backstepping_controller', {'allocation.mapping': 'opposed'}, 'allocation.mapping', 'one of'),
    ('backstepping_controller', {'orbit.altitude': -1.0}, 'orbit.altitude', '> 0'),
])
def test_bad_seed002_parameters_are_named(tmp_path, section, overrides, key, text):
    from adcs_sim.app.scenario.files import validate_scenario
    with pytest.raises(ParameterError, match=text) as err:
        validate_scenario(make_scenario(tmp_path, {section: overrides}, base=SLEW))
    assert f'{section}.ros__parameters.{key}' in str(err.value)


def test_thruster_command_conversion_validates():
    known = {n: i for i, n in enumerate(NAMES)}
    t_ns, index, on = cv.thruster_cmd_from_msg(cv.thruster_cmd_to_msg(7, ['thr_3', 'thr_1'], [0.05, 0.1]), known)
    assert t_ns == 7 and index.tolist() == [2, 0] and on.tolist() == [0.05, 0.1]
    for bad in _bad_thruster_commands(0):
        with pytest.raises(cv.InvalidMessage):
            cv.thruster_cmd_from_msg(bad, known)
    msg = cv.thruster_state_to_msg(5, NAMES, [1.0, 2, 3, 4], [0.1, 0, 0, 0.1], [0.13, 0, 0, 0.13])
    t_ns, names, impulse, on, force = cv.thruster_state_from_msg(msg)
    assert names == NAMES and impulse.tolist() == [1, 2, 3, 4] and force[0] == 0.13


def test_scenario_files_hold_the_papers_numbers():
    """The inertial frame is the orbit frame at t = 0 (to 1e-16), so the paper's q(0) = [1, 0, 0, 0]
    and q_d = [-0.3772, -0.4329, 0.6645, 0.4783] (scalar first, relative to the orbit frame) are
    the files' numbers with the scalar last; the body starts at rest in the orbit frame; the
    thruster layout is eq. (21) with (r_x, r_y, r_z) = (0.3, -0.3, 0.4) m; the slew file is the
    two-orbit file cut at 300 s."""
    from adcs_controllers.laws.backstepping import actuator_matrix, eseo_actuator_matrix
    from adcs_core.orbit import orbit_frame_attitude
    from adcs_sim.app.scenario.files import validate_scenario
    from adcs_sim.truth.schema import build_plant
    full = validate_scenario(CONFIG / 'eseo_backstepping.yaml')
    slew = validate_scenario(CONFIG / SLEW)
    assert slew['dynamics'].pop('duration') == 300.0
    # two orbits, written in whole seconds (10741 for 10740.59): half a second (was 1 s, no reason)
    assert full['dynamics'].pop('duration') == pytest.approx(2 * 2 * math.pi / 1.1699887158899546e-3, abs=0.5)
    assert slew == full
    d, c = full['dynamics'], full['backstepping_controller']
    plant = build_plant(d)
    assert_allclose(orbit_frame_attitude(plant.orbit, 0.0), [0, 0, 0, 1], atol=1e-16)
    assert d['initial.attitude'] == [0.0, 0.0, 0.0, 1.0]
    assert_allclose(d['initial.rate'], [0.0, -plant.orbit.mean_motion, 0.0], rtol=1e-15)
    qd = np.array([-0.3772, -0.4329, 0.6645, 0.4783])
    assert_allclose(c['target.attitude'], np.r_[qd[1:], qd[0]] / np.linalg.norm(qd), rtol=1e-15)
    thr = plant.actuator('thrusters')
    assert_allclose(actuator_matrix(thr.positions, thr.directions, [0, 1, 0]),
                    eseo_actuator_matrix(0.3, -0.3, 0.4), atol=1e-15)
    for key in ('inertia', 'orbit.altitude', 'orbit.inclination_deg', 'orbit.raan_deg',
                'orbit.arg_latitude_deg', 'control_period', 'thrusters.names', 'thrusters.positions',
                'thrusters.directions', 'thrusters.max_force', 'wheels.names', 'wheels.axes',
                'wheels.max_torque', 'wheels.spin_inertia', 'wheels.max_speed'):
        assert c[key] == d[key], key   # the controller's model is the plant
    tree = yaml.safe_load((CONFIG / 'eseo_backstepping.yaml').read_text())
    # 5035 rpm written to 15 significant digits (repr): round-off (was pytest.approx's default 1e-6)
    assert tree['dynamics']['ros__parameters']['wheels']['max_speed'] == [pytest.approx(5035 * math.pi / 30, rel=1e-15)]


def test_batched_geometries_and_gains_equal_single_runs():
    """Lever arms, K1, K2 and the deadzone are batch parameters (the sensitivity grid): a batch of
    three runs with different geometries and gains gives each run's numbers bit for bit."""
    import copy

    from adcs_controllers.laws.backstepping import eseo_thruster_layout
    from adcs_sim.app.batch.engine import BatchSimulation
    from adcs_sim.app.scenario.files import validate_scenario
    base = validate_scenario(CONFIG / SLEW)
    base.pop('recorder')
    base['dynamics']['duration'] = 5.0
    runs = []
    for (rx, ry, rz), k1, lv in (((0.3, -0.3, 0.4), 0.1, 0.013), ((0.25, -0.25, 0.4), 0.2, 0.026),
                                 ((0.3, 0.1, 0.3), 0.05, 0.013)):
        r = copy.deepcopy(base)
        p, d = eseo_thruster_layout(rx, ry, rz)
        for section in ('dynamics', 'backstepping_controller'):
            r[section]['thrusters.positions'] = p.ravel().tolist()
            r[section]['thrusters.directions'] = d.ravel().tolist()
        r['backstepping_controller']['K1'] = k1
        r['backstepping_controller']['firing.on_level'] = lv
        r['backstepping_controller']['firing.off_level'] = lv
        runs.append(r)
    batch = BatchSimulation.from_runs(runs).run()
    for i, r in enumerate(runs):
        single = BatchSimulation.from_runs([r]).run()
        assert_array_equal(batch.q[i], single.q[0])
        assert_array_equal(batch.thruster_impulse[i], single.thruster_impulse[0])
    assert not np.array_equal(batch.q[0], batch.q[1])
