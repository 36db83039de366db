"""The Python API (adcs_sim/app/api.py) and its example script (docs/examples/pd_slew.py).

* the example runs the PD slew through the ROS 2 graph and the batch engine and finds them equal
  bit for bit (run as a user would: a subprocess, on a leased domain, loopback discovery);
* overrides are validated whole and a bad one names its key; the scenario is never changed in place;
* batch variants: a run equals the same run alone, bit for bit; a parameter the batch engine cannot
  disperse is refused;
* the DataFrame holds the arrays; the figures are the report's; the metrics are run_metrics';
* every public function and method is documented in numpydoc form.
"""
from __future__ import annotations

import inspect
import math
import subprocess
import sys

import numpy as np
import pytest
from matplotlib.figure import Figure
from support.paths import ROOT

from adcs_msgs_py.params import ParameterError
from adcs_sim.app import api
from adcs_sim.app.analysis.metrics import run_metrics
from adcs_sim.app.api import BatchRuns, RunResult, Scenario
from adcs_sim.app.scenario.files import validate_scenario

PD = 'microsat_pd_slew.yaml'


@pytest.fixture(scope='module')
def short_slew():
    return Scenario.load(PD, {'dynamics.duration': 40.0})


@pytest.fixture(scope='module')
def batch_run(short_slew):
    return short_slew.run_batch()[0]


