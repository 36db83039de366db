"""Domain leases that cooperate with ros-domain-coordinator (issue #21 item 6).

Ours (:class:`adcs_sim.app.graph.domains.DomainLease`) and theirs (``domain_coordinator.domain_id()``,
what launch_testing and ament's isolated tests use), each held by a process of its own, never
get the same id, and a holder killed with SIGKILL frees its id. The lock files of these tests
live in a private temp directory (``TMPDIR``), so only the coordinator's ports, the machine-wide
part under test, are shared with the rest of the machine. The holders report on stdout and wait
on stdin: no sleeps.
"""
from __future__ import annotations

import signal
import subprocess
import sys

import pytest
from domain_coordinator import domain_id

from adcs_sim.app.graph import domains
from adcs_sim.app.graph.domains import DomainLease, coordinator_socket

THEIRS = ('import sys\nfrom domain_coordinator import domain_id\n'
          'with domain_id() as d:\n    print(d, flush=True)\n    sys.stdin.read()\n')
OURS = ('import sys\nfrom adcs_sim.app.graph.domains import DomainLease\n'
        'lease = DomainLease(1, 100)\nprint(lease.domain_id, flush=True)\nsys.stdin.read()\n')


@pytest.fixture
def private_locks(tmp_path, monkeypatch):
    """Lock files in tmp_path, for this process and the holders it starts."""
    monkeypatch.setattr(domains, 'LOCK_DIR', tmp_path / 'adcs_sim_domains')
    monkeypatch.setenv('TMPDIR', str(tmp_path))
    return tmp_path


def _holder(spawn, code: str) -> tuple[subprocess.Popen, int]:
    proc = spawn([sys.executable, '-c', code], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    line = proc.stdout.readline()
    assert line.strip().isdigit(), f'holder printed {line!r} (exit {proc.poll()})'
    return proc, int(line)


def _kill(proc: subprocess.Popen) -> None:
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert proc.returncode == -signal.SIGKILL


def _theirs_refused(domain: int) -> bool:
    """Whether domain_coordinator refuses ``domain`` (it tries it 100 times)."""
    try:
        with domain_id(selector=lambda: domain):
            return False
    except RuntimeError:
        return True


def test_their_holder_keeps_ours_off_its_id_until_it_is_killed(private_locks, spawn):
    theirs, d = _holder(spawn, THEIRS)
    assert 1 <= d <= 100
    with pytest.raises(RuntimeError, match='ros-domain-coordinator'):
        DomainLease(d, d)
    ours = DomainLease(1, 100)
    assert ours.domain_id != d
    ours.release()
    _kill(theirs)
    lease = DomainLease(d, d)   # the kernel freed the dead holder's port
    assert lease.domain_id == d
    lease.release()


def test_our_holder_keeps_theirs_off_its_id_until_it_is_killed(private_locks, spawn):
    ours, d = _holder(spawn, OURS)
    assert _theirs_refused(d)
    with domain_id() as other:
        assert other != d
    _kill(ours)
    assert not _theirs_refused(d)
    lease = DomainLease(d, d)   # and our lock went with the process
    lease.release()


def test_a_node_inheriting_the_lease_holds_both_parts(private_locks, spawn):
    """The runner passes :meth:`DomainLease.fds` to every node: the lease lives as long as the
    last of them, for both schemes, even after the runner let go of its own copies."""
    lease = DomainLease(1, 100)
    d = lease.domain_id
    node = spawn([sys.executable, '-c', 'import sys; print("up", flush=True); sys.stdin.read()'],
                 stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, pass_fds=lease.fds())
    assert node.stdout.readline().strip() == 'up'
    lease.release()
    assert _theirs_refused(d)
    with pytest.raises(RuntimeError):
        DomainLease(d, d)
    _kill(node)
    assert not _theirs_refused(d)
    DomainLease(d, d).release()


def test_released_lease_frees_the_port_and_refuses_its_fds(private_locks):
    lease = DomainLease(1, 100)
    d = lease.domain_id
    lease.release()
    sock = coordinator_socket(d)
    assert sock is not None
    sock.close()
    with pytest.raises(ValueError):
        lease.fds()
