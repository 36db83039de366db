"""API overrides the batch engine accepted and the graph refused (issue #31, "Tracebacks instead of
one line"): an integer outside int64 (rcl reads it as a double), a list mixing ints and floats or
other kinds (rcl refuses the file), an empty list, a string a params file cannot carry. The graph
read them from the temporary params file :meth:`Scenario.run_graph` writes, and named that file.

Now one validation refuses them for both, at :meth:`Scenario.override`, in one line naming the
override's key; and whatever it accepts, the graph's reading of the written file (rcl's) gives the
very values the batch engine runs.
"""
from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from adcs_msgs_py.params import ParameterError
from adcs_sim.app.graph import runner
from adcs_sim.app.api import Scenario
from adcs_sim.app.scenario.files import RunError, validate_scenario

PD = 'microsat_pd_slew.yaml'

BAD = [   # (the override, its key, the words of the refusal, the same value as a ROS value)
    ({'dynamics.noise.seed': 2**64}, 'noise.seed', 'outside the 64-bit range', 2**63 - 1),
    ({'dynamics': {'link_faults.seed': -2**63 - 1}}, 'link_faults.seed', 'outside the 64-bit range', 7),
    ({'dynamics.inertia': [12, 14.5, 10]}, 'inertia', 'mixes doubles and integers', [12.0, 14.5, 10.0]),
    ({'dynamics.wheels.names': ['rw_x', 2, 'rw_z']}, 'wheels.names', 'mixes integers and strings',
     ['rw_x', 'rw_y', 'rw_z']),
    ({'dynamics.initial.rate': [0.0, True, 0.0]}, 'initial.rate', 'mixes bools and doubles', [0.0, 1.0, 0.0]),
    ({'dynamics.wheels.max_torque': []}, 'wheels.max_torque', 'empty list', [0.02, 0.02, 0.02]),
    ({'dynamics.inertia': [[12.0], [14.0], [10.0]]}, 'inertia', 'a ROS array holds', [12.0, 14.0, 10.0]),
    ({'pd_controller.feedback': 'state\x00'}, 'feedback', 'cannot hold the character', 'state'),
    ({'pd_controller.kp': None}, 'kp', 'not a ROS parameter value', 0.003),
]


@pytest.fixture(scope='module')
def short():
    return Scenario.load(PD, {'dynamics.duration': 2.0})


@pytest.fixture
def no_graph(monkeypatch):
    """The graph path up to its start: a run that reaches the domain lease was validated (nothing starts)."""
    leased = []

    def lease(*args, **kwargs):
        leased.append(args)
        raise RunError('stopped before the graph (test)')
    monkeypatch.setattr(runner, 'lease_domain', lease)
    return leased


def _error(call) -> str:
    with pytest.raises(ParameterError) as info:
        call()
    return str(info.value)


@pytest.mark.parametrize('overrides, key, words, fixed', BAD)
def test_batch_and_graph_refuse_the_same_override_in_one_line_naming_its_key(short, tmp_path, no_graph,
                                                                             overrides, key, words, fixed):
    batch = _error(lambda: short.run_batch([overrides]))
    graph = _error(lambda: short.override(overrides).run_graph(tmp_path / 'run'))
    assert batch == graph                                   # one validation
    assert f".ros__parameters.{key}'" in graph and words in graph, graph
    assert '\n' not in graph and 'adcs_api_' not in graph and '/tmp' not in graph, graph   # no temporary file
    assert not no_graph and not (tmp_path / 'run').exists()  # refused before the run: nothing started

    section = next(iter(overrides))                          # the same value written as a ROS value: both run it
    scenario = short.override({f'{section.partition(".")[0]}.{key}': fixed})
    assert len(scenario.run_batch()) == 1
    with pytest.raises(RunError, match='stopped before the graph'):
        scenario.run_graph(tmp_path / 'run')               # validated by the runner: it asked for a domain
    assert len(no_graph) == 1


VALUES = st.recursive(
    st.one_of(st.booleans(), st.integers(min_value=-2**70, max_value=2**70), st.floats(),
              st.text(max_size=8), st.sampled_from(['1e-3', 'yes', 'null', '~', '.inf', '0x1F', "it's", 'a: b']),
              st.none()),
    lambda inner: st.lists(inner, max_size=4), max_leaves=6)
KEYS = ['dynamics.duration', 'dynamics.noise.seed', 'pd_controller.feedback', 'dynamics.inertia',
        'dynamics.wheels.names', 'pd_controller.kp', 'recorder.output']   # output: any string


@settings(derandomize=True, max_examples=120, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(key=st.sampled_from(KEYS), value=VALUES)
def test_fuzzed_overrides_are_refused_naming_the_key_or_read_back_by_the_graph_unchanged(short, tmp_path, key, value):
    section, _, name = key.partition('.')
    try:
        scenario = short.override({key: value})
    except ParameterError as exc:
        assert f"'{section}.ros__parameters.{name}'" in str(exc) and '\n' not in str(exc), str(exc)
        return
    path = scenario.write(tmp_path / 'written.yaml')        # what run_graph hands the runner and the nodes
    assert validate_scenario(path) == scenario.validated, value
