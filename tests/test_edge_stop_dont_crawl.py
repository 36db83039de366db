"""A run that crawls instead of stopping (issue #31, class "A run that crawls instead of stopping").

An estimator whose parameters its filter cannot take (sigmas of 1e200 or 1e-300, a huge initial
covariance, a huge reference field) made the filter raise on every step: nothing was published and
every step waited out the lockstep timeout (hours for a 3000-step run). Now such parameters are
refused before anything starts, naming the key; and a flight-software node that cannot answer a
step mid-run (its computation raises, or its estimate is not finite) stops the run with its reason
(exit status 6; ``adcs-run`` exits 1 with one line naming the node, the time and the error), the
bag keeping every step up to it, as the dynamics node does on divergence. The batch engine raises
the same error (:class:`~adcs_controllers.laws.failure.FlightSoftwareError`) from the same calls.

The mid-run failure is a real one validation cannot foresee: QUEST with a precise sun sensor (1e-5 rad)
and a coarse magnetometer (3e-4 T, a direction noise ~10 rad) in LEO. Its weights are 1e11 apart
(within what the single-frame solution can take) and the two vectors are fine at the start, but
24 s later the field has turned to within ~18 deg of the Sun, where the solver's weighted
observability test (eigenvalue >= 1e-12 of the weights' sum) fails: the filter raises.
"""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from support.paths import ROOT
from support.scenarios import make_scenario

from adcs_controllers.laws.failure import FlightSoftwareError
from adcs_msgs_py.params import ParameterError
from adcs_sim.app.graph import runner
from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.scenario.files import validate_scenario
from adcs_sim.bag.reader import read_raw

DEADLINE = 300.0   # a hang guard only (the lockstep timeout below is 600 s: a crawl never ends in it)
LEO = 'leo_tle_sun_magnetometer_mekf.yaml'
EPOCH = '2026-03-20T12:15:30Z'   # 930 s into the TLE's orbit: the field nears the Sun 24 s later
FAIL_T = 24


def _quest_scenario(tmp_path, duration: float = 100.0):
    """The LEO scenario flown on QUEST (see the module doc); lockstep.timeout 600 s: a step that waited
    it would hold the test past its deadline."""
    return make_scenario(tmp_path, {
        'dynamics': {'duration': duration, 'environment.epoch': EPOCH, 'lockstep.timeout': 600.0},
        'quest_estimator': {'sensors': ['gyro', 'sun', 'magnetometer'], 'gyro.sigma_v': 2.9e-5,
                            'sun.sigma': 1e-5, 'magnetometer.sigma': 3e-4, 'references.model': 'environment',
                            'environment.epoch': EPOCH, 'environment.orbit': 'tle',
                            'environment.tle.line1': TLE[0], 'environment.tle.line2': TLE[1],
                            'initial.attitude': [0.050384, 0.050384, 0.050384, 0.996195],
                            'initial.attitude_sigma': [0.1, 0.1, 0.1]}}, base=LEO, drop=('mekf_estimator',))


TLE = ('1 90001U          26079.50000000  .00000000  00000-0  20000-4 0    08',
       '2 90001  97.4000  10.0000 0005000  90.0000   0.0000 15.20000000    05')


# --- unusable parameters: refused at validation, naming the key ------------------------------------

UNUSABLE = [   # (section overrides of the MEKF, the key named): what made the filter raise every step
    ({'star_tracker.sigma': [1e200] * 3}, 'star_tracker.sigma'),
    ({'gyro.sigma_v': 1e200}, 'gyro.sigma_v'),
    ({'initial.attitude_sigma': [1e200] * 3}, 'initial.attitude_sigma'),
    ({'initial.bias_sigma': [1e155] * 3}, 'initial.bias_sigma'),
]
UNUSABLE_VECTORS = [   # the sun + magnetometer MEKF of the LEO scenario
    ({'sun.sigma': 1e-300}, 'sun.sigma'),
    ({'sun.sigma': 1e-12}, 'sun.sigma'),   # a normal double, but 1e22 below the 0.1 rad prior: singular S
    ({'magnetometer.sigma': 1e-300}, 'magnetometer.sigma'),
    ({'references.model': 'constant', 'references.magnetometer': [0.0, 0.0, 1e200]}, 'references.magnetometer'),
]


