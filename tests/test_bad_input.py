"""Bad input never crashes anything: bad messages are rejected and counted, bad files stop at start.

Messages: NaN / Inf, wrong lengths, non-unit quaternions, unknown wheel names are rejected by the
node that receives them, counted per topic, and the run goes on.
Files: a malformed or non-physical scenario stops the node (exit status 2) or the runner before
anything runs, with a message naming the key, and leaves no output folder behind.
"""
from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState
from support.paths import ROOT, SCRIPTS
from support.ros_graph import InProcessGraph
from support.scenarios import make_scenario

from adcs_msgs_py import conversions as cv
from adcs_msgs_py import topics
from adcs_msgs_py.params import ParameterError
from adcs_sim.app.graph.runner import main as runner_main
from adcs_sim.app.graph.runner import run_scenario


def _bad_wheel_commands(t_ns: int) -> list[JointState]:
    nan = cv.wheel_cmd_to_msg(t_ns, ['rw_x', 'rw_y', 'rw_z'], effort=[math.nan, 0.0, 0.0])
    inf = cv.wheel_cmd_to_msg(t_ns, ['rw_x'], effort=[math.inf])
    short = cv.wheel_cmd_to_msg(t_ns, ['rw_x', 'rw_y', 'rw_z'], effort=[0.0, 0.0])
    unknown = cv.wheel_cmd_to_msg(t_ns, ['rw_q'], effort=[0.001])
    both = cv.wheel_cmd_to_msg(t_ns, ['rw_x'], effort=[0.001])
    both.velocity = [1.0]
    empty = JointState()
    empty.header.stamp = cv.stamp_from_ns(t_ns)
    duplicate = cv.wheel_cmd_to_msg(t_ns, ['rw_x', 'rw_x'], effort=[0.0, 0.0])
    return [nan, inf, short, unknown, both, empty, duplicate]


def test_dynamics_rejects_bad_wheel_commands_and_runs_on(ros_domain, tmp_path):
    from adcs_sim.nodes.dynamics import DynamicsNode

    steps = 5
    scenario = make_scenario(tmp_path, {'dynamics': {'duration': float(steps), 'lockstep.timeout': 10.0}},
                             drop=('pd_controller', 'recorder'))
    with InProcessGraph(scenario) as graph:
        dyn = graph.add(DynamicsNode)
        ctl = graph.plain('bad_controller')
        pub = ctl.create_publisher(JointState, topics.WHEELS_CMD, topics.QOS_LOCKSTEP)
        good = 0.002

        def on_state(msg):
            t_ns = cv.ns_from_stamp(msg.header.stamp)
            for bad in _bad_wheel_commands(t_ns):
                pub.publish(bad)
            pub.publish(cv.wheel_cmd_to_msg(t_ns, ['rw_x'], effort=[good]))
        ctl.create_subscription(Odometry, topics.STATE, on_state, topics.QOS_LOCKSTEP)
        dyn.run(graph.executor)
    n_bad = len(_bad_wheel_commands(0))
    assert dyn.rejects.counts[topics.WHEELS_CMD] == steps * n_bad
    assert dyn.missed_steps == 0
    assert np.all(np.isfinite(dyn.x))
    # Only the good command acted: wheel x absolute momentum = good torque x duration.
    speed, w_x = dyn.x[dyn.plant.slices['wheels']][0], dyn.x[4]
    np.testing.assert_allclose(0.01 * (speed + w_x), good * steps, rtol=1e-9)


def test_controller_rejects_bad_states(ros_domain, tmp_path):
    from adcs_controllers.nodes.pd_controller import PdController

    scenario = make_scenario(tmp_path, drop=('dynamics', 'recorder'))
    with InProcessGraph(scenario) as graph:
        pd = graph.add(PdController)
        test = graph.plain('state_source')
        pub = test.create_publisher(Odometry, topics.STATE, topics.QOS_LOCKSTEP)
        answers = []
        test.create_subscription(JointState, topics.WHEELS_CMD, answers.append, topics.QOS_LOCKSTEP)
        pd.connect(graph.executor)
        graph.spin_until(lambda: pub.get_subscription_count() >= 1, what='a matched state subscriber')
        bad = [
            cv.state_to_msg(1, [0.0, 0.0, 0.0, 1.1], [0.0, 0.0, 0.0]),          # not unit
            cv.state_to_msg(2, [0.0, 0.0, 0.0, 1.0], [math.nan, 0.0, 0.0]),     # NaN rate
            cv.state_to_msg(3, [math.inf, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0]),     # Inf attitude
            cv.state_to_msg(4, [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0]),          # zero quaternion
        ]
        for msg in bad:
            pub.publish(msg)
        pub.publish(cv.state_to_msg(5, [0.0, 0.0, 0.0, 1.0], [0.01, 0.0, 0.0]))
        graph.spin_until(lambda: len(answers) >= 1, what="the controller's answer")
    assert [cv.ns_from_stamp(a.header.stamp) for a in answers] == [5]
    assert pd.rejects.counts[topics.STATE] == len(bad)
    # PD on w = [0.01, 0, 0]: body torque -kd I w = -0.05*12*0.01 -> wheel x torque +0.006
    np.testing.assert_allclose(answers[0].effort, [0.006, 0.0, 0.0], atol=1e-15)


