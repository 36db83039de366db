"""The recorder's threads run nicer than the lockstep loop's nodes (issue 18: on two cores the
recorder, which takes every message of the run, competed with the loop's critical path).

:func:`adcs_sim.nodes.recorder.lower_priority` raises the niceness of every thread of the process,
never lowers one, and survives whatever ``/proc`` shows it; the ``nice`` parameter is checked
before anything starts. That a running recorder's threads all have it: tests/test_recorder_backlog.py.
Each process-wide change runs in a child process: the test process keeps its own niceness.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from adcs_msgs_py.params import ParameterError
from adcs_sim.bag.schema import RECORDER_SCHEMA
from adcs_sim.nodes.recorder import lower_priority

ROOT = Path(__file__).resolve().parents[1]

CHILD = r'''
import json, os, sys, threading
from adcs_sim.nodes.recorder import lower_priority
ready, done = threading.Barrier(3), threading.Event()
tids = {}
def worker(name, nice):
    tids[name] = threading.get_native_id()
    if nice:
        os.setpriority(os.PRIO_PROCESS, tids[name], nice)
    ready.wait()
    done.wait()
threads = [threading.Thread(target=worker, args=('plain', 0)), threading.Thread(target=worker, args=('nicer', 15))]
for t in threads:
    t.start()
ready.wait()
tids['main'] = threading.get_native_id()
def every():   # every thread of the process: also numpy's, which the test did not start
    return [os.getpriority(os.PRIO_PROCESS, int(t)) for t in os.listdir('/proc/self/task')]
below = sum(p < int(sys.argv[1]) for p in every())
changed = lower_priority(int(sys.argv[1]))
print(json.dumps({'changed': changed, 'below': below, 'every': every(),
                  **{k: os.getpriority(os.PRIO_PROCESS, t) for k, t in tids.items()}}))
done.set()
for t in threads:
    t.join()
'''


def in_child(nice: int) -> dict:
    env = {**os.environ, 'PYTHONPATH': os.pathsep.join(filter(None, [str(ROOT), os.environ.get('PYTHONPATH')]))}
    out = subprocess.run([sys.executable, '-c', CHILD, str(nice)], env=env, capture_output=True, text=True,
                         timeout=60, check=True).stdout
    return json.loads(out)


@pytest.mark.skipif(not Path('/proc/self/task').is_dir(), reason='threads are listed in /proc on Linux only')
def test_every_thread_of_the_process_gets_the_niceness_and_a_nicer_one_keeps_its_own():
    base = os.getpriority(os.PRIO_PROCESS, 0)
    if base > 7:
        pytest.skip(f'the test process already runs at niceness {base}')
    got = in_child(7)
    assert (got['main'], got['plain'], got['nicer']) == (7, 7, 15)
    assert min(got['every']) == 7 and got['changed'] == got['below'] >= 2


@pytest.mark.skipif(not Path('/proc/self/task').is_dir(), reason='threads are listed in /proc on Linux only')
def test_niceness_zero_changes_nothing():
    base = os.getpriority(os.PRIO_PROCESS, 0)
    got = in_child(0)
    assert (got['main'], got['plain'], got['nicer'], got['changed']) == (base, base, max(15, base), 0)
    assert min(got['every']) == base


def test_what_proc_shows_is_not_trusted(tmp_path):
    """No task folder, names that are no thread ids, ids of threads that do not exist: nothing
    changes and nothing is raised (nothing real is named, so the test process is not touched)."""
    assert lower_priority(5, tmp_path / 'missing') == 0
    (tmp_path / 'tasks').mkdir()
    (tmp_path / 'tasks' / 'self').write_text('')
    assert lower_priority(5, tmp_path / 'tasks') == 0
    (tmp_path / 'ids').mkdir()
    (tmp_path / 'ids' / str(2 ** 31 - 1)).write_text('')   # above any pid_max: no such thread
    assert lower_priority(5, tmp_path / 'ids') == 0
    (tmp_path / 'file').write_text('')
    assert lower_priority(5, tmp_path / 'file') == 0


@pytest.mark.parametrize('value', [-1, 20, 1000])
def test_a_niceness_out_of_range_is_refused_naming_the_key(value):
    with pytest.raises(ParameterError, match=r"\.nice': must be a Linux niceness"):
        RECORDER_SCHEMA.validate({'nice': value})


def test_the_default_niceness():
    assert RECORDER_SCHEMA.validate({})['nice'] == 10
