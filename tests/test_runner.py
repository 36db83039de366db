"""The runner as a user meets it: ``adcs-run`` end to end, interrupted, and ``adcs-analyze``."""
from __future__ import annotations

import json
import signal
import subprocess
import sys
import time

import pytest
from support.bags import states_on_disk
from support.paths import ROOT
from support.processes import alive, children
from support.scenarios import make_scenario

from adcs_sim.app.analysis.metrics import RunData, run_metrics
from adcs_sim.app.analysis.analyze import main as analyze_main
from adcs_sim.bag.reader import read_metadata


@pytest.mark.graph
def test_runner_end_to_end_and_analyze_agree(tmp_path, capsys):
    """adcs-run prints the metrics and writes them; adcs-analyze on the bag gives the same."""
    scenario = make_scenario(tmp_path, {'dynamics': {'duration': 400.0}})
    out = tmp_path / 'run'
    result = subprocess.run([sys.executable, '-m', 'adcs_sim.app.graph.runner', str(scenario), '--out', str(out)],
                            capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert result.returncode == 0, result.stderr
    assert 'settling_euler213_0.5deg_s' in result.stdout and 'missed_steps' in result.stdout
    assert sorted(p.name for p in out.iterdir()) == ['bag', 'logs', 'metrics.json', 'scenario.yaml']
    written = json.loads((out / 'metrics.json').read_text())
    assert written['missed_steps'] == 0
    assert analyze_main([str(out / 'bag'), '--json']) == 0
    analyzed = json.loads(capsys.readouterr().out)[str(out / 'bag')]
    assert analyzed == written
    # The scenario is embedded in the bag: the bag alone describes its run.
    assert read_metadata(out / 'bag')['scenario'] == scenario.read_text()


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM])
def test_runner_interrupted_mid_run_leaves_readable_bag_and_no_orphans(tmp_path, sig, spawn):
    scenario = make_scenario(tmp_path, {'dynamics': {'duration': 1.0e6}})
    out = tmp_path / 'run'
    proc = spawn([sys.executable, '-m', 'adcs_sim.app.graph.runner', str(scenario), '--out', str(out),
                  '--no-progress'], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        bag = out / 'bag'
        deadline = time.monotonic() + 120
        # Wait until the run is really under way: two states are on disk (recorder flushed), so the
        # controller has answered a step (the first state alone can be flushed 0.5 s before the
        # first step completes, under load: the dynamics' first publications; the graph then stops
        # within ~0.2 s of the signal, too soon for a second state).
        while states_on_disk(bag) < 2:
            assert time.monotonic() < deadline, 'run did not start'
            try:  # re-check the file when the runner exits or after 0.1 s, whichever first
                proc.wait(timeout=0.1)
                pytest.fail(f'runner exited early: {proc.communicate()}')
            except subprocess.TimeoutExpired:
                pass
        kids = list(children(proc.pid))
        assert len(kids) >= 3  # recorder, controller, dynamics
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 1
    assert 'interrupted' in err and 'during the run' in err, err
    assert not [pid for pid in kids if alive(pid)]
    assert (bag / 'metadata.yaml').exists()  # the recorder closed the bag
    run = RunData.from_bag(bag)
    assert run.t.size > 1
    assert run_metrics(run)['duration_s'] > 0