# --- parameter files ------------------------------------------------------------------------

def _run_node(module: str, args: list[str], env) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-m', module, '--ros-args', *args], env=env, cwd=ROOT,
                          capture_output=True, text=True, timeout=60)


@pytest.mark.parametrize('module, overrides, key', [
    ('adcs_sim.nodes.dynamics', {'dynamics': {'duration': None}}, 'duration'),
    ('adcs_sim.nodes.dynamics', {'dynamics': {'inertia': [1.0, 1.0, 3.0]}}, 'inertia'),
    ('adcs_sim.nodes.dynamics', {'dynamics': {'inertia': [12.0, -14.0, 10.0]}}, 'inertia'),
    ('adcs_sim.nodes.dynamics', {'dynamics': {'wheels.axes': [1.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                                                             0.0, 0.0, 1.0]}}, 'wheels.axes'),
    ('adcs_sim.nodes.dynamics', {'dynamics': {'wheels.max_torque': [0.01, -0.01, 0.01]}}, 'wheels.max_torque'),
    ('adcs_sim.nodes.dynamics', {'dynamics': {'control_period': 'fast'}}, 'control_period'),
    ('adcs_sim.nodes.dynamics', {'dynamics': {'initial.attitude': [0.5, 0.0, 0.0, 1.0]}}, 'initial.attitude'),
    ('adcs_sim.nodes.dynamics', {'dynamics': {'wheel_count': 3}}, 'wheel_count'),
    ('adcs_controllers.nodes.pd_controller', {'pd_controller': {'kp': None}}, 'kp'),
    ('adcs_controllers.nodes.pd_controller', {'pd_controller': {'kd': -0.05}}, 'kd'),
    ('adcs_sim.nodes.recorder', {'recorder': {'chunk_size': 0}}, 'chunk_size'),
])
def test_node_refuses_bad_parameters_at_start(ros_domain, tmp_path, module, overrides, key):
    scenario = make_scenario(tmp_path, overrides)
    result = _run_node(module, ['--params-file', str(scenario), '-p', f'output:={tmp_path / "bag"}']
                       if module.endswith('recorder') else ['--params-file', str(scenario)], ros_domain.env())
    assert result.returncode == 2, result.stderr
    assert f"'{key}" in result.stderr or f".{key}'" in result.stderr, result.stderr


def test_node_refuses_malformed_yaml(ros_domain, tmp_path):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('dynamics:\n  ros__parameters:\n    inertia: [12.0, 14.0\n')
    result = _run_node('adcs_sim.nodes.dynamics', ['--params-file', str(bad)], ros_domain.env())
    assert result.returncode == 2
    assert 'not valid YAML' in result.stderr


@pytest.mark.parametrize('content, key', [
    ('dynamics:\n  ros__parameters:\n    inertia: [12.0, 14.0\n', '<file>'),
    ('dynamics:\n  ros__parameters:\n    inertia: [12.0, 14.0, 10.0]\n    duration: 10.0\n'
     'attitude_wizard:\n  ros__parameters:\n    x: 1.0\n', 'attitude_wizard'),
    ('pd_controller:\n  ros__parameters:\n    kp: 1.0\n', 'dynamics'),
    ('dynamics:\n  params:\n    duration: 1.0\n', 'ros__parameters'),
])
def test_runner_refuses_bad_files_before_starting_anything(tmp_path, capsys, content, key):
    path = tmp_path / 'scenario.yaml'
    path.write_text(content)
    out = tmp_path / 'out'
    assert runner_main([str(path), '--out', str(out), '--no-progress']) == 2
    assert key in capsys.readouterr().err
    assert not out.exists()


def test_runner_refuses_non_physical_inertia(tmp_path):
    scenario = make_scenario(tmp_path, {'dynamics': {'inertia': [1.0, 1.0, 5.0]}})
    with pytest.raises(ParameterError, match=r"dynamics\.ros__parameters\.inertia'.*triangle"):
        run_scenario(scenario, tmp_path / 'out', progress=False)
    assert not (tmp_path / 'out').exists()


@pytest.mark.graph
def test_runner_node_failing_at_start_stops_graph(tmp_path, monkeypatch, capsys):
    """A node that dies at start: the runner stops the other processes, exits non-zero naming
    the node and its error, and leaves no output folder claiming to be a run."""
    from adcs_sim.app.scenario import registry

    info = registry.NODES['pd_controller']
    monkeypatch.setitem(registry.NODES, 'pd_controller',
                        registry.NodeInfo('crash_at_start', info.schema, info.role, info.family))
    monkeypatch.setenv('PYTHONPATH', str(SCRIPTS))   # crash_at_start.py
    scenario = make_scenario(tmp_path, {'dynamics': {'startup.timeout': 60.0}})
    out = tmp_path / 'out'
    started = []
    real_popen = subprocess.Popen

    def recording_popen(*args, **kwargs):
        proc = real_popen(*args, **kwargs)
        started.append(proc)
        return proc
    monkeypatch.setattr(subprocess, 'Popen', recording_popen)
    status = runner_main([str(scenario), '--out', str(out), '--no-progress'])
    err = capsys.readouterr().err
    assert status == 1
    assert 'pd_controller exited with status 3' in err and 'simulated crash at start' in err
    assert not out.exists()
    assert started and all(p.poll() is not None for p in started)  # no orphans