@pytest.mark.parametrize(('overrides', 'key'), UNUSABLE)
def test_unusable_star_tracker_mekf_parameters_are_refused_naming_the_key(tmp_path, overrides, key):
    path = make_scenario(tmp_path, {'mekf_estimator': overrides}, base='microsat_gsmn_slew_mekf.yaml')
    with pytest.raises(ParameterError, match=rf"'mekf_estimator\.ros__parameters\.{key}'"):
        validate_scenario(path)


@pytest.mark.parametrize(('overrides', 'key'), UNUSABLE_VECTORS)
def test_unusable_vector_mekf_parameters_are_refused_naming_the_key(tmp_path, overrides, key):
    path = make_scenario(tmp_path, {'mekf_estimator': overrides}, base=LEO)
    with pytest.raises(ParameterError, match=rf"'mekf_estimator\.ros__parameters\.{key}'"):
        validate_scenario(path)


def test_adcs_run_refuses_them_before_anything_starts(tmp_path, monkeypatch, capsys):
    """One line naming the key, exit 2, no domain leased, no output folder."""
    path = make_scenario(tmp_path, {'mekf_estimator': {'sun.sigma': 1e-300}}, base=LEO)
    leased = []
    monkeypatch.setattr(runner, 'lease_domain', lambda *a: leased.append(a))
    out = tmp_path / 'run'
    assert runner.main([str(path), '--out', str(out), '--no-progress']) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "mekf_estimator.ros__parameters.sun.sigma'" in err, err
    assert not leased and not out.exists()


# --- a model that fails mid-run: stops, with its reason -----------------------------------------

def test_the_batch_engine_raises_the_flight_software_error_at_that_step(tmp_path):
    """Where the node stops: the same error, naming the node, the time and the solver's reason."""
    validated = validate_scenario(_quest_scenario(tmp_path))
    with pytest.raises(FlightSoftwareError) as info:
        BatchSimulation.from_runs([validated]).run()
    assert info.value.node == 'quest_estimator' and info.value.t_ns == FAIL_T * 10 ** 9
    assert str(info.value).startswith(f'flight software failed: quest_estimator could not answer the step at '
                                      f't = {FAIL_T} s: ValueError: body vectors: attitude unobservable')


@pytest.mark.graph
def test_an_estimator_that_cannot_answer_stops_the_run_with_its_reason(tmp_path):
    """The graph: exit 1, one line naming the node, the time and the error, no traceback; the bag holds
    every state up to the failing step and the dynamics node never missed a step (its lockstep timeout
    is 600 s: one waited would hold the test past its deadline)."""
    scenario = _quest_scenario(tmp_path)
    out = tmp_path / 'run'
    proc = subprocess.run([sys.executable, '-m', 'adcs_sim.app.graph.runner', str(scenario), '--out', str(out),
                           '--no-progress'], capture_output=True, text=True, timeout=DEADLINE, cwd=ROOT)
    assert proc.returncode == 1, proc.stderr
    errors = [line for line in proc.stderr.splitlines() if line.startswith('adcs-run: error:')]
    assert len(errors) == 1, proc.stderr
    assert (f'flight software failed: quest_estimator could not answer the step at t = {FAIL_T} s: '
            'ValueError: body vectors: attitude unobservable') in errors[0], proc.stderr
    assert 'Traceback' not in proc.stderr
    assert f'bag kept in {out / "bag"}' in errors[0]
    assert '[quest_estimator] error: flight software failed' in (out / 'logs' / 'quest_estimator.log').read_text()
    states = [topic for topic, *_ in read_raw(out / 'bag') if topic == '/state']
    assert len(states) == FAIL_T + 1   # t = 0 .. 24 s: every state up to the step that could not be answered
    from adcs_sim.app.analysis.stream_metrics import analyse_bag
    assert analyse_bag(out / 'bag', 0.5).metrics['missed_steps'] == 0


