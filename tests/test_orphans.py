"""No orphans, ever (issue #17): ``kill -9`` of ``adcs-run`` mid-run takes every node of the run
with it (Linux parent-death signal, set by each node at start), and the run's domain lease is
not granted again while any of its nodes lives (the nodes hold the lease's lock). Waits poll the
process table and files with a bounded deadline; the 5 s is the bound."""
from __future__ import annotations

import os
import re
import select
import signal
import subprocess
import sys
import time

from support.bags import states_on_disk
from support.paths import ROOT
from support.processes import alive, children
from support.scenarios import make_scenario

from adcs_msgs_py.node import RUNNER_PID_ENV
from adcs_sim.app.graph.domains import DomainLease
from adcs_sim.bag.reader import is_complete

START_DEADLINE = 120.0   # a hang guard for the run to get under way
DEATH_BOUND = 5.0        # every node is gone this long after the runner's SIGKILL


def _lease_granted(domain_id: int) -> bool:
    try:
        lease = DomainLease(domain_id, domain_id)
    except RuntimeError:
        return False
    lease.release()
    return True


def test_sigkill_of_the_runner_leaves_no_node_and_holds_the_lease_until_the_last_is_gone(tmp_path, spawn):
    scenario = make_scenario(tmp_path, {'dynamics': {'duration': 1.0e6}})
    out = tmp_path / 'run'
    runner = spawn([sys.executable, '-m', 'adcs_sim.app.graph.runner', str(scenario), '--out', str(out), '--no-progress'],
                   stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, cwd=ROOT)
    domain = int(re.search(r'ROS_DOMAIN_ID=(\d+)', runner.stdout.readline() + runner.stdout.readline())[1])
    deadline = time.monotonic() + START_DEADLINE
    while not states_on_disk(out / 'bag') > 0:
        assert runner.poll() is None, f'runner exited ({runner.returncode}) before the run got under way'
        assert time.monotonic() < deadline, 'the run did not get under way'
        try:
            runner.wait(timeout=0.05)
        except subprocess.TimeoutExpired:
            pass
    nodes = children(runner.pid)
    spawn.adopt(nodes)   # killed at teardown if this test fails
    assert len(nodes) >= 3, nodes   # recorder, controller, dynamics
    assert not _lease_granted(domain)

    pidfds = {}
    for pid in nodes:   # a pidfd becomes readable when its process exits: waits without sleeping
        try:
            pidfds[pid] = os.pidfd_open(pid)
        except ProcessLookupError:
            pass
    os.kill(runner.pid, signal.SIGKILL)
    runner.wait()
    bound = time.monotonic() + DEATH_BOUND
    poller = select.poll()
    for fd in pidfds.values():
        poller.register(fd, select.POLLIN)
    try:
        while True:
            granted = _lease_granted(domain)
            living = [f'{pid} {cmd}' for pid, cmd in nodes.items() if alive(pid)]
            assert not (granted and living), f'domain {domain} granted again while {living} live'
            if not living:
                break
            remaining = bound - time.monotonic()
            assert remaining > 0, f'alive {DEATH_BOUND:g} s after the runner was killed: {living}'
            for fd, _ in poller.poll(remaining * 1000):
                poller.unregister(fd)
    finally:
        for fd in pidfds.values():
            os.close(fd)
    assert _lease_granted(domain)   # the last node gone, the domain is free again
    # The recorder got SIGTERM: it closed the bag, with what it had recorded.
    assert is_complete(out / 'bag')
    assert states_on_disk(out / 'bag') > 0


def test_a_process_that_inherits_the_lock_holds_the_lease_until_it_exits(spawn):
    lease = DomainLease(100, 232)
    domain = lease.domain_id
    child = spawn([sys.executable, '-c', 'import sys; sys.stdin.read()'], stdin=subprocess.PIPE,
                  pass_fds=(lease.fileno(),))
    lease.release()   # the runner is gone...
    assert not _lease_granted(domain)   # ...but its node still holds the domain
    child.stdin.close()
    assert child.wait() == 0
    assert _lease_granted(domain)


def test_a_node_whose_runner_is_already_gone_exits_at_start(spawn):
    """The runner died between the fork and the node's prctl: the node sees another parent and exits."""
    probe = 'from adcs_msgs_py.node import die_with_runner; die_with_runner(); print("alive")'
    for runner_pid, expected in ((os.getpid(), 'alive'), (1, '')):
        env = {**os.environ, RUNNER_PID_ENV: str(runner_pid)}
        proc = spawn([sys.executable, '-c', probe], stdout=subprocess.PIPE, text=True, env=env, cwd=ROOT)
        out, _ = proc.communicate(timeout=60)
        assert out.strip() == expected
        assert proc.returncode == (0 if expected else 128 + signal.SIGKILL)
