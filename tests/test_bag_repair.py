"""Recorder crash: a bag writer SIGKILLed at random (seeded) moments loses nothing it had flushed,
``adcs-analyze`` reads what was written, and ``adcs-bag-repair`` rewrites the truncated file into
a complete bag (summary, index, metadata.yaml) that rosbags' AnyReader opens. No ROS graph: the
child process runs :class:`adcs_sim.bag.writer.BagWriter`, the recorder's own writer, in the recorder's
write/flush pattern (the recorder node itself is killed the same way in
tests/test_recorder.py::test_sigkill_keeps_everything_flushed)."""
from __future__ import annotations

import json
import math
import signal
import subprocess
import sys

import numpy as np
import pytest
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader
from support.paths import ROOT, SCRIPTS

from adcs_sim.app.analysis.analyze import main as analyze_main
from adcs_sim.app.analysis.repair import main as repair_main
from adcs_sim.bag.reader import is_complete, read_metadata, read_raw
from adcs_sim.bag.storage import typestore

CHILD = SCRIPTS / 'bag_writer_child.py'
SCENARIO = ROOT / 'config' / 'microsat_pd_slew.yaml'
SEEDS = range(6)


def check_states(states) -> int:
    """The /state messages are k = 0, 1, 2, ... in order, each with its exact content."""
    for k, (t, msg) in enumerate(states):
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        assert stamp == t == k * 100_000_000, (k, stamp, t)
        o = msg.pose.pose.orientation
        assert (o.z, o.w) == (math.sin(1e-3 * k / 2), math.cos(1e-3 * k / 2)), k
        assert msg.twist.twist.angular.x == float(k)
    return len(states)


def killed_bag(tmp_path, seed):
    """Start the writer with seeded chunk size and flush interval, SIGKILL it right after a seeded
    number of flushes has been reported (the child keeps writing meanwhile, so the kill lands at
    an arbitrary point of a chunk). Returns (bag folder, states flushed before the kill)."""
    rng = np.random.default_rng(seed)
    chunk = int(rng.choice([1024, 4096, 65536]))
    every = int(rng.integers(5, 60))
    flushes = int(rng.integers(1, 25))
    out = tmp_path / 'bag'
    proc = subprocess.Popen([sys.executable, str(CHILD), str(out), str(chunk), str(every), str(SCENARIO)],
                            stdout=subprocess.PIPE, text=True, cwd=ROOT)
    flushed = 0
    try:
        assert proc.stdout.readline().strip() == 'ready'
        for _ in range(flushes):
            line = proc.stdout.readline()
            assert line.startswith('flushed '), line
            flushed = int(line.split()[1])
        proc.send_signal(signal.SIGKILL)
        assert proc.wait(timeout=60) == -signal.SIGKILL
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdout.close()
    return out, flushed


@pytest.mark.parametrize('seed', SEEDS)
def test_kill_at_random_moment_loses_nothing_flushed_and_repairs(tmp_path, seed, capsys):
    bag, flushed = killed_bag(tmp_path, seed)
    assert not (bag / 'metadata.yaml').exists() and not is_complete(bag)
    store = typestore()

    # what was written is readable as it is: every flushed state, in order, intact
    truncated = [(t, store.deserialize_cdr(d, ty)) for topic, ty, t, d in read_raw(bag) if topic == '/state']
    n = check_states(truncated)
    assert n >= flushed > 0
    assert analyze_main([str(bag), '--json', '--no-report']) == 0
    before = json.loads(capsys.readouterr().out)[str(bag)]

    # repaired: a complete bag with the same messages, the scenario still embedded
    assert repair_main([str(bag)]) == 0
    assert 'repaired' in capsys.readouterr().out
    assert (bag / 'metadata.yaml').is_file() and is_complete(bag)
    assert (bag / 'bag_0.mcap.truncated').is_file()
    with open(bag / 'bag_0.mcap', 'rb') as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.chunk_indexes       # summary and index
    assert summary.statistics.message_count == sum(1 for _ in read_raw(bag))
    with AnyReader([bag], default_typestore=store) as reader:
        assert reader.message_count == summary.statistics.message_count
        conns = [c for c in reader.connections if c.topic == '/state']
        repaired = [(t, reader.deserialize(d, c.msgtype)) for c, t, d in reader.messages(connections=conns)]
    assert check_states(repaired) == n
    assert read_metadata(bag)['scenario'] == SCENARIO.read_text()
    assert analyze_main([str(bag), '--json', '--no-report']) == 0
    assert json.loads(capsys.readouterr().out)[str(bag)] == before

    # a complete bag is left alone
    assert repair_main([str(bag)]) == 0
    assert 'complete, nothing to repair' in capsys.readouterr().out


def test_repair_refuses_what_is_not_a_bag(tmp_path, capsys):
    (tmp_path / 'notes.txt').write_text('hello')
    assert repair_main([str(tmp_path / 'notes.txt'), str(tmp_path / 'missing')]) == 1
    err = capsys.readouterr().err
    assert 'not a bag' in err and 'no such bag' in err
