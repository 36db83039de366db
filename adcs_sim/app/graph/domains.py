"""Allocate a ROS_DOMAIN_ID no other adcs_sim process, and no ROS tool using
``ros-domain-coordinator``, on this machine is using.

Each run (runner, test, benchmark) takes a domain with an exclusive ``flock`` on a file in the
temp directory and holds it while it runs, so concurrent runs never cross-talk. A process that
dies releases its lock with it. The runner's nodes inherit the lock's file descriptor
(:meth:`DomainLease.fds`, ``pass_fds``): a ``flock`` belongs to the open file, so the domain is
free again only when the runner *and* the last of its nodes have exited, however they ended.

The lease also takes the domain the way ``ros-domain-coordinator`` does (the package behind
``launch_testing``'s and ament's isolated tests, ``domain_coordinator.domain_id()``): it binds a
TCP socket to port ``PORT_BASE + id`` (32768 + id, on every interface, never listening, no
``SO_REUSEADDR``) and holds it as long as the lock. A domain is taken only if both the lock and
the port are free, so an adcs_sim run and a test suite using the coordinator never get the same
id: each one's bind fails on the other's port. The socket is inherited by the nodes like the
lock, and the kernel frees the port when the last process holding it exits (SIGKILL included).
Their scheme grants ids 1..100; ours binds the port of whatever id it leases (0..232).
"""
from __future__ import annotations

import fcntl
import os
import socket
import tempfile
from contextlib import contextmanager
from pathlib import Path

from domain_coordinator.impl import PORT_BASE  # ros-domain-coordinator's port = PORT_BASE + domain id

LOCK_DIR = Path(tempfile.gettempdir()) / 'adcs_sim_domains'
MAX_DOMAIN_ID = 232  # largest id whose DDS ports stay valid on Linux


def coordinator_socket(domain: int) -> socket.socket | None:
    """The ``ros-domain-coordinator`` claim on ``domain``: a TCP socket bound to ``PORT_BASE +
    domain``, or None when another process holds that port."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    try:
        sock.bind(('', PORT_BASE + domain))
    except OSError:
        sock.close()
        return None
    return sock


class DomainLease:
    """An exclusively held domain id; release() or process exit frees it."""

    def __init__(self, first: int = 1, last: int = MAX_DOMAIN_ID, prefer: int | None = None) -> None:
        """The first free id of ``first..last`` from ``prefer`` on (default: one spread by the
        process id, so that concurrent callers do not all try the same one first)."""
        if not 0 <= first <= last <= MAX_DOMAIN_ID:
            raise ValueError(f'domain range must lie in 0..{MAX_DOMAIN_ID}, got {first}..{last}')
        LOCK_DIR.mkdir(parents=True, exist_ok=True)
        offset = os.getpid() if prefer is None else prefer - first
        start = first + offset % (last - first + 1)
        ids = list(range(start, last + 1)) + list(range(first, start))
        self._fd: int | None = None
        self._socket: socket.socket | None = None
        held = {'lock': 0, 'port': 0}
        for domain in ids:
            fd = os.open(LOCK_DIR / f'{domain}.lock', os.O_CREAT | os.O_RDWR, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                os.close(fd)
                held['lock'] += 1
                continue
            sock = coordinator_socket(domain)
            if sock is None:
                os.close(fd)
                held['port'] += 1
                continue
            self.domain_id, self._fd, self._socket = domain, fd, sock
            return
        raise RuntimeError(f'no free ROS domain id in {first}..{last} ({held["lock"]} held by adcs_sim runs, '
                           f'{held["port"]} by another process on port {PORT_BASE}+id: ros-domain-coordinator\'s '
                           f'scheme)')

    def env(self, base: dict | None = None, allow_network: bool = False) -> dict:
        """Environment for a process of this run: own domain, loopback-only discovery.

        ``allow_network=True`` (``adcs-run --allow-network``, for a graph spread over several
        hosts) lets DDS discover participants on the local subnet instead
        (``ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET``); nothing else ever widens discovery."""
        env = dict(os.environ if base is None else base)
        env['ROS_DOMAIN_ID'] = str(self.domain_id)
        env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'SUBNET' if allow_network else 'LOCALHOST'
        env.pop('ROS_LOCALHOST_ONLY', None)   # deprecated; would override the range above
        return env

    def fileno(self) -> int:
        """The lock's file descriptor: a process that inherits it holds the lock until it exits."""
        if self._fd is None:
            raise ValueError('the lease was released')
        return self._fd

    def fds(self) -> tuple[int, int]:
        """The lock's and the coordinator socket's descriptors: a process that inherits both
        (``pass_fds``) holds the whole lease until it exits."""
        if self._fd is None or self._socket is None:
            raise ValueError('the lease was released')
        return self._fd, self._socket.fileno()

    def release(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
        if self._socket is not None:
            self._socket.close()
            self._socket = None


@contextmanager
def leased_domain(first: int = 1, last: int = MAX_DOMAIN_ID):
    lease = DomainLease(first, last)
    try:
        yield lease
    finally:
        lease.release()