def test_example_script_runs_graph_and_batch_and_they_are_equal(ros_domain, tmp_path):
    out = tmp_path / 'graph_run'
    proc = subprocess.run([sys.executable, str(ROOT / 'docs' / 'examples' / 'pd_slew.py'), '--duration', '30',
                           '--out', str(out)], cwd=tmp_path, env=ros_domain.env(), capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert 'graph and batch equal bit for bit over 31 states' in proc.stdout
    assert (out / 'bag' / 'metadata.yaml').exists() and (out / 'metrics.json').exists()


def test_load_by_name_and_by_path_agree(short_slew):
    by_path = Scenario.load(ROOT / 'config' / PD, {'dynamics': {'duration': 40.0}})
    assert by_path.validated == short_slew.validated
    assert short_slew['dynamics.duration'] == 40.0 and short_slew['dynamics.noise.seed'] == 0   # a default
    assert short_slew.validated == validate_scenario(ROOT / 'config' / PD, 40.0)


def test_override_returns_a_validated_copy(short_slew):
    faster = short_slew.override({'pd_controller.kp': 0.004, 'dynamics.wheels.max_torque': [0.02] * 3})
    assert faster['pd_controller.kp'] == 0.004 and faster['dynamics.wheels.max_torque'] == [0.02] * 3
    assert short_slew['pd_controller.kp'] == 0.002   # unchanged


@pytest.mark.parametrize('overrides, key', [
    ({'pd_controller.kp': -1.0}, "'pd_controller.ros__parameters.kp'"),
    ({'pd_controller.kq': 1.0}, "'pd_controller.ros__parameters.kq'"),
    ({'dynamics.inertia': [1.0, 1.0, 5.0]}, 'triangle inequality'),
    ({'dynamics.duration': math.nan}, "'dynamics.ros__parameters.duration'"),
    ({'no_such_node.x': 1}, "unknown node section 'no_such_node'"),
    ({'duration': 60.0}, "'section.key'"),
])
def test_a_bad_override_names_its_key(short_slew, overrides, key):
    with pytest.raises(ParameterError) as info:
        short_slew.override(overrides)
    assert key in str(info.value)


def test_scenario_file_round_trip(short_slew, tmp_path):
    changed = short_slew.override({'pd_controller.kd': 0.06})
    again = Scenario.load(changed.write(tmp_path / 'changed.yaml'))
    assert again.validated == changed.validated


def test_batch_variants_are_the_runs_alone(short_slew):
    variants = [{'pd_controller.kp': 0.003, 'dynamics.inertia': [13.0, 14.0, 10.0]}, {}]
    batch = short_slew.run_batch(variants)
    assert isinstance(batch, BatchRuns) and len(batch) == 2 and batch.result.q.shape == (2, 41, 4)
    alone = short_slew.override(variants[0]).run_batch()[0]
    assert np.array_equal(batch[0].data.q, alone.data.q) and np.array_equal(batch[0].data.u, alone.data.u)
    assert not np.array_equal(batch[0].data.q, batch[1].data.q)
    assert np.array_equal(batch[-1].data.q, batch[1].data.q)
    with pytest.raises(IndexError):
        batch[2]
    with pytest.raises(ParameterError, match='control_period.*differs between the runs'):
        short_slew.run_batch([{}, {'dynamics.control_period': 2.0}])


def test_metrics_are_the_analysis_metrics(batch_run):
    assert batch_run.metrics() == run_metrics(batch_run.data)
    assert batch_run.metrics(1.0)['settling_euler213_1deg_s'] == run_metrics(batch_run.data, 1.0)[
        'settling_euler213_1deg_s']


def test_dataframe_holds_the_arrays(batch_run):
    pytest.importorskip('pandas')
    frame = batch_run.dataframe()
    run = batch_run.data
    assert np.array_equal(frame.index.to_numpy(), run.t)
    assert np.array_equal(frame[['q_x', 'q_y', 'q_z', 'q_w']].to_numpy(), run.q)
    assert np.array_equal(frame[['u_x', 'u_y', 'u_z']].to_numpy()[:-1], run.u)
    assert frame[['u_x', 'u_y', 'u_z']].iloc[-1].isna().all()   # no command after the last state
    assert np.array_equal(frame[[f'wheel_speed.{n}' for n in run.wheel_names]].to_numpy(), run.wheel_speed)
    # the eigenaxis error of q_e = q_ref* q: with q_ref = identity, 2 acos|q_w|
    assert np.allclose(frame['eigenaxis_error_deg'], np.degrees(2 * np.arccos(np.abs(run.q[:, 3]))),
                       rtol=0, atol=1e-9)


def test_figures_are_the_reports(batch_run, tmp_path):
    figures = batch_run.figures()
    assert {'attitude_error', 'euler_213', 'body_rates', 'torque', 'wheels'} <= set(figures)
    assert 'thrusters' not in figures and 'controller_status' not in figures   # no data for them
    assert all(isinstance(f, Figure) for f in figures.values())
    figures['wheels'].savefig(tmp_path / 'wheels.png')
    assert (tmp_path / 'wheels.png').stat().st_size > 1000
    with pytest.raises(ValueError, match='no bag'):
        batch_run.write_report(tmp_path / 'report')


@pytest.mark.slow
def test_a_committed_bag_as_a_run(tmp_path):
    bag = ROOT / 'bags' / 'microsat_pd_slew' / 'bag'
    run = api.load_run(bag)
    assert isinstance(run, RunResult) and run.bag == bag
    assert run.data.t_end == 600.0
    batch = Scenario.load(ROOT / 'bags' / 'microsat_pd_slew' / 'scenario.yaml').run_batch()[0]
    assert run.metrics()['integrated_torque_Nms'] == pytest.approx(batch.metrics()['integrated_torque_Nms'],
                                                                   rel=1e-9)
    report = run.write_report(tmp_path / 'report')
    assert report.exists() and (tmp_path / 'report' / 'wheels.png').exists()


def test_explain_shows_the_overrides(short_slew):
    text = short_slew.override({'pd_controller.kp': 0.003}).explain()
    assert '(overrides included)' in text
    kp = next(line for line in text.splitlines() if line.split()[:1] == ['kp'])
    assert kp.split()[1:] == ['0.003', '1/s^2', '(file)']


def _public_callables():
    for name in api.__all__:
        obj = getattr(api, name)
        if getattr(obj, '__module__', None) != api.__name__:
            continue
        yield name, obj
        if inspect.isclass(obj):
            for attr, member in vars(obj).items():
                member = member.__func__ if isinstance(member, classmethod) else member
                if inspect.isfunction(member) and not attr.startswith('_'):
                    yield f'{name}.{attr}', member


@pytest.mark.parametrize('name, obj', list(_public_callables()), ids=lambda v: v if isinstance(v, str) else '')
def test_public_api_has_numpydoc_docstrings(name, obj):
    doc = inspect.getdoc(obj)
    assert doc and doc.splitlines()[0].strip(), f'{name} has no summary line'
    if inspect.isfunction(obj):
        params = [p for p in inspect.signature(obj).parameters if p not in ('self', 'cls')]
        if params:
            assert 'Parameters\n----------' in doc, f'{name}: no Parameters section'
            for p in params:
                assert p in doc.split('Parameters\n----------')[1], f'{name}: parameter {p} undocumented'
        if inspect.signature(obj).return_annotation not in ('None', inspect.Signature.empty):
            assert 'Returns\n-------' in doc, f'{name}: no Returns section'
