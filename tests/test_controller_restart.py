"""A controller killed with SIGKILL mid-run, then started again (issue #10 item 1).

The dynamics node applies its timeout policy and counts the missed steps (published on
``dynamics/status``); the restarted controller — the same law (through ``adcs-run --restart``)
or another one (node processes started by the test) — rejoins the lockstep loop at the next
state and the run completes; the bag holds every step of the run and the analysis shows the gap
(``missed_step_gaps``, ``longest_missed_gap_s``). Waits on files and process states only.
"""
from __future__ import annotations

import json
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import yaml
from support.paths import CONFIG, ROOT
from support.processes import children
from support.scenarios import make_scenario

from adcs_sim.app.analysis.metrics import RunData, run_metrics
from adcs_sim.bag.reader import read_raw

DEADLINE = 180.0
DURATION = 2000.0   # simulated s (1 s steps): long enough to be killed mid-run, short once rejoined
TIMEOUT = 0.25      # lockstep.timeout (wall s) while the controller is gone


def _states_recorded(bag) -> int:
    try:
        return sum(1 for t, *_ in read_raw(bag) if t == '/state')
    except (FileNotFoundError, ValueError):
        return 0


def _wait(what, condition, proc):
    """Until ``condition()``, re-checked when ``proc`` exits or every 20 ms, whichever first."""
    deadline = time.monotonic() + DEADLINE
    while not condition():
        assert proc.poll() is None, f'{what}: process exited ({proc.returncode})'
        assert time.monotonic() < deadline, f'{what}: not within {DEADLINE:g} s'
        try:
            proc.wait(timeout=0.02)
        except subprocess.TimeoutExpired:
            pass


def _assert_whole_run_with_gap(bag, killed_after: int):
    run = RunData.from_bag(bag)
    np.testing.assert_array_equal(run.t, np.arange(DURATION + 1))      # every step recorded
    metrics = run_metrics(run)
    assert metrics['missed_steps'] >= 1
    assert metrics['missed_step_gaps'] >= 1
    start, end = metrics['longest_missed_gap_s']
    assert start >= killed_after - 1 and end >= start                 # the gap is where the kill was
    assert metrics['final_eigenaxis_error_deg'] < 0.01                 # the rejoined law finished the slew
    return metrics


@pytest.mark.slow
def test_runner_restarts_a_killed_controller_which_rejoins(tmp_path, spawn):
    scenario = make_scenario(tmp_path, {'dynamics': {'duration': DURATION, 'lockstep.timeout': TIMEOUT}})
    out = tmp_path / 'run'
    proc = spawn([sys.executable, '-m', 'adcs_sim.app.graph.runner', str(scenario), '--out', str(out),
                  '--no-progress', '--restart', '1'], stdout=subprocess.PIPE,
                 stderr=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        _wait('run under way', lambda: _states_recorded(out / 'bag') > 0, proc)
        killed_after = _states_recorded(out / 'bag')
        [pid] = [p for p, a in children(proc.pid).items() if 'adcs_controllers.nodes.pd_controller' in a]
        subprocess.run(['kill', '-KILL', str(pid)], check=True)
        _, err = proc.communicate(timeout=DEADLINE)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, err
    assert 'pd_controller was killed by SIGKILL' in err and 'restarting it (1 of 1)' in err
    metrics = _assert_whole_run_with_gap(out / 'bag', killed_after)
    assert json.loads((out / 'metrics.json').read_text())['missed_steps'] == metrics['missed_steps']
    assert (out / 'logs' / 'pd_controller.1.log').is_file() and (out / 'logs' / 'pd_controller.log').is_file()


@pytest.mark.slow
def test_another_law_takes_over_after_a_kill(ros_domain, tmp_path, spawn):
    """Node processes on the test's domain: recorder, dynamics, PD; the PD is SIGKILLed and the
    min-norm law of the same spacecraft (seed 004 eq. 14) is started in its place."""
    minnorm = yaml.safe_load((CONFIG / 'microsat_minnorm_slew.yaml').read_text())['minnorm_controller']
    scenario = make_scenario(tmp_path, {'dynamics': {'duration': DURATION, 'lockstep.timeout': TIMEOUT},
                                        'minnorm_controller': minnorm['ros__parameters']})
    bag = tmp_path / 'bag'
    env = ros_domain.env()
    procs = {}

    def start(name, module, *params):
        log = open(tmp_path / f'{name}.log', 'wb')
        procs[name] = spawn([sys.executable, '-m', module, '--ros-args', '--params-file', str(scenario),
                             *[a for p in params for a in ('-p', p)]], stdout=log,
                            stderr=subprocess.STDOUT, env=env, cwd=ROOT)
        log.close()
        return procs[name]

    try:
        rec = start('recorder', 'adcs_sim.nodes.recorder', f'output:={bag}', 'flush_period:=0.2')
        _wait('recorder ready', lambda: 'recorder: ready' in (tmp_path / 'recorder.log').read_text(), rec)
        start('pd_controller', 'adcs_controllers.nodes.pd_controller', 'startup.expect_recorder:=true')
        dyn = start('dynamics', 'adcs_sim.nodes.dynamics', 'startup.expect_recorder:=true')
        _wait('run under way', lambda: _states_recorded(bag) > 0, dyn)
        killed_after = _states_recorded(bag)
        procs['pd_controller'].send_signal(signal.SIGKILL)
        assert procs['pd_controller'].wait(timeout=DEADLINE) == -signal.SIGKILL
        start('minnorm_controller', 'adcs_controllers.nodes.minnorm_controller', 'startup.expect_recorder:=true')
        assert dyn.wait(timeout=DEADLINE) == 0, (tmp_path / 'dynamics.log').read_text()[-2000:]
        for name in ('minnorm_controller', 'recorder'):
            procs[name].send_signal(signal.SIGINT)
            assert procs[name].wait(timeout=DEADLINE) == 0, (tmp_path / f'{name}.log').read_text()[-2000:]
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.kill()
                p.wait()
    try:
        _assert_whole_run_with_gap(bag, killed_after)
    except AssertionError as exc:   # rare (twice in many full runs): the nodes' own words with it
        logs = '\n'.join(f'--- {f.name}:\n{f.read_text()[-3000:]}' for f in sorted(tmp_path.glob('*.log')))
        raise AssertionError(f'{exc}\nkilled after {killed_after} states recorded\n{logs}') from None
    log = (tmp_path / 'dynamics.log').read_text()
    assert 'no command on' in log and 'policy hold' in log
    run = RunData.from_bag(bag)
    laws = {name for _, name, _ in run.controller_status}
    assert {'pd_controller', 'minnorm_controller'} <= laws        # both laws answered, in turn
