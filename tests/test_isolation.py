"""Eight scenarios at once on one machine (issue #10 item 5): each ``adcs-run`` leases its own
ROS_DOMAIN_ID, nothing crosses between them, and each run's recorded data is identical, message
for message and value for value (bit for bit in every number), to the same scenario run alone.

The eight scenarios differ (initial attitude), so a message that crossed from one run to
another would show as foreign data or an extra message; one of them (seeded pick) is also run
alone afterwards and compared message for message. Short scenarios (60 steps) keep it to one start-up
burst. (The long run with bounded memory is benchmarks/long_run_memory.py, not a test.)
"""
from __future__ import annotations

import re
import subprocess
import sys
from collections import defaultdict

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from support.comparison import plain_message
from support.paths import ROOT
from support.scenarios import make_scenario

from adcs_sim.app.analysis.metrics import RunData
from adcs_sim.bag.reader import read_messages

N_RUNS = 8
DURATION = 60.0
TIMEOUT = 600


def _scenarios(tmp_path):
    rng = np.random.default_rng(10)
    attitudes = Rotation.from_euler('YXZ', rng.uniform(-30, 30, size=(N_RUNS, 3)), degrees=True).as_quat()
    return [make_scenario(tmp_path, {'dynamics': {'duration': DURATION, 'initial.attitude': [float(x) for x in q]}})
            for q in attitudes], attitudes


def _launch(spawn, scenario, out):
    return spawn([sys.executable, '-m', 'adcs_sim.app.graph.runner', str(scenario), '--out', str(out),
                  '--no-progress'], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)


def _finish(proc):
    try:
        out, err = proc.communicate(timeout=TIMEOUT)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, err
    return int(re.search(r'ROS_DOMAIN_ID=(\d+), discovery LOCALHOST', out).group(1))


def _content(bag):
    """{topic: [(log time, message content), ...] in the order received}: everything the run
    recorded. Content, not CDR bytes: Fast DDS leaves a serialised message's alignment padding
    uninitialised (seen here: the byte after a string's terminator), so equal messages can
    differ there."""
    out = defaultdict(list)
    for topic, t, msg in read_messages(bag):
        out[topic].append((t, plain_message(msg)))
    return dict(out)


@pytest.mark.slow
def test_eight_concurrent_runs_do_not_cross_talk_and_equal_solo_runs(tmp_path, spawn):
    scenarios, attitudes = _scenarios(tmp_path)
    outs = [tmp_path / f'concurrent{i}' for i in range(N_RUNS)]
    procs = [_launch(spawn, s, o) for s, o in zip(scenarios, outs)]
    domains = [_finish(p) for p in procs]
    assert len(set(domains)) == N_RUNS, domains                       # a domain each

    contents = [_content(o / 'bag') for o in outs]
    for i, (content, q0) in enumerate(zip(contents, attitudes)):
        run = RunData.from_bag(outs[i] / 'bag')
        np.testing.assert_array_equal(run.t, np.arange(DURATION + 1))  # one state per step, no extra
        np.testing.assert_allclose(run.q[0], q0, atol=1e-12)         # its own spacecraft
        assert run.missed_steps == 0
        assert len(content['/wheels/cmd']) == DURATION + 1             # one answer per state, no foreign one
        assert len(content['/state']) == len({t for t, _ in content['/state']})        # no duplicates

    for i in np.random.default_rng(5).choice(N_RUNS, size=1):
        solo = tmp_path / f'solo{i}'
        _finish(_launch(spawn, scenarios[i], solo))
        assert _content(solo / 'bag') == contents[i], f'run {i}: concurrent != alone'
