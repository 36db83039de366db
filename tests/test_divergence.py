"""A run whose plant state is no longer finite ends clearly (issue #17): the dynamics node stops
the graph with a non-zero exit naming the time and the cause, and the batch engine records the
same failure, at the same time (the graph and the batch step the same plant bit for bit).

Torquers with unlimited torque and kd * period > 2 (kd = 40): the discrete rate loop is unstable
and overflows within a few hundred steps (tests/test_batch.py)."""
from __future__ import annotations

import functools
import re
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support.paths import ROOT
from support.scenarios import make_scenario

from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.scenario.files import validate_scenario
from adcs_sim.bag.reader import read_raw
from adcs_sim.truth.divergence import nonfinite_cause
from adcs_sim.truth.schema import build_plant

DEADLINE = 300.0   # a hang guard only
NO_WHEELS = {'wheels.names': None, 'wheels.axes': None, 'wheels.max_torque': None}


def _diverging(tmp_path):
    return make_scenario(tmp_path, {
        'dynamics': {'duration': 400.0, 'torquers.enabled': True, 'wheels.spin_inertia': None,
                     'wheels.max_speed': None, **NO_WHEELS},
        'pd_controller': {'actuator': 'torquers', 'kd': 40.0, **NO_WHEELS}})


def _batch_failure(scenario) -> tuple[str, int]:
    result = BatchSimulation.from_runs([validate_scenario(scenario)]).run()
    assert result.failure[0] is not None
    return result.failure[0], int(result.n_steps[0])


def test_batch_names_the_time_and_the_cause(tmp_path):
    failure, k_fail = _batch_failure(_diverging(tmp_path))
    assert 0 < k_fail < 400
    assert f'no longer finite at t = {k_fail:g} s' in failure, failure
    assert re.search(r'non-finite (attitude quaternion|body rate|applied torque)', failure), failure


@pytest.mark.graph
def test_dynamics_node_stops_the_run_naming_the_time_and_the_cause(tmp_path):
    scenario = _diverging(tmp_path)
    _, k_fail = _batch_failure(scenario)
    out = tmp_path / 'run'
    proc = subprocess.run([sys.executable, '-m', 'adcs_sim.app.graph.runner', str(scenario), '--out', str(out),
                           '--no-progress'], capture_output=True, text=True, timeout=DEADLINE, cwd=ROOT)
    assert proc.returncode == 1, proc.stderr
    assert 'dynamics exited with status 5' in proc.stderr, proc.stderr
    assert f'the plant state is no longer finite at t = {k_fail:g} s' in proc.stderr, proc.stderr
    assert 'Traceback' not in proc.stderr
    # The bag keeps every finite state up to the divergence, and no non-finite one.
    states = [m for t, *m in read_raw(out / 'bag') if t == '/state']
    assert len(states) == k_fail


def _named(plant, x, torque):
    """What is not finite, part by part (the check before the one-sum shortcut)."""
    parts = {'attitude quaternion': x[:4], 'body rate': x[4:7]}
    parts.update({f'{name} state': x[s] for name, s in plant.slices.items()})
    if torque is not None:
        parts['applied torque'] = torque
    return ', '.join(n for n, v in parts.items() if not np.isfinite(v).all()) or None


@settings(max_examples=300, derandomize=True, deadline=None)
@given(st.data())
def test_the_one_sum_shortcut_names_what_the_part_by_part_check_names(data):
    """Any mix of finite values (sums that overflow to infinity among them), NaNs and infinities
    in the state and the torque: the same answer as checking each part."""
    plant = showcase_plant()
    values = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([1e308, -1e308, 0.0]))
    x = np.array(data.draw(st.lists(values, min_size=plant.n_states, max_size=plant.n_states)))
    torque = data.draw(st.one_of(st.none(), st.lists(values, min_size=3, max_size=3).map(np.array)))
    assert nonfinite_cause(plant, x, torque) == _named(plant, x, torque)


@functools.lru_cache(maxsize=1)
def showcase_plant():
    """The showcase's plant (body and three wheels), built once."""
    return build_plant(validate_scenario(ROOT / 'config' / 'uosat12_gsmn.yaml')['dynamics'], warm=False)
