"""Lost and late messages (issue #10 item 2): a seeded fraction of the lockstep steps lose their
commands or get them late (``link_faults.*`` of the dynamics node, :mod:`adcs_sim.truth.link_faults`).
The run completes, the metrics report the missed steps, and seed 004's PD slew still converges
with 10 % of the commands lost (and 5 % late)."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from support.paths import ROOT
from support.scenarios import make_scenario

from adcs_msgs_py.params import ParameterError
from adcs_sim.app.scenario.registry import NODES
from adcs_sim.bag.reader import read_messages
from adcs_sim.truth.link_faults import DELAY, DROP, LinkFaults


def test_fates_are_seeded_and_have_the_fractions():
    a, b = LinkFaults(7, 0.1, 0.05, 20000), LinkFaults(7, 0.1, 0.05, 20000)
    assert np.array_equal(a.fates, b.fates)
    assert not np.array_equal(a.fates, LinkFaults(8, 0.1, 0.05, 20000).fates)
    assert abs(np.mean(a.fates == DROP) - 0.1) < 0.01 and abs(np.mean(a.fates == DELAY) - 0.05) < 0.01
    off = LinkFaults(7, 0.0, 0.0, 100)
    assert not off.active and all(off.fate(k) == 0 for k in range(100))
    with pytest.raises(ValueError, match='drop'):
        LinkFaults(0, 0.8, 0.3, 10)


def test_fractions_are_checked_at_start(tmp_path):
    schema = NODES['dynamics'].schema
    from adcs_msgs_py.params_file import load_params_file
    section = load_params_file(str(ROOT / 'config' / 'microsat_pd_slew.yaml'))['dynamics']
    with pytest.raises(ParameterError, match='link_faults.drop'):
        schema.validate({**section, 'link_faults.drop': 1.5})
    with pytest.raises(ParameterError, match='link_faults.delay'):
        schema.validate({**section, 'link_faults.drop': 0.6, 'link_faults.delay': 0.6})


@pytest.mark.graph
def test_pd_slew_with_10_percent_lost_commands_converges(tmp_path):
    """Through adcs-run: 600 steps, 10 % lost and 5 % late, hold policy. Every such step is a
    missed step (exactly the seeded draws), the late ones are counted stale, and the slew still
    settles (nominal: 0.5 deg in ~183 s, final error ~0.01 deg)."""
    seed, drop, delay = 42, 0.10, 0.05
    scenario = make_scenario(tmp_path, {'dynamics': {'link_faults.seed': seed, 'link_faults.drop': drop,
                                                     'link_faults.delay': delay}})
    out = tmp_path / 'run'
    result = subprocess.run([sys.executable, '-m', 'adcs_sim.app.graph.runner', str(scenario), '--out', str(out),
                             '--no-progress'], capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert result.returncode == 0, result.stderr
    fates = LinkFaults(seed, drop, delay, 600).fates
    metrics = json.loads((out / 'metrics.json').read_text())
    assert metrics['missed_steps'] == int(np.count_nonzero(fates)) > 60
    final = [s for _, t, s in _statuses(out / 'bag') if s.get('final') == 'true']
    assert final and final[-1]['link_lost_steps'] == str(np.count_nonzero(fates == DROP))
    assert final[-1]['link_late_steps'] == str(np.count_nonzero(fates == DELAY))
    assert int(final[-1]['stale_commands']) == np.count_nonzero(fates[:-1] == DELAY)
    assert metrics['final_eigenaxis_error_deg'] < 0.1
    assert metrics['settling_euler213_0.5deg_s'] < 400.0


def _statuses(bag):
    for topic, t, msg in read_messages(bag, {'/dynamics/status'}):
        for st in msg.status:
            yield topic, t, {kv.key: kv.value for kv in st.values}


def test_every_topic_has_its_qos_justified():
    """adcs_msgs_py.topics.QOS_RATIONALE: one reason per topic, naming the reliability,
    durability and history the topic really has (changing a QoS means revisiting its reason)."""
    from adcs_msgs_py import topics
    assert set(topics.TOPICS) <= set(topics.QOS_RATIONALE), set(topics.TOPICS) - set(topics.QOS_RATIONALE)
    for name, spec in topics.TOPICS.items():
        why = topics.QOS_RATIONALE[name]
        for policy in (spec.qos.reliability, spec.qos.durability, spec.qos.history):
            assert policy.name in why, (name, policy.name, why)