def test_a_law_that_raises_stops_its_node_but_a_refused_state_is_counted(ros_domain, tmp_path, monkeypatch):
    """The controller node: a refusal (the law's ValueError, Krstic-Tsiotras at 180 deg) is counted
    and the node goes on (tests/test_fuzz.py); anything else the law or the allocation raises is the
    node unable to answer: nothing is published, no later state is answered, and its loop ends with
    FlightSoftwareFailed (exit status 6) naming the node, the time and the error."""
    from support.ros_graph import InProcessGraph

    from adcs_controllers.nodes.pd_controller import PdController
    from adcs_msgs_py import conversions as cv
    from adcs_msgs_py.node import FlightSoftwareFailed
    scenario = make_scenario(tmp_path)
    with InProcessGraph(scenario) as graph:
        ctl = graph.add(PdController)
        sent = []
        (pub_cmd,) = ctl.pub_cmds.values()   # the one command topic of its actuation
        pub_cmd.publish = sent.append
        q, w = [0.0, 0.0, 0.0, 1.0], [0.01, 0.0, 0.0]
        law = ctl.law.control
        monkeypatch.setattr(ctl.law, 'control', lambda *a: (_ for _ in ()).throw(ValueError('refused')))
        ctl._on_state(cv.state_to_msg(0, q, w))
        assert sent == [] and ctl.rejects.counts['law'] == 1 and ctl.failure is None
        monkeypatch.setattr(ctl.law, 'control', law)
        ctl._on_state(cv.state_to_msg(10 ** 9, q, w))
        assert len(sent) == 1
        monkeypatch.setattr(ctl.actuation, 'command', lambda u: np.linalg.inv(np.zeros((3, 3))))
        ctl._on_state(cv.state_to_msg(2 * 10 ** 9, q, w))
        ctl._on_state(cv.state_to_msg(3 * 10 ** 9, q, w))
        assert len(sent) == 1 and ctl.rejects.counts['law'] == 1
        with pytest.raises(FlightSoftwareFailed, match=r'pd_controller could not answer the step at t = 2 s: '
                                                      r'LinAlgError: Singular matrix'):
            ctl.spin(graph.executor)


def test_a_law_that_refuses_every_state_stops_its_node(ros_domain, tmp_path, monkeypatch):
    """A law that refuses the state three times in a row (a plant resting on its singular set: each
    refusal a lockstep timeout waited, for ever) cannot answer: the third refusal stops the node."""
    from support.ros_graph import InProcessGraph

    from adcs_controllers.nodes.pd_controller import PdController
    from adcs_msgs_py import conversions as cv
    from adcs_msgs_py.node import FlightSoftwareFailed
    with InProcessGraph(make_scenario(tmp_path)) as graph:
        ctl = graph.add(PdController)
        sent = []
        (pub_cmd,) = ctl.pub_cmds.values()   # the one command topic of its actuation
        pub_cmd.publish = sent.append
        law = ctl.law.control
        monkeypatch.setattr(ctl.law, 'control', lambda *a: (_ for _ in ()).throw(ValueError('singular')))
        q, w = [0.0, 0.0, 0.0, 1.0], [0.01, 0.0, 0.0]
        for k in range(2):   # refused, counted, the node goes on
            ctl._on_state(cv.state_to_msg(k * 10 ** 9, q, w))
        monkeypatch.setattr(ctl.law, 'control', law)
        ctl._on_state(cv.state_to_msg(2 * 10 ** 9, q, w))   # answered: the count starts again
        monkeypatch.setattr(ctl.law, 'control', lambda *a: (_ for _ in ()).throw(ValueError('singular')))
        for k in range(3, 5):
            ctl._on_state(cv.state_to_msg(k * 10 ** 9, q, w))
        assert ctl.failure is None and len(sent) == 1 and ctl.rejects.counts['law'] == 4
        ctl._on_state(cv.state_to_msg(5 * 10 ** 9, q, w))
        assert ctl.rejects.counts['law'] == 5 and len(sent) == 1
        with pytest.raises(FlightSoftwareFailed, match=r'pd_controller could not answer the step at t = 5 s: the '
                                                      r'law refused 3 states in a row, the last: .*singular'):
            ctl.spin(graph.executor)
